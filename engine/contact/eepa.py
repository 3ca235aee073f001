"""The Edinburgh elasto-plastic adhesion law, non-linear (EEPA; Morrissey 2013, Thakur et al.
2014): its record, its normal force kernel, its impact overlap and its kernel family
(docs/PHYSICS.md section 8)."""

from __future__ import annotations

from collections import namedtuple
from dataclasses import dataclass

from numba import njit

from ..core.config import NJIT_INLINE
from ..core.records import check_fields, param
from .adhesive import ADHESIVE_SLOTS, ADHESIVE_SWITCHES, AdhesiveLaw, check_k2
from .kernel import COMPOSITION_SWITCHES, LawKernel, Slot


@njit(**NJIT_INLINE)
def eepa_normal_force(d, dmax, k1, k2, f0, kadh, n, chi):
    r"""Hysteretic normal force of the non-linear EEPA law (Morrissey 2013).

    .. math::
        d_{max} \leftarrow \max(d_{max}, d),\quad d_p^n = (1 - K_1/K_2)\,d_{max}^n,\quad
        f_{hys} = f_0 + \min\big(K_1 d^n,\ \max(K_2 (d^n - d_p^n),\ -k_{adh} d^\chi)\big)

    Args: overlap d [m] (> 0), largest overlap so far dmax [m], loading stiffness k1
    [N/m^n], unloading stiffness k2 [N/m^n] (>= k1), adhesion f0 [N] (<= 0), adhesive
    stiffness kadh [N/m^chi] (>= 0), exponents n, chi [-] (>= 1).
    Returns: (f_hys [N], tangent factor n d^(n-1) [m^(1-n)] (the loading tangent stiffness
    is K1 times it, the tangential stiffness kt times it), adhesive-branch pull kadh d^chi
    [N], updated dmax [m]). With n = chi = 1 every operation is that of
    :func:`bilinear_normal_force` (x**1.0 == x and x**0.0 == 1.0 exactly), so the force is the
    same to the last bit.
    """
    if d > dmax:
        dmax = d
    dn = d**n
    dpn = (1.0 - k1 / k2) * dmax**n
    f_adh = kadh * d**chi if kadh != 0.0 else 0.0  # no power where there is no branch
    f = f0 + min(k1 * dn, max(k2 * (dn - dpn), -f_adh))
    # n d^(n-1) as n d^n / d: one power less (d / d == 1 exactly, so n = 1 gives 1)
    return f, n * dn / d, f_adh, dmax


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


#: The EEPA family's parameters as its kernels read them: k1, k2, kt [N/m^n], f0 [N],
#: kadh [N/m^chi], zeta, mu_s, mu_r, n, chi [-].
EEPAParams = namedtuple("EEPAParams", "k1 k2 f0 kadh kt zeta mu_s mu_r n chi")
#: Its switches: the composition's, then adhesion (f0), the adhesive branch (kadh) and the
#: plastic unloading branch (k2 > k1; a K2 of K1 without it).
EEPASwitches = namedtuple("EEPASwitches", (*COMPOSITION_SWITCHES, *ADHESIVE_SWITCHES))


@njit(**NJIT_INLINE)
def normal_force(d, dmax, r_star, law, flags):
    """The family's normal force (engine.contact.kernel): :func:`eepa_normal_force`, with
    the loading tangent stiffness n K1 d^(n-1) and the cap force f_el - f0 + kadh d^chi."""
    f_el, tangent, f_adh, dmax = eepa_normal_force(
        d, dmax, law.k1, law.k2, law.f0, law.kadh, law.n, law.chi
    )
    return f_el, tangent * law.k1, f_el - law.f0 + f_adh, tangent, dmax


@njit(**NJIT_INLINE)
def tangential_stiffness(d, r_star, law, tangent):
    """kt_ratio x the loading tangent stiffness, kt n d^(n-1) [N/m]."""
    return law.kt * tangent


KERNEL = LawKernel(
    name="eepa",
    module=__name__,
    params=EEPAParams,
    switch_tuple=EEPASwitches,
    slots=(*ADHESIVE_SLOTS, Slot("n"), Slot("chi")),
    switches=ADHESIVE_SWITCHES,
    normal_force=normal_force,
    tangential_stiffness=tangential_stiffness,
)


#: Friction cap conventions of :class:`EEPA`: ``"adhesive"`` (default, the EEPA papers and
#: this engine: :math:`\mu_s|f_{hys} - f_0 + k_{adh}d^\chi|`, no friction on the adhesive
#: plateau) or ``"normal"`` (LIGGGHTS ``model edinburgh``: :math:`\mu_s|F_n|`, the total normal
#: force with f0 and damping).
FRICTION_CAPS = ("adhesive", "normal")


@dataclass(frozen=True)
class EEPA(AdhesiveLaw):
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

    kernel = KERNEL

    def __post_init__(self) -> None:
        check_fields(self, "EEPA")
        check_k2(self, "EEPA", "N/m^n")

    def impact_tangent(self, m_eff: float, v: float) -> tuple[float, str, str]:
        """The tangent factor n d^(n-1) at the largest overlap of a head-on impact of two
        particles each at ``v`` [m/s] (:func:`eepa_impact_overlap`; 1 for n = 1)."""
        if self.n == 1.0:
            return super().impact_tangent(m_eff, v)
        d_exp = eepa_impact_overlap(m_eff, self, 2.0 * v)
        where = f" x n d^(n-1) at the overlap {d_exp:.3g} m of a {2 * v:.3g} m/s head-on impact"
        return self.n * d_exp ** (self.n - 1.0), where, "N/m^n"
