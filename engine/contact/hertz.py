"""The Hertz-Mindlin (no slip) contact law, for walls and, selectable, for particle pairs:
its record, its force kernels, its time-step limits, its kernel family and its LIGGGHTS
mapping (``model hertz``)."""

from __future__ import annotations

import math
from collections import namedtuple
from dataclasses import dataclass

import numpy as np
from numba import njit

from ..core.config import NJIT_INLINE
from ..core.records import check_fields, param
from .export import LiggghtsPair, elastic_atom_type, gran_coefficients
from .kernel import COMPOSITION_SWITCHES, LawKernel, Slot, law_array
from .limits import TimeStepCandidate, damping_ratio, oscillator_limit
from .wall import WallMaterial


def hertz_damping_factor(restitution: float) -> float:
    r"""Positive Hertz-Mindlin damping factor :math:`-2\sqrt{5/6}\,\beta` [-] (Tsuji et al. 1992).

    .. math:: \beta = \ln e / \sqrt{\ln^2 e + \pi^2}, \quad
              F_d = -2\sqrt{5/6}\,\beta\,\sqrt{S\,m^*}\; v

    The force opposes the relative velocity ``v``; with ``e = 1`` the factor is 0.
    """
    return 2.0 * math.sqrt(5.0 / 6.0) * damping_ratio(restitution)


@njit(**NJIT_INLINE)
def hertz_normal_force(d, e_star, r_star):
    r"""Hertz elastic normal force and normal contact stiffness.

    .. math:: F_n = \tfrac43 E^*\sqrt{R^*}\,d^{3/2}, \qquad S_n = 2E^*\sqrt{R^* d}

    Args: overlap d [m] (> 0), effective modulus e_star [Pa], effective radius r_star [m].
    Returns: (F_n [N], S_n [N/m]). Reference: Johnson, Contact Mechanics (1985).
    """
    a = math.sqrt(r_star * d)
    return (4.0 / 3.0) * e_star * a * d, 2.0 * e_star * a


@njit(**NJIT_INLINE)
def hertz_tangential_stiffness(d, g_star, r_star):
    r"""Mindlin no-slip tangential stiffness :math:`S_t = 8G^*\sqrt{R^* d}` [N/m]."""
    return 8.0 * g_star * math.sqrt(r_star * d)


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
    zeta = 0.5 * hertz_damping_factor(restitution)
    out = []
    osc = math.inf
    tc = math.inf
    for m, r in zip(m_star, r_star):
        dmax = hertz_impact_overlap(m, r, e_star, v)
        s_n = 2.0 * e_star * math.sqrt(r * dmax)  # hertz_normal_force's S_n (plain Python here)
        osc = min(osc, oscillator_limit(s_n, m, zeta))
        tc = min(tc, hertz_contact_time(m, r, e_star, v))
    out.append(
        TimeStepCandidate(
            kind, f"{kind} Hertz stiffness at the overlap of a {v:.3g} m/s impact", osc, True
        )
    )
    out.append(TimeStepCandidate(kind, f"{kind} Hertz contact duration at {v:.3g} m/s", tc, False))
    return out


#: The Hertz family's parameters as its kernels read them: effective moduli e_star,
#: g_star [Pa], damping ratio zeta (sqrt(5/6) x the restitution's), mu_s, mu_r [-].
HertzParams = namedtuple("HertzParams", "e_star g_star zeta mu_s mu_r")
#: Its switches: the composition's (it has none of its own).
HertzSwitches = namedtuple("HertzSwitches", tuple(COMPOSITION_SWITCHES))


@njit(**NJIT_INLINE)
def normal_force(d, dmax, r_star, law, flags):
    """The family's normal force (engine.contact.kernel): :func:`hertz_normal_force` with
    its stiffness S_n; the history holds the current overlap as the contact marker; the
    cap force is the elastic force."""
    f_el, stiff = hertz_normal_force(d, law.e_star, r_star)
    return f_el, stiff, f_el, 1.0, d


@njit(**NJIT_INLINE)
def tangential_stiffness(d, r_star, law, tangent):
    """Mindlin's S_t = 8 G* sqrt(R* d) [N/m]."""
    return hertz_tangential_stiffness(d, law.g_star, r_star)


