"""Contact-law parameter records: validated once in Python, read by the compiled kernels.

Each record is a frozen dataclass. Construction checks every field and raises
:class:`engine.ParameterError` naming the field and its allowed range. Each law states
everything the rest of the engine needs to know about it, so that nothing outside this module
asks which law it is (the LAMMPS ``GranularModel`` way):

- ``kernel``: the kernel family and its slot table (``engine.kernel.specialise.PAIR_SLOTS``);
- ``adhesive``: whether the scaling rules act on it (K1, K2, f0, kadh);
- ``pair``/``wall``: where it may be used (a scene's pair law, its wall law);
- :meth:`pair_features` / :meth:`wall_features`: the compile-time switches it turns on;
- :meth:`pair_values` / :meth:`wall_values`: the values of its kernel slots;
- :meth:`pair_time_steps` / :meth:`wall_time_steps`: its time-step limits
  (:mod:`engine.contact.limits`);
- :meth:`adhesion_overlap`: the overlap its adhesion alone holds a contact at.

:data:`LAWS` registers them by name (the ``type`` of a law in JSON).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..core.errors import ParameterError
from ..core.records import check_fields, param
from .limits import (
    TimeStepCandidate,
    damping_ratio,
    eepa_impact_overlap,
    hertz_candidates,
    oscillator_limit,
    rayleigh_time,
)


def _check(owner: str, name: str, value: float, ok: bool, limit: str, why: str = "") -> None:
    if not ok:
        raise ParameterError(f"{owner}.{name}", value, limit, why)


def hertz_damping_factor(restitution: float) -> float:
    r"""Positive Hertz-Mindlin damping factor :math:`-2\sqrt{5/6}\,\beta` [-] (Tsuji et al. 1992).

    .. math:: \beta = \ln e / \sqrt{\ln^2 e + \pi^2}, \quad
              F_d = -2\sqrt{5/6}\,\beta\,\sqrt{S\,m^*}\; v

    The force opposes the relative velocity ``v``; with ``e = 1`` the factor is 0.
    """
    return 2.0 * math.sqrt(5.0 / 6.0) * damping_ratio(restitution)


def pack_params(values: dict[str, float], slots: tuple[str, ...]) -> np.ndarray:
    """Flat float64 kernel parameter array: ``values[name]`` for each slot name in order, then
    a trailing NaN slot. engine.kernel.specialise points every parameter a specialised kernel does
    not use at that NaN, so reading one by mistake poisons the run instead of reading a neighbour.
    """
    return np.array([values[name] for name in slots] + [math.nan], dtype=np.float64)


class _AdhesiveLaw:
    """What the bilinear and the EEPA law share: the derived values, the scaling and the
    kernel parameters. The bilinear law is the EEPA law with n = chi = 1 (class attributes
    here; fields of :class:`EEPA`)."""

    n = 1.0
    chi = 1.0
    kernel = "bilinear"
    adhesive = True
    pair = True
    wall = False

    @property
    def kt(self) -> float:
        """Tangential stiffness coefficient kt_ratio * k1 [N/m^n]: the contact's
        K_t = kt n d^(n-1) [N/m] (the bilinear law: K_t = kt)."""
        return self.kt_ratio * self.k1

    @property
    def zeta(self) -> float:
        """Damping ratio from the restitution [-]."""
        return damping_ratio(self.restitution)

    def similarity_exponents(self) -> tuple[float, float, float]:
        """Exponents (stiffness, adhesion, adhesive branch) that keep the law geometrically
        and stress similar (overlaps ~ s, forces ~ s^2): K ~ s^(2-n), f0 ~ s^2,
        kadh ~ s^(2-chi); (1, 2, 1) for the bilinear law, the rule of Thakur et al. 2013."""
        return 2.0 - self.n, 2.0, 2.0 - self.chi

    def scaled(
        self,
        s: float,
        stiffness_exponent: float,
        adhesion_exponent: float,
        adhesive_exponent: float | None = None,
    ):
        """The law for particles ``s`` times the reference size: K1, K2 (and so Kt) times
        ``s**stiffness_exponent``, f0 times ``s**adhesion_exponent``, kadh times
        ``s**adhesive_exponent`` (default: the stiffness exponent). Friction coefficients and
        restitution do not scale."""
        c = stiffness_exponent if adhesive_exponent is None else adhesive_exponent
        ks = s**stiffness_exponent
        return replace(
            self,
            k1=self.k1 * ks,
            k2=self.k2 * ks,
            kadh=self.kadh * s**c,
            f0=self.f0 * s**adhesion_exponent,
        )

    def kernel_params(self) -> dict[str, float]:
        """The values the step kernel reads, by slot name (engine.kernel.specialise.PAIR_SLOTS):
        k1, k2, kt [N/m^n], kadh [N/m^chi], f0 [N], damping ratio zeta, mu_s, mu_r, and the
        exponents n, chi [-] (bilinear: n = chi = 1, units N/m)."""
        return {
            "k1": self.k1,
            "k2": self.k2,
            "f0": self.f0,
            "kadh": self.kadh,
            "kt": self.kt,
            "zeta": self.zeta,
            "mu_s": self.mu_s,
            "mu_r": self.mu_r,
            "n": self.n,
            "chi": self.chi,
        }

    def pair_features(self) -> dict[str, bool]:
        """The step kernel's switches this law turns on (engine.kernel.specialise.FEATURES)."""
        return {
            "adhesion": self.f0 != 0,
            "adhesive_branch": self.kadh > 0,
            "plastic": self.k2 > self.k1,
            "friction": self.mu_s > 0,
            "rolling": self.mu_r > 0,
            "damping": self.restitution < 1,
        }

    def pair_values(self) -> dict[str, float]:
        """Kernel slot values of a particle-particle contact (:meth:`kernel_params`)."""
        return self.kernel_params()

    def adhesion_overlap(self, rmin: float, fraction: float) -> float | None:
        """Overlap (|f0|/k1)^(1/n) [m] at which adhesion alone holds a contact on the
        loading branch, when it lies beyond ``fraction`` x the smallest radius ``rmin`` [m];
        None when it does not (or f0 = 0)."""
        if self.f0 < 0:
            d_eq = (-self.f0 / self.k1) ** (1.0 / self.n)
            if d_eq > fraction * rmin:
                return d_eq
        return None

    def pair_time_steps(
        self, m_eff: float, r_eff: float, r_min: float, rho_min: float, v: float
    ) -> list[TimeStepCandidate]:
        """Stability limits of the lightest pair (reduced mass ``m_eff`` [kg]) at the expected
        speed ``v`` [m/s]: the K2 branch with the damping of K1, and the tangential spring
        with rotation. (``r_eff``, ``r_min``, ``rho_min`` are for laws that need them.)"""
        zeta = damping_ratio(self.restitution)
        # the tangent stiffnesses n K d^(n-1) at the largest expected overlap, that of a
        # head-on impact of two particles each at the expected speed (n = 1: K itself)
        tangent, where, unit = 1.0, "", "N/m"
        if self.n != 1.0:
            d_exp = eepa_impact_overlap(m_eff, self, 2.0 * v)
            tangent = self.n * d_exp ** (self.n - 1.0)
            where = f" x n d^(n-1) at the overlap {d_exp:.3g} m of a {2 * v:.3g} m/s head-on impact"
            unit = "N/m^n"
        # damping c_n = 2 zeta sqrt(m K1) seen by the stiffer K2 branch
        out = [
            TimeStepCandidate(
                "pair",
                f"pair unloading stiffness k2 = {self.k2:g} {unit}{where}, lightest pair",
                oscillator_limit(self.k2 * tangent, m_eff, zeta * math.sqrt(self.k1 / self.k2)),
                True,
            )
        ]
        if self.mu_s > 0 and self.kt > 0:
            # relative tangential motion with rotation: 1/m_t = 3.5 (1/mi + 1/mj)
            out.append(
                TimeStepCandidate(
                    "pair",
                    f"pair tangential stiffness kt = {self.kt:g} {unit}{where} with rotation",
                    oscillator_limit(3.5 * self.kt * tangent, m_eff, zeta * math.sqrt(3.5)),
                    True,
                )
            )
        return out

    def to_array(
        self, slots: tuple[str, ...] = ("k1", "k2", "f0", "kadh", "kt", "zeta", "mu_s", "mu_r")
    ) -> np.ndarray:
        """Kernel parameter array: the values of ``slots`` in order, then a trailing NaN
        (where the kernel's absent slots point, see engine.kernel.specialise)."""
        return pack_params(self.kernel_params(), slots)


