"""A contact law, fine or scaled, out to LIGGGHTS and back (docs/LIGGGHTS_EEPA.md).

:func:`to_liggghts` writes the ``fix property/global`` lines and the ``pair_style`` of
LIGGGHTS 3.8's ``edinburgh/stiffness`` model (the EEPA law; the bilinear law is its n = chi
= 1 case) for one atom type, SI units, mapped as benchmarks/liggghts_eepa.py maps it and as
docs/LIGGGHTS_EEPA.md checks it against LIGGGHTS on one packing:

=================  ===========================================
demscale           LIGGGHTS ``fix property/global``
=================  ===========================================
k1                 ``LoadingStiffness`` (peratomtypepair)
k2                 ``UnloadingStiffness`` = K2 / K1 (a ratio)
n, chi             ``overlapExponent``, ``adhesionExponent`` (scalar)
f0                 ``pullOffForce`` [N]
kadh = 0           ``surfaceEnergy`` 0 with ``fixKc`` off
restitution        ``coefficientRestitution``
mu_s, mu_r         ``coefficientFriction``, ``coefficientRollingFriction``
=================  ===========================================

What LIGGGHTS cannot take is said, not hidden: its tangential stiffness is K1 whatever the
law's ``kt_ratio``, its Coulomb cap is mu |F_n| (EEPA's ``friction_cap="normal"``), and for
n != 1 its damping at a given restitution differs from demscale's (constant, from K1, against
demscale's from the tangent stiffness: :func:`matched_restitution`). Those go into the
fragment's comments and :func:`differences`. An adhesive branch (kadh > 0) is refused:
LIGGGHTS' ``fixKc`` path resets the plastic overlap with the n = 1 formula, and no mapping of
it has been checked. :func:`from_liggghts` reads such a fragment back into a law (LIGGGHTS'
conventions, or the bilinear law for n = chi = 1), and :func:`law_table` lists a law's
parameters with units (JSON or CSV).
"""

from __future__ import annotations

import csv
import io
import math
import re

from ..contact.bilinear import BilinearAdhesive
from ..contact.eepa import EEPA
from ..core.errors import ParameterError
from ..core.records import describe

