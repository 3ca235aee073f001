"""Time-step limits (PHYSICS.md section 6).

Linear contacts: the damped oscillator limit :math:`\\Delta t_c = \\tfrac{2}{\\omega}
(\\sqrt{1+\\zeta^2}-\\zeta)`, :math:`\\omega = \\sqrt{K/m_{eff}}`, for the stiffest branch (K2)
and the lightest pair; tangential spring with rotation: :math:`\\omega^2 = 3.5 K_t / m_{eff}`.
EEPA contacts: the same limits with the tangent stiffnesses :math:`n K d^{n-1}` at the largest
overlap of a head-on impact at the expected speed (section 8).
Hertz contacts: the same oscillator limit with the Hertz stiffness at the largest overlap of an
impact at the expected speed, the Rayleigh time
:math:`T_R = \\pi R\\sqrt{\\rho/G}/(0.1631\\nu + 0.8766)` and the Hertz contact duration
:math:`t_c = 2.868\\,(m^{*2}/(R^*E^{*2}v))^{1/5}`.

The oscillator limits are hard (a larger step is refused); the Rayleigh time and contact
duration are accuracy limits. The recommended step is ``DT_FRACTION`` of the smallest of all.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..contact.limits import TimeStepCandidate
from ..core.config import DT_FRACTION
from .scene import Scene


@dataclass(frozen=True)
class TimeStepLimit:
    """Result of :func:`critical_time_step`.

    Attributes:
        dt: the stable limit [s]: the smallest hard limit (inf when no contact can form).
        reason: which contact kind and limit sets ``dt``.
        recommended: ``DT_FRACTION`` times the smallest of all limits [s].
        recommended_reason: which limit sets ``recommended``.
        max_speed: the impact speed assumed for the Hertz limits [m/s].
        candidates: every limit considered.
    """

    dt: float
    reason: str
    recommended: float
    recommended_reason: str
    max_speed: float
    candidates: tuple[TimeStepCandidate, ...]

    def __iter__(self):
        """Unpack as ``dt, reason = critical_time_step(scene)``."""
        return iter((self.dt, self.reason))


def adhesion_overlap(law, rmin: float, fraction: float) -> float | None:
    """Overlap [m] at which adhesion alone holds a contact of ``law``, when it lies beyond
    ``fraction`` x the smallest radius ``rmin`` [m] (the overlap guard of a run); None when it
    does not or the law has no adhesion (the law's own :meth:`adhesion_overlap`)."""
    return law.adhesion_overlap(rmin, fraction)


def expected_max_speed(scene: Scene) -> float:
    """Default impact speed for the Hertz limits [m/s]: the largest of the particles', the
    walls' and the meshes' speeds, the free-fall speed over the scene's extent along gravity,
    and 0.1 m/s."""
    v = [0.1, float(np.sqrt((scene.velocities**2).sum(axis=1)).max())]
    v += [math.sqrt(sum(c * c for c in w.velocity)) for w in (*scene.walls, *scene.meshes)]
    g = np.asarray(scene.gravity)
    gnorm = float(np.linalg.norm(g))
    if gnorm > 0:
        h = scene.positions @ (g / gnorm)
        v.append(math.sqrt(2.0 * gnorm * (float(h.max() - h.min()) + 2 * scene.radii.max())))
    return max(v)


def critical_time_step(scene: Scene, max_speed: float | None = None) -> TimeStepLimit:
    """Time-step limits of ``scene`` and which contact kind sets them.

    Args:
        scene: the scene.
        max_speed: largest expected impact speed for the Hertz limits [m/s]; default
            :func:`expected_max_speed`.
    Returns: :class:`TimeStepLimit` (unpacks as ``(dt, reason)``).
    """
    with np.errstate(all="ignore"):
        return _critical_time_step(scene, max_speed)


def _critical_time_step(scene: Scene, max_speed: float | None) -> TimeStepLimit:
    v = expected_max_speed(scene) if max_speed is None else float(max_speed)
    masses = scene.masses
    radii = scene.radii
    cands: list[TimeStepCandidate] = []
    if scene.n >= 2:
        # the lightest pair, and the smallest particle (for the accuracy limits)
        order = np.argsort(masses)
        m0, m1 = masses[order[0]], masses[order[1]]
        r0, r1 = radii[order[0]], radii[order[1]]
        i = int(np.argmin(radii))
        cands += scene.pair_law.pair_time_steps(
            m0 * m1 / (m0 + m1), r0 * r1 / (r0 + r1), radii[i], scene.density[i], v
        )
    if scene.walls or scene.meshes:
        # distinct (m, R) only: monodisperse scenes do this once
        mr = np.unique(np.stack([masses, radii], axis=1), axis=0)
        i = int(np.argmin(radii))
        cands += scene.wall_law.wall_time_steps(
            scene.wall_material, mr[:, 0], mr[:, 1], radii[i], scene.density[i], v
        )
    # masses or stiffnesses beyond the float range (extreme inputs) give inf or NaN limits: a
    # NaN limit would compare false with any step and let it through, so it counts as 0
    cands = [
        c
        if c.value == c.value
        else TimeStepCandidate(c.kind, f"{c.name} (not finite)", 0.0, c.hard)
        for c in cands
    ]
    hard = [c for c in cands if c.hard]
    if hard:
        h = min(hard, key=lambda c: c.value)
        dt, reason = h.value, h.name
    else:
        dt, reason = math.inf, "no contact can form"
    if cands:
        r = min(cands, key=lambda c: c.value)
        rec, rec_reason = DT_FRACTION * r.value, f"{DT_FRACTION:g} x {r.name}"
    else:
        rec, rec_reason = math.inf, "no contact can form"
    return TimeStepLimit(dt, reason, rec, rec_reason, v, tuple(cands))
