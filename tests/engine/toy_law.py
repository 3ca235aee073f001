"""A toy contact law of its own force shape, written as a new law is: one module with its
record, its scalar kernels and its kernel family; registering it (``LAWS["PowerSpring"] =
PowerSpring``) is the only other change (tests/engine/test_toy_law.py).

The power spring: F = k d^p [N] (p = 1: a linear spring, p = 1.5: a Hertz-like one), no
damping, friction or adhesion. Its closed forms for a head-on impact of two particles of
reduced mass m* at closing speed v: the largest overlap d_max = ((p + 1) m* v^2 / (2 k))^(1/(p+1))
(energy), the contact duration 2 d_max / v I(p), I(p) = int_0^1 du / sqrt(1 - u^(p+1)), and a
restitution of 1.
"""

from __future__ import annotations

import math
from collections import namedtuple
from dataclasses import dataclass

from numba import njit

from engine.contact.kernel import COMPOSITION_SWITCHES, LawKernel, Slot
from engine.contact.limits import TimeStepCandidate, oscillator_limit
from engine.core.config import NJIT_INLINE
from engine.core.records import check_fields, param

PowerParams = namedtuple("PowerParams", "k p zeta mu_s mu_r")
PowerSwitches = namedtuple("PowerSwitches", tuple(COMPOSITION_SWITCHES))


@njit(**NJIT_INLINE)
def normal_force(d, dmax, r_star, law, flags):
    """F = k d^p, its stiffness p k d^(p-1); the history slot holds the overlap."""
    f = law.k * d**law.p
    return f, law.p * f / d, f, 1.0, d


@njit(**NJIT_INLINE)
def tangential_stiffness(d, r_star, law, tangent):
    """No tangential spring."""
    return 0.0


KERNEL = LawKernel(
    name="power_spring",
    module=__name__,
    params=PowerParams,
    switch_tuple=PowerSwitches,
    slots=(
        Slot("k"),
        Slot("p"),
        Slot("zeta", "damping"),
        Slot("mu_s", "friction"),
        Slot("mu_r", "rolling"),
    ),
    switches={},
    normal_force=normal_force,
    tangential_stiffness=tangential_stiffness,
)


def impact_overlap(k: float, p: float, m_star: float, v: float) -> float:
    """Largest overlap [m] of an impact at closing speed ``v`` [m/s]."""
    return ((p + 1.0) * m_star * v * v / (2.0 * k)) ** (1.0 / (p + 1.0))


def impact_duration(k: float, p: float, m_star: float, v: float) -> float:
    """Contact duration [s] of that impact: 2 d_max / v x sqrt(pi) G(1 + 1/(p+1)) /
    G(1/2 + 1/(p+1))."""
    q = 1.0 / (p + 1.0)
    integral = math.sqrt(math.pi) * math.gamma(1.0 + q) / math.gamma(0.5 + q)
    return 2.0 * impact_overlap(k, p, m_star, v) / v * integral


@dataclass(frozen=True)
class PowerSpring:
    """F = k d^p between particles [N]; k [N/m^p], p [-] in [1, 3]."""

    k: float = param(unit="N/m^p", doc="stiffness coefficient", gt=0)
    p: float = param(2.0, unit="1", doc="overlap exponent", ge=1, le=3)

    kernel = KERNEL
    adhesive = False
    pair = True
    wall = False

    def __post_init__(self) -> None:
        check_fields(self, "PowerSpring")

    def switches(self) -> dict[str, bool]:
        return {}

    def pair_values(self) -> dict[str, float]:
        return {"k": self.k, "p": self.p, "zeta": 0.0, "mu_s": 0.0, "mu_r": 0.0}

    def load_overlap(self, force: float, radius: float) -> tuple[float, str]:
        """Overlap [m] at which the spring carries ``force`` [N] (k d^p = F), and the
        parameter that sets it."""
        return (force / self.k) ** (1.0 / self.p), "k"

    def adhesion_overlap(self, rmin: float, fraction: float) -> None:
        return None

    def pair_time_steps(self, m_eff, r_eff, r_min, rho_min, v) -> list[TimeStepCandidate]:
        d = impact_overlap(self.k, self.p, m_eff, 2.0 * v)
        stiffness = self.p * self.k * d ** (self.p - 1.0)
        return [
            TimeStepCandidate(
                "pair",
                f"power spring stiffness at the overlap {d:.3g} m of a head-on impact",
                oscillator_limit(stiffness, m_eff, 0.0),
                True,
            )
        ]