@dataclass(frozen=True)
class BilinearAdhesive(_AdhesiveLaw):
    r"""Bilinear adhesive elasto-plastic pair law (linear EEPA, Thakur et al. 2014).

    .. math::
        d_p = (1 - K_1/K_2)\,d_{max}, \qquad
        f_{hys} = f_0 + \min\big(K_1 d,\ \max(K_2 (d - d_p),\ -k_{adh} d)\big)

    plus viscous normal damping :math:`c_n = 2\zeta\sqrt{m_{eff} K_1}`, an incremental linear
    tangential spring :math:`K_t = \text{kt\_ratio}\,K_1` with damping
    :math:`c_t = 2\zeta\sqrt{m_{eff} K_t}` and the adhesion-aware Coulomb cap
    :math:`|F_t| \le \mu_s |f_{hys} - f_0 + k_{adh} d|`, and the constant directional rolling
    torque :math:`\tau = -\mu_r |f_{hys}| R\,\hat\omega`.

    Attributes:
        k1: virgin loading stiffness K1 [N/m], > 0.
        k2: unloading/reloading stiffness K2 [N/m], >= k1 (k2 == k1: elastic, no plasticity).
        f0: adhesion (pull-off) force f0 [N], <= 0 (0: cohesionless).
        kadh: slope of the adhesive branch k_adh [N/m], >= 0 (0 in Thakur et al. 2013).
        kt_ratio: tangential stiffness as a fraction of k1 [-], >= 0 (2/7 by default).
        mu_s: static (sliding) friction coefficient [-], >= 0 (0: frictionless).
        mu_r: rolling friction coefficient [-], >= 0.
        restitution: coefficient of restitution setting the damping ratio [-], in (0, 1].
    """

    k1: float = param(unit="N/m", doc="virgin loading stiffness K1", gt=0)
    k2: float = param(unit="N/m", doc="unloading/reloading stiffness K2 (>= k1)", gt=0)
    f0: float = param(0.0, unit="N", doc="adhesion (pull-off) force, <= 0", le=0)
    kadh: float = param(0.0, unit="N/m", doc="slope of the adhesive branch", ge=0)
    kt_ratio: float = param(2.0 / 7.0, unit="1", doc="tangential stiffness / k1", ge=0)
    mu_s: float = param(0.5, unit="1", doc="sliding friction coefficient", ge=0)
    mu_r: float = param(0.001, unit="1", doc="rolling friction coefficient", ge=0)
    restitution: float = param(0.4, unit="1", doc="coefficient of restitution", gt=0, le=1)

    def __post_init__(self) -> None:
        o = "BilinearAdhesive"
        check_fields(self, o)
        _check(
            o,
            "k2",
            self.k2,
            self.k2 >= self.k1,
            f">= k1 = {self.k1:g} N/m",
            "unloading must be at least as stiff as loading",
        )


