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

from .config import DT_FRACTION
from .materials import ADHESIVE_LAWS, EEPA, HertzMindlin, damping_ratio
from .scene import Scene


@dataclass(frozen=True)
class TimeStepCandidate:
    """One time-step limit: ``kind`` is ``"pair"`` or ``"wall"``, ``name`` what sets it,
    ``value`` [s], ``hard`` True for a stability (not accuracy) limit."""

    kind: str
    name: str
    value: float
    hard: bool


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
    """Overlap (|f0|/k1)^(1/n) [m] at which adhesion alone holds a bilinear (n = 1) or EEPA
    contact on its loading branch, when it lies beyond ``fraction`` x the smallest radius
    ``rmin`` [m] (the overlap guard of a run); None when it does not (or the law has no
    adhesion)."""
    if isinstance(law, ADHESIVE_LAWS) and law.f0 < 0:
        d_eq = (-law.f0 / law.k1) ** (1.0 / law.n)
        if d_eq > fraction * rmin:
            return d_eq
    return None


def eepa_impact_overlap(m_eff: float, law: EEPA, v0: float) -> float:
    """Largest overlap [m] of an undamped head-on impact at speed v0 [m/s] on the EEPA
    loading branch, adhesion pulling in: the root of
    K1 d^(n+1)/(n+1) = m v0^2/2 + |f0| d (fixed-point iteration, contracting for n >= 1)."""
    n = law.n
    d = 0.0
    for _ in range(60):
        d_new = ((n + 1.0) * (0.5 * m_eff * v0 * v0 - law.f0 * d) / law.k1) ** (1.0 / (n + 1.0))
        if abs(d_new - d) <= 1e-12 * d_new:
            return d_new
        d = d_new
    return d


def oscillator_limit(k: float, m: float, zeta: float) -> float:
    """Stable explicit time step of a damped linear oscillator [s]: 2/w (sqrt(1+z^2) - z),
    w = sqrt(k/m); k [N/m], m [kg], zeta [-]."""
    omega = math.sqrt(k / m)
    if omega == 0.0:  # a spring too soft for the mass to register: no limit
        return math.inf
    return 2.0 / omega * (math.sqrt(1.0 + zeta * zeta) - zeta)


def hertz_impact_overlap(m_star: float, r_star: float, e_star: float, v0: float) -> float:
    """Largest overlap of an undamped Hertz impact at speed v0 [m]:
    (15 m* v0^2 / (16 E* sqrt(R*)))^(2/5)."""
    return (15.0 * m_star * v0 * v0 / (16.0 * e_star * math.sqrt(r_star))) ** 0.4


def hertz_contact_time(m_star: float, r_star: float, e_star: float, v0: float) -> float:
    """Duration of an undamped Hertz impact [s]: 2.868 (m*^2 / (R* E*^2 v0))^(1/5)."""
    return 2.868 * (m_star * m_star / (r_star * e_star * e_star * v0)) ** 0.2


def rayleigh_time(radius: float, density: float, shear_modulus: float, nu: float) -> float:
    """Rayleigh wave time pi R sqrt(rho/G) / (0.1631 nu + 0.8766) [s]."""
    return math.pi * radius * math.sqrt(density / shear_modulus) / (0.1631 * nu + 0.8766)


def expected_max_speed(scene: Scene) -> float:
    """Default impact speed for the Hertz limits [m/s]: the largest of the particles' and
    walls' speeds, the free-fall speed over the scene's extent along gravity, and 0.1 m/s."""
    v = [0.1, float(np.sqrt((scene.velocities**2).sum(axis=1)).max())]
    v += [math.sqrt(sum(c * c for c in w.velocity)) for w in scene.walls]
    g = np.asarray(scene.gravity)
    gnorm = float(np.linalg.norm(g))
    if gnorm > 0:
        h = scene.positions @ (g / gnorm)
        v.append(math.sqrt(2.0 * gnorm * (float(h.max() - h.min()) + 2 * scene.radii.max())))
    return max(v)