#: The ``fix property/global`` names a fragment sets, in order.
PROPERTIES = (
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
_SCALAR = ("overlapExponent", "adhesionExponent")


def _meanings(law, n: float, chi: float) -> dict[str, str]:
    """What each property's value means, with its unit, for the fragment's comments: a
    LIGGGHTS user reads ``UnloadingStiffness 9.78`` as a stiffness otherwise."""
    k_unit = "N/m" if n == 1.0 else f"N/m^{n:g}"
    return {
        "coefficientRestitution": "normal coefficient of restitution [-] (sets the damping)",
        "coefficientFriction": "sliding friction coefficient mu_s [-]",
        "coefficientRollingFriction": "rolling friction coefficient mu_r [-] (cdt model)",
        "LoadingStiffness": f"virgin loading stiffness K1 [{k_unit}]",
        "UnloadingStiffness": f"RATIO K2 / K1 [-] of unloading to loading stiffness, not a "
        f"stiffness: K2 = {law.k2!r} {k_unit}",
        "overlapExponent": f"overlap exponent n [-] of the loading branch (K1 d^n); {n:g}: "
        + ("linear" if n == 1.0 else "non-linear"),
        "adhesionExponent": f"adhesion exponent chi [-] of the adhesive branch; {chi:g}",
        "pullOffForce": "constant pull-off (adhesion) force f0 [N], <= 0 (0: none)",
        "surfaceEnergy": "surface energy [J/m^2] from which LIGGGHTS computes the adhesive "
        "branch's stiffness kadh (fixKc off); 0: kadh = 0, no adhesive branch",
        "coefficientAdhesionStiffness": "adhesive branch stiffness kadh [N/m] for fixKc on; "
        "0, and not read with fixKc off",
    }


def _exponents(law) -> tuple[float, float]:
    if isinstance(law, EEPA):
        return law.n, law.chi
    if isinstance(law, BilinearAdhesive):
        return 1.0, 1.0
    raise ParameterError("law", type(law).__name__, "an engine.BilinearAdhesive or engine.EEPA")


def differences(law) -> list[str]:
    """What LIGGGHTS' ``edinburgh/stiffness`` does differently from ``law`` (module
    docstring): empty when the fragment is the same law."""
    n, _ = _exponents(law)
    out = []
    if not (n == 1.0 and law.kt_ratio == 1.0):
        out.append(
            f"tangential stiffness: LIGGGHTS uses K1, this law kt_ratio = {law.kt_ratio:g} x "
            + ("K1" if n == 1.0 else "the loading tangent n K1 d^(n-1)")
        )
    if getattr(law, "friction_cap", "adhesive") != "normal":
        out.append(
            "Coulomb cap: LIGGGHTS mu_s |F_n|, this law mu_s |f_hys - f0 + kadh d^chi| "
            "(friction_cap='adhesive')"
        )
    if law.f0 == 0.0 and law.kadh == 0.0 and law.restitution < 1.0:
        out.append(
            "separation: with f0 = kadh = 0 LIGGGHTS clips the total normal force, damping "
            "included, at zero (limitForce); this law lets damping pull on a separating "
            "contact, so a pair leaves an impact slower"
        )
    if n != 1.0:
        out.append(
            "damping: LIGGGHTS' is constant (from K1), this law's follows the tangent "
            "stiffness; matched_restitution(restitution, n, d) gives LIGGGHTS' restitution "
            "with the same damping at an overlap d"
        )
    return out


def matched_restitution(restitution: float, n: float, d: float) -> float:
    """LIGGGHTS restitution whose constant damping 2 zeta_L sqrt(m K1) equals demscale's
    2 zeta sqrt(m n K1 d^(n-1)) at the overlap ``d`` [m]: zeta_L = zeta sqrt(n d^(n-1)),
    e = exp(-pi zeta_L / sqrt(1 - zeta_L^2))."""
    from ..contact.limits import damping_ratio

    z = damping_ratio(restitution) * math.sqrt(n * d ** (n - 1.0))
    return math.exp(-math.pi * z / math.sqrt(1.0 - z * z))


def to_liggghts(law, atom_type: int = 1, note: str = "", radius: float | None = None) -> str:
    """The LIGGGHTS 3.8 input fragment of ``law`` (an :class:`engine.BilinearAdhesive` or
    :class:`engine.EEPA`, fine or scaled) for one ``atom_type``: ``fix property/global`` lines
    and the ``pair_style``/``pair_coeff``, SI units, each value's meaning and unit in a
    comment line above it, with what LIGGGHTS does differently in its comments; ``radius``
    [m], where known, the particle radius the law is for (a law is calibrated, or scaled,
    for one size). Raises :class:`engine.ParameterError` for kadh > 0 (module docstring)."""
    n, chi = _exponents(law)
    if law.kadh != 0.0:
        raise ParameterError(
            f"{type(law).__name__}.kadh",
            law.kadh,
            "0 to export to LIGGGHTS",
            "LIGGGHTS' adhesive branch (fixKc) resets the plastic overlap with the n = 1 "
            "formula and has no checked mapping here",
        )
    if atom_type != 1:
        raise ParameterError("atom_type", atom_type, "1 (one particle type per fragment)")
    values = {
        "coefficientRestitution": law.restitution,
        "coefficientFriction": law.mu_s,
        "coefficientRollingFriction": law.mu_r,
        "LoadingStiffness": law.k1,
        "UnloadingStiffness": law.k2 / law.k1,
        "overlapExponent": n,
        "adhesionExponent": chi,
        "pullOffForce": law.f0,
        "surfaceEnergy": 0.0,
        "coefficientAdhesionStiffness": 0.0,
    }
    unit = "N/m" if n == 1.0 else f"N/m^{n:g}"
    lines = [
        f"# demscale {type(law).__name__} as LIGGGHTS edinburgh/stiffness (engine.io.liggghts)",
        f"# K1 = {law.k1!r} {unit}, K2 = {law.k2!r} {unit}, n = {n:g}, chi = {chi:g}, "
        f"f0 = {law.f0!r} N, kadh = 0",
    ]
    if radius is not None:
        lines.append(
            f"# for particles of radius R = {radius!r} m: the law is calibrated (or scaled) for "
            "this size; at another radius scale it first (demscale export --radius)"
        )
    if note:
        lines += [f"# {line}" for line in note.splitlines()]
    for d in differences(law):
        lines.append(f"# differs: {d}")
    meaning = _meanings(law, n, chi)
    for k, name in enumerate(PROPERTIES, start=1):
        how = "scalar" if name in _SCALAR else f"peratomtypepair {atom_type}"
        lines.append(f"# {name}: {meaning[name]}")
        lines.append(f"fix dsl{k} all property/global {name} {how} {values[name]!r}")
    lines += [
        "pair_style gran model edinburgh/stiffness tangential history rolling_friction cdt",
        "pair_coeff * *",
    ]
    return "\n".join(lines) + "\n"


_FIX = re.compile(
    r"^\s*fix\s+\S+\s+\S+\s+property/global\s+(?P<name>\w+)\s+"
    r"(?:scalar|peratomtype|peratomtypepair\s+\d+)\s+(?P<value>\S+)\s*$"
)


def from_liggghts(text: str, bilinear: bool = False):
    """The law of a LIGGGHTS ``edinburgh/stiffness`` fragment (as :func:`to_liggghts` writes
    it, or a deck with one atom type): an :class:`engine.EEPA` with LIGGGHTS' conventions
    where it has them (Coulomb cap ``"normal"``; ``kt_ratio`` 1, which is LIGGGHTS' tangential
    stiffness K1 exactly for n = 1; for n != 1 LIGGGHTS keeps K1 where EEPA follows the
    loading tangent). With ``bilinear`` and n = chi = 1, an :class:`engine.BilinearAdhesive`
    instead (the seed's law, whose cap is the adhesion-aware one). Raises
    :class:`engine.ParameterError` naming a missing property, a non-zero adhesive branch, or
    another pair model."""
    found: dict[str, float] = {}
    style = None
    for raw in text.splitlines():
        line = raw.split("#", 1)[0]
        m = _FIX.match(line)
        if m and m["name"] in PROPERTIES:
            try:
                found[m["name"]] = float(m["value"])
            except ValueError:
                raise ParameterError(f"liggghts.{m['name']}", m["value"], "a number") from None
        elif line.strip().startswith("pair_style"):
            style = line.split()
    if style is not None and "edinburgh/stiffness" not in style:
        raise ParameterError(
            "liggghts.pair_style", " ".join(style[1:]), "gran model edinburgh/stiffness"
        )
    need = [p for p in PROPERTIES[:8] if p not in found]
    if need:
        raise ParameterError("liggghts", ", ".join(need), "set by fix property/global")
    if found.get("surfaceEnergy", 0.0) != 0.0 or found.get("coefficientAdhesionStiffness", 0.0):
        raise ParameterError(
            "liggghts.surfaceEnergy",
            found.get("surfaceEnergy"),
            "0 (an adhesive branch has no checked mapping)",
        )
    k1 = found["LoadingStiffness"]
    common = {
        "k1": k1,
        "k2": k1 * found["UnloadingStiffness"],
        "f0": found["pullOffForce"],
        "kadh": 0.0,
        "kt_ratio": 1.0,
        "mu_s": found["coefficientFriction"],
        "mu_r": found["coefficientRollingFriction"],
        "restitution": found["coefficientRestitution"],
    }
    n, chi = found["overlapExponent"], found["adhesionExponent"]
    if bilinear and n == 1.0 and chi == 1.0:
        return BilinearAdhesive(**common)
    return EEPA(**common, n=n, chi=chi, friction_cap="normal")


def law_table(law, fmt: str = "json", radius: float | None = None):
    """The parameters of ``law`` with their units and meaning: a list of {name, value, unit,
    doc} (``fmt`` ``"json"``) or CSV text with a header (``"csv"``); ``radius`` [m], where
    known, as a row ``reference_radius``: the particle radius the law is for."""
    rows = [{"name": "type", "value": type(law).__name__, "unit": "", "doc": "contact law"}]
    rows += [
        {"name": i.name, "value": getattr(law, i.name), "unit": i.unit, "doc": i.doc}
        for i in describe(type(law))
    ]
    if radius is not None:
        rows.append(
            {
                "name": "reference_radius",
                "value": radius,
                "unit": "m",
                "doc": "particle radius the law is calibrated (or scaled) for",
            }
        )
    if fmt == "json":
        return rows
    if fmt != "csv":
        raise ParameterError("fmt", fmt, "'json' or 'csv'")
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=["name", "value", "unit", "doc"], lineterminator="\n")
    w.writeheader()
    w.writerows(rows)
    return buf.getvalue()


__all__ = [
    "PROPERTIES",
    "differences",
    "from_liggghts",
    "law_table",
    "matched_restitution",
    "to_liggghts",
]