#: Friction cap conventions of :class:`EEPA`: ``"adhesive"`` (default, the EEPA papers and
#: this engine: :math:`\mu_s|f_{hys} - f_0 + k_{adh}d^\chi|`, no friction on the adhesive
#: plateau) or ``"normal"`` (LIGGGHTS ``model edinburgh``: :math:`\mu_s|F_n|`, the total normal
#: force with f0 and damping).
FRICTION_CAPS = ("adhesive", "normal")


@dataclass(frozen=True)
class EEPA(_AdhesiveLaw):
    r"""Edinburgh elasto-plastic adhesion law, non-linear (Morrissey 2013; Thakur et al. 2014).

    .. math::
        d_{max} \leftarrow \max(d_{max}, d),\quad
        d_p^n = (1 - K_1/K_2)\,d_{max}^n,\quad
        f_{hys} = f_0 + \min\big(K_1 d^n,\ \max(K_2 (d^n - d_p^n),\ -k_{adh} d^\chi)\big)

    so the plastic overlap is :math:`d_p = (1 - K_1/K_2)^{1/n} d_{max}`. Damping, tangential
    spring, friction and rolling are those of :class:`BilinearAdhesive`, with the contact's
    loading-branch tangent stiffness :math:`S = n K_1 d^{n-1}` [N/m] in place of K1:
    :math:`c_n = 2\zeta\sqrt{m_{eff} S}`, :math:`K_t = \text{kt\_ratio}\,S`,
    :math:`c_t = 2\zeta\sqrt{m_{eff} K_t}`; the Coulomb cap is
    :math:`\mu_s |f_{hys} - f_0 + k_{adh} d^\chi|` (``friction_cap="adhesive"``) or
    :math:`\mu_s |F_n|` (``"normal"``, the LIGGGHTS convention). With n = chi = 1 and the
    adhesive cap it is :class:`BilinearAdhesive`, to the last bit (tests/engine/test_eepa.py).
    docs/PHYSICS.md section 8.

    Attributes:
        k1: virgin loading stiffness K1 [N/m^n], > 0.
        k2: unloading/reloading stiffness K2 [N/m^n], >= k1.
        f0: adhesion (pull-off) force f0 [N], <= 0.
        kadh: adhesive branch stiffness k_adh [N/m^chi], >= 0.
        n: overlap exponent of the loading and unloading branches [-], in [1, 3] (1.5: Hertz-
            like; below 1 the tangent stiffness is infinite at first touch).
        chi: exponent of the adhesive branch [-], in [1, 3].
        kt_ratio: tangential stiffness as a fraction of the loading tangent stiffness [-].
        mu_s: sliding friction coefficient [-], >= 0.
        mu_r: rolling friction coefficient [-], >= 0.
        restitution: coefficient of restitution setting the damping ratio [-], in (0, 1].
        friction_cap: ``"adhesive"`` or ``"normal"`` (:data:`FRICTION_CAPS`).
    """

    k1: float = param(unit="N/m^n", doc="virgin loading stiffness K1", gt=0)
    k2: float = param(unit="N/m^n", doc="unloading/reloading stiffness K2 (>= k1)", gt=0)
    f0: float = param(0.0, unit="N", doc="adhesion (pull-off) force, <= 0", le=0)
    kadh: float = param(0.0, unit="N/m^chi", doc="adhesive branch stiffness", ge=0)
    n: float = param(
        1.5, unit="1", doc="overlap exponent n of the loading and unloading branches", ge=1, le=3
    )
    chi: float = param(1.5, unit="1", doc="exponent chi of the adhesive branch", ge=1, le=3)
    kt_ratio: float = param(
        2.0 / 7.0,
        unit="1",
        doc="tangential stiffness / loading tangent stiffness n k1 d^(n-1)",
        ge=0,
    )
    mu_s: float = param(0.5, unit="1", doc="sliding friction coefficient", ge=0)
    mu_r: float = param(0.001, unit="1", doc="rolling friction coefficient", ge=0)
    restitution: float = param(0.4, unit="1", doc="coefficient of restitution", gt=0, le=1)
    friction_cap: str = param(
        "adhesive",
        unit="",
        kind="str",
        choices=FRICTION_CAPS,
        doc="Coulomb cap: mu_s |f_hys - f0 + kadh d^chi| (adhesive) or "
        "mu_s |F_n| (normal, as LIGGGHTS)",
    )

    def __post_init__(self) -> None:
        o = "EEPA"
        check_fields(self, o)
        _check(
            o,
            "k2",
            self.k2,
            self.k2 >= self.k1,
            f">= k1 = {self.k1:g} N/m^n",
            "unloading must be at least as stiff as loading",
        )

    def pair_features(self) -> dict[str, bool]:
        # n = chi = 1 still takes the EEPA branches: the law a user chose is the law run
        return {
            **super().pair_features(),
            "eepa": True,
            "normal_cap": self.friction_cap == "normal" and self.mu_s > 0,
        }


