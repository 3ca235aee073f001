"""The formulas of the time-step limits (docs/PHYSICS.md section 6), shared by the contact
laws (each law states its own limits: :mod:`engine.contact.materials`) and
:func:`engine.simulation.timestep.critical_time_step`, which gathers them for a scene."""

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


def eepa_impact_overlap(m_eff: float, law, v0: float) -> float:
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


def hertz_candidates(
    kind: str, m_star, r_star, e_star: float, restitution: float, v: float
) -> list[TimeStepCandidate]:
    """The Hertz oscillator limit (stiffness at the overlap of an impact at ``v`` [m/s]) and
    the contact duration, for the (m* [kg], R* [m]) pairs given, E* [Pa]."""
    # c = 2 sqrt(5/6) zeta sqrt(S m): a damping ratio of sqrt(5/6) zeta against stiffness S
    zeta = math.sqrt(5.0 / 6.0) * damping_ratio(restitution)
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