def _hertz_candidates(
    kind: str, m_star: np.ndarray, r_star: np.ndarray, e_star: float, law: HertzMindlin, v: float
) -> list[TimeStepCandidate]:
    # c = 2 sqrt(5/6) zeta sqrt(S m): a damping ratio of sqrt(5/6) zeta against stiffness S
    zeta = math.sqrt(5.0 / 6.0) * damping_ratio(law.restitution)
    out = []
    osc = math.inf
    tc = math.inf
    for m, r in zip(m_star, r_star):
        dmax = hertz_impact_overlap(m, r, e_star, v)
        s_n = 2.0 * e_star * math.sqrt(r * dmax)
        osc = min(osc, oscillator_limit(s_n, m, zeta))
        tc = min(tc, hertz_contact_time(m, r, e_star, v))
    out.append(
        TimeStepCandidate(
            kind, f"{kind} Hertz stiffness at the overlap of a {v:.3g} m/s impact", osc, True
        )
    )
    out.append(TimeStepCandidate(kind, f"{kind} Hertz contact duration at {v:.3g} m/s", tc, False))
    return out


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
    law = scene.pair_law
    if scene.n >= 2:
        order = np.argsort(masses)
        m0, m1 = masses[order[0]], masses[order[1]]
        m_eff = m0 * m1 / (m0 + m1)
        if isinstance(law, ADHESIVE_LAWS):
            zeta = damping_ratio(law.restitution)
            # the tangent stiffnesses n K d^(n-1) at the largest expected overlap, that of a
            # head-on impact of two particles each at the expected speed (n = 1: K itself)
            tangent, where, unit = 1.0, "", "N/m"
            if law.n != 1.0:
                d_exp = eepa_impact_overlap(m_eff, law, 2.0 * v)
                tangent = law.n * d_exp ** (law.n - 1.0)
                where = (f" x n d^(n-1) at the overlap {d_exp:.3g} m of a {2 * v:.3g} m/s "
                         "head-on impact")
                unit = "N/m^n"
            # damping c_n = 2 zeta sqrt(m K1) seen by the stiffer K2 branch
            cands.append(
                TimeStepCandidate(
                    "pair",
                    f"pair unloading stiffness k2 = {law.k2:g} {unit}{where}, lightest pair",
                    oscillator_limit(law.k2 * tangent, m_eff, zeta * math.sqrt(law.k1 / law.k2)),
                    True,
                )
            )
            if law.mu_s > 0 and law.kt > 0:
                # relative tangential motion with rotation: 1/m_t = 3.5 (1/mi + 1/mj)
                cands.append(
                    TimeStepCandidate(
                        "pair",
                        f"pair tangential stiffness kt = {law.kt:g} {unit}{where} with rotation",
                        oscillator_limit(3.5 * law.kt * tangent, m_eff, zeta * math.sqrt(3.5)),
                        True,
                    )
                )
        else:
            e_star, _ = law.pair_moduli()
            r0, r1 = radii[order[0]], radii[order[1]]
            cands += _hertz_candidates(
                "pair", np.array([m_eff]), np.array([r0 * r1 / (r0 + r1)]), e_star, law, v
            )
            i = int(np.argmin(radii))
            cands.append(
                TimeStepCandidate(
                    "pair",
                    "pair Rayleigh time of the smallest particle",
                    rayleigh_time(radii[i], scene.density[i], law.G, law.nu),
                    False,
                )
            )
    if scene.walls:
        wl = scene.wall_law
        e_star, _ = wl.wall_moduli(scene.wall_material)
        # distinct (m, R) only: monodisperse scenes do this once
        mr = np.unique(np.stack([masses, radii], axis=1), axis=0)
        cands += _hertz_candidates("wall", mr[:, 0], mr[:, 1], e_star, wl, v)
        i = int(np.argmin(radii))
        cands.append(
            TimeStepCandidate(
                "wall",
                "wall Rayleigh time of the smallest particle",
                rayleigh_time(radii[i], scene.density[i], wl.G, wl.nu),
                False,
            )
        )
    # masses or stiffnesses beyond the float range (extreme inputs) give inf or NaN limits: a
    # NaN limit would compare false with any step and let it through, so it counts as 0
    cands = [c if c.value == c.value else TimeStepCandidate(c.kind, f"{c.name} (not finite)",
                                                             0.0, c.hard) for c in cands]
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
