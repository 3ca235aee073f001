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
kadh > 0 (n=chi=1) ``coefficientAdhesionStiffness`` = kadh / K1, ``fixKc on limitForce off``
restitution        ``coefficientRestitution``
mu_s, mu_r         ``coefficientFriction``, ``coefficientRollingFriction``
=================  ===========================================

The law declares this mapping itself (its ``liggghts`` method, an
:class:`engine.contact.export.LiggghtsPair`: for the adhesive laws in
engine/contact/adhesive.py); this module writes and reads the LIGGGHTS text and asks the law
nothing else (:func:`mapping`). A law without a mapping, or one whose mapping is no fragment
on its own (the Hertz-Mindlin law's E and nu are per atom type: it exports in a deck,
:mod:`engine.io.liggghts_deck`), is refused naming the field.

What LIGGGHTS cannot take is said, not hidden: its tangential stiffness is K1 whatever the
law's ``kt_ratio``, its Coulomb cap is mu |F_n| (EEPA's ``friction_cap="normal"``), and for
n != 1 its damping at a given restitution differs from demscale's (constant, from K1, against
demscale's from the tangent stiffness: :func:`matched_restitution`). Those go into the
fragment's comments and :func:`differences`.

**The adhesive branch (kadh > 0).** LIGGGHTS 3.8 (CFDEMproject/LIGGGHTS-PUBLIC, tag 3.8.0,
``src/normal_model_edinburgh_stiffness.h``) has two paths:

- ``fixKc off`` (its default, lines 207-258) has no kadh parameter: at every step it
  computes one per contact from ``surfaceEnergy`` gamma and the contact's geometry
  (``calculate_k_adh``, lines 154-170): a pull-off f_min = 1.5 pi gamma a, a the contact
  radius from the two radii and the centre distance (line 158), capped at K2 dp^n / 2,
  and k_adh = f_min / delta_min^chi, delta_min where the unloading branch reaches -f_min.
  Its branch ends at a JKR-like force of the contact's size; no surfaceEnergy gives
  demscale's constant kadh. Not used.
