"""The bilinear adhesive elasto-plastic law (linear EEPA; Thakur et al. 2013, 2014): its
record, its normal force kernel and its kernel family."""

from __future__ import annotations

from collections import namedtuple
from dataclasses import dataclass

from numba import njit

from ..core.config import NJIT_INLINE
from ..core.records import check_fields, param
from .adhesive import ADHESIVE_SLOTS, ADHESIVE_SWITCHES, AdhesiveLaw, check_k2
from .kernel import COMPOSITION_SWITCHES, LawKernel


@njit(**NJIT_INLINE)
def bilinear_normal_force(d, dmax, k1, k2, f0, kadh):
    r"""Hysteretic normal force of the bilinear adhesive elasto-plastic law.

    .. math::
        d_{max} \leftarrow \max(d_{max}, d),\quad d_p = (1 - K_1/K_2)\,d_{max},\quad
        f_{hys} = f_0 + \min\big(K_1 d,\ \max(K_2 (d - d_p),\ -k_{adh} d)\big)

    Args: overlap d [m] (> 0), largest overlap of this contact so far dmax [m], loading
    stiffness k1 [N/m], unloading/reloading stiffness k2 [N/m] (>= k1), adhesion f0 [N] (<= 0),
    adhesive branch slope kadh [N/m] (>= 0).
    Returns: (f_hys [N], updated dmax [m]). Reference: Thakur et al. 2014, Granular Matter 16:383.
    """
    if d > dmax:
        dmax = d
    dp = (1.0 - k1 / k2) * dmax
    f = f0 + min(k1 * d, max(k2 * (d - dp), -kadh * d))
    return f, dmax


#: The bilinear family's parameters as its kernels read them: k1, k2, kt [N/m], f0 [N],
#: kadh [N/m], zeta, mu_s, mu_r [-].
BilinearParams = namedtuple("BilinearParams", "k1 k2 f0 kadh kt zeta mu_s mu_r")
#: Its switches: the composition's, then adhesion (f0), the adhesive branch (kadh) and the
#: plastic unloading branch (k2 > k1).
BilinearSwitches = namedtuple("BilinearSwitches", (*COMPOSITION_SWITCHES, *ADHESIVE_SWITCHES))


@njit(**NJIT_INLINE)
def normal_force(d, dmax, r_star, law, flags):
    """The family's normal force (engine.contact.kernel): :func:`bilinear_normal_force`, or
    without plasticity the elastic line f0 + K1 d; stiffness K1; cap force
    f_el - f0 + kadh d (no friction on the adhesive plateau)."""
    if flags.plastic:
        f_el, dmax = bilinear_normal_force(d, dmax, law.k1, law.k2, law.f0, law.kadh)
    else:  # k2 == k1: no plastic overlap, linear elastic (plus the adhesion offset)
        if d > dmax:
            dmax = d
        f_el = law.f0 + law.k1 * d
    f_adh = law.kadh * d
    return f_el, law.k1, f_el - law.f0 + f_adh, 1.0, dmax


@njit(**NJIT_INLINE)
def tangential_stiffness(d, r_star, law, tangent):
    """The constant tangential stiffness Kt = kt_ratio K1 [N/m]."""
    return law.kt


KERNEL = LawKernel(
    name="bilinear",
    module=__name__,
    params=BilinearParams,
    switch_tuple=BilinearSwitches,
    slots=ADHESIVE_SLOTS,
    switches=ADHESIVE_SWITCHES,
    normal_force=normal_force,
    tangential_stiffness=tangential_stiffness,
)


@dataclass(frozen=True)
class BilinearAdhesive(AdhesiveLaw):
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

    kernel = KERNEL

    def __post_init__(self) -> None:
        check_fields(self, "BilinearAdhesive")
        check_k2(self, "BilinearAdhesive", "N/m")