@dataclass(frozen=True)
class HertzMindlin:
    r"""Hertz-Mindlin (no slip) contact law; for walls and, selectable, for particle pairs.

    .. math::
        F_n = \tfrac43 E^*\sqrt{R^*}\,d^{3/2},\quad S_n = 2E^*\sqrt{R^* d},\quad
        S_t = 8G^*\sqrt{R^* d},\quad F_d = -2\sqrt{5/6}\,\beta\sqrt{S m^*}\,v,\quad
        |F_t| \le \mu F_n

    Attributes:
        E: Young's modulus of the particle material [Pa], > 0.
        nu: Poisson's ratio of the particle material [-], in (-1, 0.5).
        restitution: coefficient of restitution [-], in (0, 1].
        mu: sliding friction coefficient [-], >= 0.
        mu_r: rolling friction coefficient [-], >= 0 (constant directional torque).
    """

    E: float = param(unit="Pa", doc="Young's modulus of the particle material", gt=0)
    nu: float = param(0.25, unit="1", doc="Poisson's ratio of the particle material", gt=-1, lt=0.5)
    restitution: float = param(0.4, unit="1", doc="coefficient of restitution", gt=0, le=1)
    mu: float = param(0.3, unit="1", doc="sliding friction coefficient", ge=0)
    mu_r: float = param(0.0, unit="1", doc="rolling friction coefficient", ge=0)

    kernel = "hertz"
    adhesive = False
    pair = True
    wall = True

    def __post_init__(self) -> None:
        check_fields(self, "HertzMindlin")

    def pair_features(self) -> dict[str, bool]:
        """The step kernel's switches this law turns on as the pair law."""
        return {
            "pair_hertz": True,
            "friction": self.mu > 0,
            "rolling": self.mu_r > 0,
            "damping": self.restitution < 1,
        }

    def wall_features(self) -> dict[str, bool]:
        """The step kernel's switches this law turns on as the wall law."""
        return {
            "wall_friction": self.mu > 0,
            "wall_rolling": self.mu_r > 0,
            "wall_damping": self.restitution < 1,
        }

    def pair_values(self) -> dict[str, float]:
        """Kernel slot values of a contact between two particles of this material."""
        return self.kernel_params(*self.pair_moduli())

    def wall_values(self, wall: WallMaterial) -> dict[str, float]:
        """Kernel slot values of a contact between a particle of this material and ``wall``."""
        return self.kernel_params(*self.wall_moduli(wall))

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
        out = hertz_candidates(
            "pair", np.array([m_eff]), np.array([r_eff]), e_star, self.restitution, v
        )
        out.append(
            TimeStepCandidate(
                "pair",
                "pair Rayleigh time of the smallest particle",
                rayleigh_time(r_min, rho_min, self.G, self.nu),
                False,
            )
        )
        return out

    def wall_time_steps(
        self, wall: WallMaterial, m, r, r_min: float, rho_min: float, v: float
    ) -> list[TimeStepCandidate]:
        """The Hertz limits of particles of masses ``m`` [kg] and radii ``r`` [m] on
        ``wall`` at ``v`` [m/s], and the Rayleigh time of the smallest particle."""
        e_star, _ = self.wall_moduli(wall)
        out = hertz_candidates("wall", m, r, e_star, self.restitution, v)
        out.append(
            TimeStepCandidate(
                "wall",
                "wall Rayleigh time of the smallest particle",
                rayleigh_time(r_min, rho_min, self.G, self.nu),
                False,
            )
        )
        return out

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

    def kernel_params(self, e_star: float, g_star: float) -> dict[str, float]:
        """The values the step kernel reads, by slot name (engine.kernel.specialise.PAIR_SLOTS and
        WALL_SLOTS): effective moduli e_star, g_star [Pa] (from :meth:`pair_moduli` or
        :meth:`wall_moduli`), damping ratio on the contact stiffness zeta = sqrt(5/6) x
        the restitution's damping ratio (so that :math:`c = 2\\zeta\\sqrt{S m^*}` is the Tsuji
        damping :math:`-2\\sqrt{5/6}\\beta\\sqrt{S m^*}`), mu_s (the record's ``mu``), mu_r [-]."""
        return {
            "e_star": e_star,
            "g_star": g_star,
            "zeta": 0.5 * hertz_damping_factor(self.restitution),
            "mu_s": self.mu,
            "mu_r": self.mu_r,
        }

    def to_array(
        self,
        e_star: float,
        g_star: float,
        slots: tuple[str, ...] = ("e_star", "g_star", "zeta", "mu_s", "mu_r"),
    ) -> np.ndarray:
        """Kernel parameter array: the values of ``slots`` in order, then a trailing NaN."""
        return pack_params(self.kernel_params(e_star, g_star), slots)


