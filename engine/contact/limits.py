"""The time-step formulas every law's limits are made of (docs/PHYSICS.md section 6): each
law states its own limits (``pair_time_steps``, ``wall_time_steps``, in its module) with
these, and :func:`engine.simulation.timestep.critical_time_step` gathers them for a scene."""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class TimeStepCandidate:
    """One time-step limit: ``kind`` is ``"pair"`` or ``"wall"``, ``name`` what sets it,
    ``value`` [s], ``hard`` True for a stability (not accuracy) limit."""

    kind: str
    name: str
    value: float
    hard: bool


def damping_ratio(restitution: float) -> float:
    r"""Viscous damping ratio for a coefficient of restitution [-].

    .. math:: \zeta = -\ln e / \sqrt{\pi^2 + \ln^2 e}

    ``e = 1`` gives 0 (no damping); ``e -> 0`` gives 1 (critical damping).
    """
    if restitution >= 1.0:
        return 0.0
    ln_e = math.log(restitution)
    return -ln_e / math.sqrt(math.pi**2 + ln_e**2)


def oscillator_limit(k: float, m: float, zeta: float) -> float:
    """Stable explicit time step of a damped linear oscillator [s]: 2/w (sqrt(1+z^2) - z),
    w = sqrt(k/m); k [N/m], m [kg], zeta [-]."""
    omega = math.sqrt(k / m)
    if omega == 0.0:  # a spring too soft for the mass to register: no limit
        return math.inf
    return 2.0 / omega * (math.sqrt(1.0 + zeta * zeta) - zeta)
