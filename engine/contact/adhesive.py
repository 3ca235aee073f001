"""What the adhesive elasto-plastic laws share (:class:`engine.BilinearAdhesive`,
:class:`engine.EEPA`): their derived values, how the scaling rules act on them, their slot
values, switches, adhesion overlap and time-step limits. Each law's module adds its record
and its force kernel."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ..core.errors import ParameterError
from .kernel import Slot, law_array
from .limits import TimeStepCandidate, damping_ratio, oscillator_limit

#: The slots both adhesive families read, in order (the EEPA law adds its exponents): K2 is
#: K1 without the plastic branch, the others 0 when their switch is off.
ADHESIVE_SLOTS = (
    Slot("k1"),
    Slot("k2", "plastic", "k1"),
    Slot("f0", "adhesion"),
    Slot("kadh", "adhesive_branch"),
    Slot("kt", "friction"),
    Slot("zeta", "damping"),
    Slot("mu_s", "friction"),
    Slot("mu_r", "rolling"),
)

#: The adhesive families' own switches, with what each adds.
ADHESIVE_SWITCHES = {
    "adhesion": "adhesive force f0",
    "adhesive_branch": "adhesive branch kadh",
    "plastic": "plastic unloading branch (k2 > k1)",
}


def check_k2(law, owner: str, unit: str) -> None:
    """Raise :class:`engine.ParameterError` unless K2 >= K1 (``unit``: theirs)."""
    if not law.k2 >= law.k1:
        raise ParameterError(
            f"{owner}.k2",
            law.k2,
            f">= k1 = {law.k1:g} {unit}",
            "unloading must be at least as stiff as loading",
        )


class AdhesiveLaw:
    """Base of the adhesive elasto-plastic laws (fields k1, k2, f0, kadh, kt_ratio, mu_s,
    mu_r, restitution; exponents n, chi: class attributes of 1 for the bilinear law, fields of
    the EEPA law). The scaling rules act on these laws' K1, K2, f0 and kadh."""

    n = 1.0
    chi = 1.0
    friction_cap = "adhesive"
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

    def pair_values(self) -> dict[str, float]:
        """The values of the kernel's slots, by name: k1, k2, kt [N/m^n], kadh [N/m^chi],
        f0 [N], damping ratio zeta, mu_s, mu_r, and the exponents n, chi [-] (bilinear:
        n = chi = 1, units N/m)."""
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

    def switches(self) -> dict[str, bool]:
        """The step kernel's switches this law turns on (its kernel's and the
        composition's)."""
        return {
            "adhesion": self.f0 != 0,
            "adhesive_branch": self.kadh > 0,
            "plastic": self.k2 > self.k1,
            "friction": self.mu_s > 0,
            "rolling": self.mu_r > 0,
            "damping": self.restitution < 1,
            "normal_cap": self.friction_cap == "normal" and self.mu_s > 0,
        }

    def adhesion_overlap(self, rmin: float, fraction: float) -> float | None:
        """Overlap (|f0|/k1)^(1/n) [m] at which adhesion alone holds a contact on the
        loading branch, when it lies beyond ``fraction`` x the smallest radius ``rmin`` [m];
        None when it does not (or f0 = 0)."""
        if self.f0 < 0:
            d_eq = (-self.f0 / self.k1) ** (1.0 / self.n)
            if d_eq > fraction * rmin:
                return d_eq
        return None

    def load_overlap(self, force: float, radius: float) -> tuple[float, str]:
        """Overlap [m] at which the virgin loading branch carries a compressive ``force`` [N]
        (adhesion included: K1 d^n = force + |f0|), and the parameter that sets it."""
        return ((force - self.f0) / self.k1) ** (1.0 / self.n), "k1"

    def impact_tangent(self, m_eff: float, v: float) -> tuple[float, str, str]:
        """The factor n d^(n-1) [m^(1-n)] that turns K into the tangent stiffness at the
        largest overlap of a head-on impact of two particles each at ``v`` [m/s] (reduced
        mass ``m_eff`` [kg]), the words that say so, and the unit of K. The bilinear law: 1."""
        return 1.0, "", "N/m"

    def pair_time_steps(
        self, m_eff: float, r_eff: float, r_min: float, rho_min: float, v: float
    ) -> list[TimeStepCandidate]:
        """Stability limits of the lightest pair (reduced mass ``m_eff`` [kg]) at the expected
        speed ``v`` [m/s]: the K2 branch with the damping of K1, and the tangential spring
        with rotation. (``r_eff``, ``r_min``, ``rho_min`` are for laws that need them.)"""
        zeta = damping_ratio(self.restitution)
        tangent, where, unit = self.impact_tangent(m_eff, v)
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

    def to_array(self, slots: tuple[str, ...] | None = None) -> np.ndarray:
        """Kernel parameter array: the values of ``slots`` (default: every slot of the
        law's kernel) in order, then a trailing NaN (where a kernel's absent slots point)."""
        return law_array(self.pair_values(), self.kernel, slots)