- ``fixKc on`` (lines 259-290): k_adh = ``coefficientAdhesionStiffness`` x K1 (line 260),
  and the force is f0 + min(K1 d^n, max(K2 (d^n - dmax^n) + K1 dmax^n, -k_adh d^chi))
  (lines 275-285), demscale's f_hys exactly (K2 (d^n - dmax^n) + K1 dmax^n = K2 (d^n -
  dp^n)). On the adhesive branch it sets dmax = (K2 + k_adh) / (K2 - K1) d at every step
  (line 286): for n = chi = 1 the K2 branch then passes through the current point, so
  a contact that unloads monotonically follows demscale's force exactly, and one that
  closes again from the branch reloads along K2 from where it is, its old dmax forgotten
  (demscale's branch is reversible: back along f0 - kadh d to the old K2 branch). For
  n != 1 or chi != 1 the reset uses d, not d^n and d^chi, so the moved K2 branch misses
  the point and the force jumps at every step on the branch: such a law is refused.
  ``limitForce off`` is written with it: LIGGGHTS clips a negative normal force where
  f0 = 0 and "k_adh == 0" (line 296), but that k_adh is the one declared at line 205,
  which the fixKc-on path shadows (line 260) and leaves 0, so with f0 = 0 the clip would
  remove the adhesive branch; demscale clips nothing.

So a law with kadh > 0 and n = chi = 1 is exported on the ``fixKc on`` path
(``liggghts_adhesive_branch`` of the adhesive laws, engine/contact/adhesive.py), its
remaining difference (the plastic reload from the branch) in the fragment's comments;
checked against LIGGGHTS on a head-on impact (the rebound speed the same within 1e-6,
tests/engine/test_calibration.py) and on one packing (benchmarks/liggghts_kadh,
docs/LIGGGHTS_DECK.md "The adhesive branch": the platen-stress curves 2.76 % apart with
kadh, 2.70 % without, within the 5 % criterion; kadh moves that loading curve by only 4-5 %,
and the reload from the branch is not measured there). A law with kadh > 0 and n or chi != 1
is refused with the reason. :func:`from_liggghts` reads such a fragment back into a law
(LIGGGHTS' conventions, or the bilinear law for n = chi = 1), and :func:`law_table` lists a
law's parameters with units (JSON or CSV).
"""

from __future__ import annotations

import csv
import io
import math
import re

from ..contact.adhesive import EDINBURGH_PROPERTIES
from ..contact.bilinear import BilinearAdhesive
from ..contact.eepa import EEPA
from ..contact.registry import LAWS, law_names
from ..core.errors import ParameterError
from ..core.records import describe

#: The ``fix property/global`` names a fragment sets, in order (the adhesive laws' mapping,
#: engine.contact.adhesive).
PROPERTIES = EDINBURGH_PROPERTIES


def mapping(law, field: str = "law", owner: str | None = None):
    """``law``'s LIGGGHTS mapping (:class:`engine.contact.export.LiggghtsPair`, declared by the
    law: its ``liggghts`` method). Raises :class:`engine.ParameterError` at ``field`` for a
    law that declares none (naming those that do), and the law's own refusals at
    ``<owner>.<its field>`` (default owner: the law's name)."""
    declare = getattr(law, "liggghts", None)
    if declare is None:
        able = [c for c in LAWS.values() if hasattr(c, "liggghts")]
        raise ParameterError(
            field,
            type(law).__name__,
            f"{law_names(able)} to export to LIGGGHTS",
            "the law declares no LIGGGHTS mapping (its liggghts method, engine/contact/export.py)",
        )
    return declare(owner)


def differences(law) -> list[str]:
    """What LIGGGHTS does differently from ``law`` (module docstring; the law's mapping
    declares it): empty when the fragment is the same law."""
    return list(mapping(law).differences)


def matched_restitution(restitution: float, n: float, d: float) -> float:
    """LIGGGHTS restitution whose constant damping 2 zeta_L sqrt(m K1) equals demscale's
    2 zeta sqrt(m n K1 d^(n-1)) at the overlap ``d`` [m]: zeta_L = zeta sqrt(n d^(n-1)),
    e = exp(-pi zeta_L / sqrt(1 - zeta_L^2))."""
    from ..contact.limits import damping_ratio

    z = damping_ratio(restitution) * math.sqrt(n * d ** (n - 1.0))
    return math.exp(-math.pi * z / math.sqrt(1.0 - z * z))


def to_liggghts(law, atom_type: int = 1, note: str = "", radius: float | None = None) -> str:
    """The LIGGGHTS 3.8 input fragment of ``law`` (a law whose mapping is a fragment on its
    own: :class:`engine.BilinearAdhesive` or :class:`engine.EEPA`, fine or scaled) for one
    ``atom_type``: ``fix property/global`` lines and the ``pair_style``/``pair_coeff``, SI
    units, each value's meaning and unit in a comment line above it, with what LIGGGHTS does
    differently in its comments; ``radius`` [m], where known, the particle radius the law is
    for (a law is calibrated, or scaled, for one size). What is written is the law's mapping
    (:func:`mapping`); an adhesive branch (kadh > 0) goes on LIGGGHTS' ``fixKc on`` path for
    n = chi = 1. Raises :class:`engine.ParameterError` at ``law`` for a law without a
    fragment, at ``<law>.kadh`` for kadh > 0 with n or chi != 1 (module docstring)."""
    pair = mapping(law)
    if pair.fragment:
        raise ParameterError(
            "law", pair.law, "a law with a LIGGGHTS fragment of its own", pair.fragment
        )
    if atom_type != 1:
        raise ParameterError("atom_type", atom_type, "1 (one particle type per fragment)")
    lines = [
        f"# demscale {pair.law} as LIGGGHTS {pair.model} (engine.io.liggghts)",
        f"# {pair.summary}",
    ]
    if radius is not None:
        lines.append(
            f"# for particles of radius R = {radius!r} m: the law is calibrated (or scaled) for "
            "this size; at another radius scale it first (demscale export --radius)"
        )
    if note:
        lines += [f"# {line}" for line in note.splitlines()]
    for d in pair.differences:
        lines.append(f"# differs: {d}")
    for k, p in enumerate((*pair.coefficients, *pair.properties), start=1):
        how = "scalar" if p.scalar else f"peratomtypepair {atom_type}"
        lines.append(f"# {p.name}: {p.meaning}")
        lines.append(f"fix dsl{k} all property/global {p.name} {how} {p.value!r}")
    lines += [
        f"pair_style gran model {pair.model} tangential history rolling_friction cdt"
        + pair.settings,
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
    :class:`engine.ParameterError` naming a missing property, a ``surfaceEnergy`` branch
    (fixKc off), a ``coefficientAdhesionStiffness`` without ``fixKc on``, or another pair
    model. With ``fixKc on`` kadh = coefficientAdhesionStiffness x K1."""
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
    fix_kc = (
        style is not None and "fixKc" in style and style[style.index("fixKc") + 1 :][:1] == ["on"]
    )
    if not fix_kc and found.get("surfaceEnergy", 0.0) != 0.0:
        raise ParameterError(
            "liggghts.surfaceEnergy",
            found.get("surfaceEnergy"),
            "0 (with fixKc off LIGGGHTS computes the adhesive branch per contact from it, "
            "a JKR-like force of the contact's size: no constant kadh is that branch)",
        )
    ratio = found.get("coefficientAdhesionStiffness", 0.0)
    if ratio and not fix_kc:
        raise ParameterError(
            "liggghts.coefficientAdhesionStiffness",
            ratio,
            "0 without 'fixKc on' in the pair style (LIGGGHTS reads it only with fixKc on)",
        )
    k1 = found["LoadingStiffness"]
    common = {
        "k1": k1,
        "k2": k1 * found["UnloadingStiffness"],
        "f0": found["pullOffForce"],
        "kadh": ratio * k1 if fix_kc else 0.0,
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
    "mapping",
    "matched_restitution",
    "to_liggghts",
]