KERNEL = LawKernel(
    name="hertz",
    module=__name__,
    params=HertzParams,
    switch_tuple=HertzSwitches,
    slots=(
        Slot("e_star"),
        Slot("g_star", "friction"),
        Slot("zeta", "damping"),
        Slot("mu_s", "friction"),
        Slot("mu_r", "rolling"),
    ),
    switches={},
    normal_force=normal_force,
    tangential_stiffness=tangential_stiffness,
    effective_radius=True,
)


@dataclass(frozen=True)
class HertzMindlin:
    r"""Hertz-Mindlin (no slip) contact law; for walls and, selectable, for particle pairs.

    .. math::
        F_n = \tfrac43 E^*\sqrt{R^*}\,d^{3/2},\quad S_n = 2E^*\sqrt{R^* d},\quad
        S_t = 8G^*\sqrt{R^* d},\quad F_d = -2\sqrt{5/6}\,\beta\sqrt{S m^*}\,v,\quad
        |F_t| \le \mu F_n

    Attributes:
        E: Young's modulus of the particle material [Pa], >= 1 (below that its shear
            modulus underflows).
        nu: Poisson's ratio of the particle material [-], in (-1, 0.5).
        restitution: coefficient of restitution [-], in (0, 1].
        mu: sliding friction coefficient [-], >= 0.
        mu_r: rolling friction coefficient [-], >= 0 (constant directional torque).
    """

    E: float = param(
        unit="Pa",
        doc="Young's modulus of the particle material (>= 1 Pa: below that no solid, and "
        "its shear modulus underflows)",
        ge=1.0,
    )
    nu: float = param(0.25, unit="1", doc="Poisson's ratio of the particle material", gt=-1, lt=0.5)
    restitution: float = param(0.4, unit="1", doc="coefficient of restitution", gt=0, le=1)
    mu: float = param(0.3, unit="1", doc="sliding friction coefficient", ge=0)
    mu_r: float = param(0.0, unit="1", doc="rolling friction coefficient", ge=0)

    kernel = KERNEL
    adhesive = False
    pair = True
    wall = True

    def __post_init__(self) -> None:
        check_fields(self, "HertzMindlin")

    def switches(self) -> dict[str, bool]:
        """The step kernel's switches this law turns on (on the side it is used on)."""
        return {
            "friction": self.mu > 0,
            "rolling": self.mu_r > 0,
            "damping": self.restitution < 1,
        }

    def pair_values(self) -> dict[str, float]:
        """Kernel slot values of a contact between two particles of this material."""
        return self.slot_values(*self.pair_moduli())

    def wall_values(self, wall: WallMaterial) -> dict[str, float]:
        """Kernel slot values of a contact between a particle of this material and ``wall``."""
        return self.slot_values(*self.wall_moduli(wall))

    def load_overlap(self, force: float, radius: float) -> tuple[float, str]:
        """Overlap [m] at which two particles of ``radius`` [m] carry ``force`` [N]
        (F = 4/3 E* sqrt(R*) d^1.5, R* = radius / 2), and the parameter that sets it."""
        e_star, _ = self.pair_moduli()
        return (0.75 * force / (e_star * math.sqrt(0.5 * radius))) ** (2.0 / 3.0), "E"

    def adhesion_overlap(self, rmin: float, fraction: float) -> None:
        """No adhesion: None."""
        return None

    def pair_time_steps(
        self, m_eff: float, r_eff: float, r_min: float, rho_min: float, v: float
    ) -> list[TimeStepCandidate]:
        """The Hertz limits of the lightest pair (``m_eff`` [kg], ``r_eff`` [m]) at ``v``
        [m/s], and the Rayleigh time of the smallest particle (``r_min`` [m], ``rho_min``
        [kg/m^3])."""
        e_star, _ = self.pair_moduli()
        return self._time_steps("pair", e_star, [m_eff], [r_eff], r_min, rho_min, v)

    def wall_time_steps(
        self, wall: WallMaterial, m, r, r_min: float, rho_min: float, v: float
    ) -> list[TimeStepCandidate]:
        """The Hertz limits of particles of masses ``m`` [kg] and radii ``r`` [m] on
        ``wall`` at ``v`` [m/s], and the Rayleigh time of the smallest particle."""
        e_star, _ = self.wall_moduli(wall)
        return self._time_steps("wall", e_star, m, r, r_min, rho_min, v)

    def _time_steps(self, kind, e_star, m, r, r_min, rho_min, v) -> list[TimeStepCandidate]:
        rayleigh = rayleigh_time(r_min, rho_min, self.G, self.nu)
        return [
            *hertz_candidates(kind, m, r, e_star, self.restitution, v),
            TimeStepCandidate(
                kind, f"{kind} Rayleigh time of the smallest particle", rayleigh, False
            ),
        ]

    @property
    def G(self) -> float:
        """Shear modulus E / (2 (1 + nu)) [Pa]."""
        return self.E / (2.0 * (1.0 + self.nu))

    def pair_moduli(self) -> tuple[float, float]:
        """(E*, G*) [Pa] for a contact between two particles of this material."""
        e_star = 1.0 / (2.0 * (1.0 - self.nu**2) / self.E)
        g_star = 1.0 / (2.0 * (2.0 - self.nu) / self.G)
        return e_star, g_star

    def wall_moduli(self, wall: WallMaterial) -> tuple[float, float]:
        """(E*, G*) [Pa] for a contact between a particle of this material and ``wall``."""
        e_star = 1.0 / ((1.0 - self.nu**2) / self.E + (1.0 - wall.nu**2) / wall.E)
        g_star = 1.0 / ((2.0 - self.nu) / self.G + (2.0 - wall.nu) / wall.G)
        return e_star, g_star

    def slot_values(self, e_star: float, g_star: float) -> dict[str, float]:
        """The values the step kernel reads, by slot name (:data:`KERNEL`): effective moduli
        e_star, g_star [Pa] (from :meth:`pair_moduli` or :meth:`wall_moduli`), damping ratio on
        the contact stiffness zeta = sqrt(5/6) x the restitution's damping ratio (so that
        :math:`c = 2\\zeta\\sqrt{S m^*}` is the Tsuji damping
        :math:`-2\\sqrt{5/6}\\beta\\sqrt{S m^*}`), mu_s (the record's ``mu``), mu_r [-]."""
        return {
            "e_star": e_star,
            "g_star": g_star,
            "zeta": 0.5 * hertz_damping_factor(self.restitution),
            "mu_s": self.mu,
            "mu_r": self.mu_r,
        }

    def liggghts(self, owner: str | None = None) -> LiggghtsPair:
        """This law as LIGGGHTS 3.8's ``model hertz`` (pairs) and ``wall/gran model hertz``
        (walls) take it (engine/contact/export.py): restitution, friction ``mu`` and rolling
        friction per atom type pair, E [Pa] and nu per atom type. No fragment on its own: a
        deck writes E and nu for the particles and the platens together
        (:mod:`engine.io.liggghts_deck`). ``owner`` is not read (every value exports)."""
        return LiggghtsPair(
            law=type(self).__name__,
            model="hertz",
            coefficients=gran_coefficients(
                self.restitution, self.mu, self.mu_r, ("restitution", "mu", "mu_r")
            ),
            atom_type=elastic_atom_type(self.E, self.nu),
            differences=(
                "Coulomb cap: LIGGGHTS mu |F_n| with damping, this law mu times the elastic force",
            ),
            deck_differences=(
                "Hertz pairs: LIGGGHTS caps friction at mu |F_n| with damping, demscale at mu "
                "times the elastic force; rolling friction (cdt) as for the platens",
            ),
            fragment="LIGGGHTS' hertz model reads E and nu per atom type (youngsModulus, "
            "poissonsRatio), for the particles' pairs and walls alike: export it in a deck "
            "(engine.io.liggghts_deck, demscale export-test)",
        )

    def to_array(self, slots: tuple[str, ...] | None = None) -> np.ndarray:
        """Kernel parameter array of a pair of particles of this material
        (:meth:`pair_values`): the values of ``slots`` (default: every slot of the law's
        kernel) in order, then a trailing NaN (where a kernel's absent slots point)."""
        return law_array(self.pair_values(), self.kernel, slots)