@dataclass(frozen=True)
class WallMaterial:
    """Elastic properties of a wall (platen) for the Hertz-Mindlin wall law.

    Attributes:
        E: Young's modulus [Pa], > 0 (steel: 2e11).
        nu: Poisson's ratio [-], in (-1, 0.5).
    """

    E: float = param(2e11, unit="Pa", doc="Young's modulus of the wall", gt=0)
    nu: float = param(0.3, unit="1", doc="Poisson's ratio of the wall", gt=-1, lt=0.5)

    def __post_init__(self) -> None:
        check_fields(self, "WallMaterial")

    @property
    def G(self) -> float:
        """Shear modulus [Pa]."""
        return self.E / (2.0 * (1.0 + self.nu))


#: Every contact law by name (the ``type`` of a law in JSON); a new law is a record with the
#: attributes and methods listed in this module's docstring, added here.
LAWS: dict[str, type] = {
    "BilinearAdhesive": BilinearAdhesive,
    "EEPA": EEPA,
    "HertzMindlin": HertzMindlin,
}


#: The adhesive elasto-plastic pair laws: the scaling rules act on their K1, K2, f0, kadh.
ADHESIVE_LAWS = tuple(c for c in LAWS.values() if c.adhesive)


def adhesive_laws() -> tuple[type, ...]:
    """The registered laws the scaling rules act on (``adhesive``)."""
    return tuple(c for c in LAWS.values() if c.adhesive)


def pair_laws() -> tuple[type, ...]:
    """The laws a scene may take as its pair law."""
    return tuple(c for c in LAWS.values() if c.pair)


def wall_laws() -> tuple[type, ...]:
    """The laws a scene may take as its wall law."""
    return tuple(c for c in LAWS.values() if c.wall)


def law_names(laws) -> str:
    """``engine.A, engine.B or engine.C``: the laws' names for an error message."""
    names = [f"engine.{c.__name__}" for c in laws]
    return names[0] if len(names) == 1 else ", ".join(names[:-1]) + " or " + names[-1]
