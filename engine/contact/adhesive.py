"""What the adhesive elasto-plastic laws share (:class:`engine.BilinearAdhesive`,
:class:`engine.EEPA`): their derived values, how the scaling rules act on them, their slot
values, switches, adhesion overlap, time-step limits and their LIGGGHTS mapping (LIGGGHTS
3.8's ``edinburgh/stiffness`` model, engine/io/liggghts.py's docstring). Each law's module
adds its record and its force kernel."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ..core.errors import ParameterError
from .export import LiggghtsPair, LiggghtsProperty, gran_coefficients
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


#: The ``fix property/global`` names of LIGGGHTS' ``edinburgh/stiffness`` model, in the order
#: a fragment sets them: the granular coefficients, then the model's own.
EDINBURGH_PROPERTIES = (
    "coefficientRestitution",
    "coefficientFriction",
    "coefficientRollingFriction",
    "LoadingStiffness",
    "UnloadingStiffness",
    "overlapExponent",
    "adhesionExponent",
    "pullOffForce",
    "surfaceEnergy",
    "coefficientAdhesionStiffness",
)


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

    def liggghts_adhesive_branch(self, owner: str | None = None) -> tuple[float, str]:
        """LIGGGHTS' ``coefficientAdhesionStiffness`` (kadh / K1 [-]) and the pair style's
        settings for the adhesive branch: (0, "") for kadh = 0 (``fixKc`` off,
        ``surfaceEnergy`` 0: no branch); (kadh / K1, " fixKc on limitForce off") for kadh > 0
        with n = chi = 1 (engine/io/liggghts.py's docstring). Raises
        :class:`engine.ParameterError` at ``<owner>.kadh`` (default owner: the law's name) for
        kadh > 0 with n or chi != 1."""
        if self.kadh == 0.0:
            return 0.0, ""
        if self.n != 1.0 or self.chi != 1.0:
            raise ParameterError(
                f"{owner or type(self).__name__}.kadh",
                self.kadh,
                f"0 to export to LIGGGHTS with n = {self.n:g}, chi = {self.chi:g} (kadh > 0 "
                "needs n = chi = 1)",
                "on its adhesive branch LIGGGHTS 3.8 resets dmax = (K2 + kadh) / (K2 - K1) d "
                "(normal_model_edinburgh_stiffness.h line 286), the n = chi = 1 formula: for "
                "other exponents the moved K2 branch misses the contact's point and the force "
                "jumps at every step on the branch",
            )
        return self.kadh / self.k1, " fixKc on limitForce off"

    def liggghts_differences(self) -> tuple[str, ...]:
        """What LIGGGHTS' ``edinburgh/stiffness`` does differently from this law (empty when
        it is the same law): tangential stiffness K1, Coulomb cap mu_s |F_n|, force
        clipping without adhesion, the plastic adhesive branch, damping for n != 1."""
        n = self.n
        out = []
        if not (n == 1.0 and self.kt_ratio == 1.0):
            out.append(
                f"tangential stiffness: LIGGGHTS uses K1, this law kt_ratio = {self.kt_ratio:g} "
                "x " + ("K1" if n == 1.0 else "the loading tangent n K1 d^(n-1)")
            )
        if self.friction_cap != "normal":
            out.append(
                "Coulomb cap: LIGGGHTS mu_s |F_n|, this law mu_s |f_hys - f0 + kadh d^chi| "
                "(friction_cap='adhesive')"
            )
        if self.f0 == 0.0 and self.kadh == 0.0 and self.restitution < 1.0:
            out.append(
                "separation: with f0 = kadh = 0 LIGGGHTS clips the total normal force, damping "
                "included, at zero (limitForce); this law lets damping pull on a separating "
                "contact, so a pair leaves an impact slower"
            )
        if self.kadh > 0.0:
            out.append(
                "adhesive branch: LIGGGHTS' is plastic, this law's reversible; on it LIGGGHTS "
                "resets dmax = (K2 + kadh) / (K2 - K1) d every step, so a contact that closes "
                "again from the branch reloads along K2 from where it is, its old dmax "
                "forgotten; this law's goes back along f0 - kadh d to its K2 branch (the same "
                "force while the contact only opens)"
            )
        if n != 1.0:
            out.append(
                "damping: LIGGGHTS' is constant (from K1), this law's follows the tangent "
                "stiffness; matched_restitution(restitution, n, d) gives LIGGGHTS' restitution "
                "with the same damping at an overlap d"
            )
        return tuple(out)

    def liggghts(self, owner: str | None = None) -> LiggghtsPair:
        """This law as LIGGGHTS 3.8's ``edinburgh/stiffness`` model (engine/contact/export.py;
        the mapping: engine/io/liggghts.py's docstring): K1 [N/m^n], K2 / K1, n, chi, f0 [N],
        kadh / K1 on the ``fixKc on`` path. Raises :class:`engine.ParameterError` at
        ``<owner>.kadh`` for an adhesive branch LIGGGHTS cannot follow
        (:meth:`liggghts_adhesive_branch`)."""
        n, chi = float(self.n), float(self.chi)
        ratio, settings = self.liggghts_adhesive_branch(owner)
        name = type(self).__name__
        unit = "N/m" if n == 1.0 else f"N/m^{n:g}"
        # the model's own properties: value, meaning (with its unit), the law's field
        own = {
            "LoadingStiffness": (self.k1, f"virgin loading stiffness K1 [{unit}]", "k1"),
            "UnloadingStiffness": (
                self.k2 / self.k1,
                f"RATIO K2 / K1 [-] of unloading to loading stiffness, not a stiffness: "
                f"K2 = {self.k2!r} {unit}",
                "k2",
            ),
            "overlapExponent": (
                n,
                f"overlap exponent n [-] of the loading branch (K1 d^n); {n:g}: "
                + ("linear" if n == 1.0 else "non-linear"),
                "n",
            ),
            "adhesionExponent": (
                chi,
                f"adhesion exponent chi [-] of the adhesive branch; {chi:g}",
                "chi",
            ),
            "pullOffForce": (
                self.f0,
                "constant pull-off (adhesion) force f0 [N], <= 0 (0: none)",
                "f0",
            ),
            "surfaceEnergy": (
                0.0,
                "surface energy [J/m^2] from which LIGGGHTS computes the adhesive branch's "
                "stiffness per contact with fixKc off; 0 here, not read with fixKc on",
                "",
            ),
            "coefficientAdhesionStiffness": (
                ratio,
                "RATIO kadh / K1 [-] of the adhesive branch's stiffness to K1 (read with fixKc "
                f"on): kadh = {self.kadh!r} {unit}"
                + ("" if self.kadh else "; 0: no adhesive branch (fixKc off)"),
                "kadh",
            ),
        }
        scalar = ("overlapExponent", "adhesionExponent")
        differences = self.liggghts_differences()
        deck = list(differences)
        if self.f0 != 0.0 or self.kadh != 0.0:
            deck.append(
                "plastic reload: a LIGGGHTS contact below its plastic overlap that closes "
                "again reloads along K2 from the overlap of the step before; demscale's stays "
                "on the plateau f0 until the overlap is back at the plastic overlap"
            )
        if self.mu_r > 0.0:
            deck.append(
                "rolling friction: LIGGGHTS cdt mu_r K1 d R/2 against the relative spin; "
                "demscale mu_r |f_hys| R against the particle's own spin"
            )
        periodic = ()
        if self.k2 != self.k1:
            periodic = (
                "contact history across the periodic faces: LIGGGHTS (newton off) computes "
                "such a contact once from each particle, each with its own copy of the plastic "
                "history, and the copies part (the one handed to the partner at a list rebuild "
                "is negated): the two particles feel different forces, so the pair forces stop "
                "summing to zero; a cohesive bed of this law gains momentum and may not settle "
                "(docs/LIGGGHTS_DECK.md, the probe)",
            )
        branch = (
            f"kadh = {self.kadh!r} N/m (fixKc on: coefficientAdhesionStiffness = kadh / K1)"
            if ratio
            else "kadh = 0 (surfaceEnergy 0, fixKc off)"
        )
        return LiggghtsPair(
            law=name,
            model="edinburgh/stiffness",
            settings=settings,
            coefficients=gran_coefficients(self.restitution, self.mu_s, self.mu_r),
            properties=tuple(
                LiggghtsProperty(p, *own[p][:2], scalar=p in scalar, field=own[p][2])
                for p in EDINBURGH_PROPERTIES[3:]
            ),
            summary=f"K1 = {self.k1!r} {unit}, K2 = {self.k2!r} {unit}, n = {n:g}, "
            f"chi = {chi:g}, f0 = {self.f0!r} N, kadh = {self.kadh!r} {unit}"
            + (" (fixKc on: coefficientAdhesionStiffness = kadh / K1)" if ratio else ""),
            deck_summary=f"{name}: K1 = {self.k1!r} N/m^n, K2 = {self.k2!r} N/m^n, "
            f"n = {n:g}, chi = {chi:g}, f0 = {self.f0!r} N, {branch}",
            differences=differences,
            deck_differences=tuple(deck),
            periodic_differences=periodic,
        )

    def to_array(self, slots: tuple[str, ...] | None = None) -> np.ndarray:
        """Kernel parameter array: the values of ``slots`` (default: every slot of the
        law's kernel) in order, then a trailing NaN (where a kernel's absent slots point)."""
        return law_array(self.pair_values(), self.kernel, slots)
