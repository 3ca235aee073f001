"""The similarity of the equations of motion under coarse-graining, applied to any declared
record from its fields' units (docs/PHYSICS.md section 5.1).

With lengths x s, times x s and densities x 1, every other unit follows: masses x s^3,
velocities x 1, accelerations (gravity) x 1/s, forces x s^2, stresses x 1, stiffnesses
N/m x s and N/m^n x s^(2-n). A contact law whose parameters scale so (the bilinear law with
K ~ R and f0 ~ R^2, EEPA with K ~ R^(2-n) and kadh ~ R^(2-chi), Hertz with E unchanged)
moves every particle of the scaled scene along the scaled trajectory: x'(t') = s x(t' / s).
A test made by :func:`similar` is therefore the same experiment in other units, and any
constant of the code fixed in seconds, metres or metres per second shows as a difference
between the two runs (tests/engine/test_similarity.py).

The exponent of a field is read from its declared unit (:func:`engine.core.records.param`),
so a new field needs no entry here; a unit this module cannot read is refused, naming the
field, rather than left unscaled.
"""

from __future__ import annotations

import dataclasses
import math
import re

import numpy as np

from .errors import ParameterError
from .records import describe

#: Similarity exponent of each base unit: a quantity in it is multiplied by s to this power.
#: kg: a mass at a fixed density (kg = kg/m^3 m^3); N = kg m / s^2 (3 + 1 - 2); Pa = N/m^2; J = N m.
BASE_EXPONENTS = {
    "m": 1.0,
    "s": 1.0,
    "kg": 3.0,
    "N": 2.0,
    "Pa": 0.0,
    "J": 3.0,
    "W": 2.0,
    "rad": 0.0,
    "1": 0.0,
}
_TOKEN = re.compile(r"^([A-Za-z]+|1)(?:\^(-?[0-9.]+|[A-Za-z_]+))?$")


def unit_exponent(unit: str, record=None, owner: str = "unit") -> float:
    """The similarity exponent of ``unit`` (e.g. ``"N/m"`` -> 1, ``"m/s^2"`` -> -1,
    ``"N/m^n"`` -> 2 - n with ``n`` read from ``record``). Products with ``*``, one ``/``
    (everything after it divides). Raises :class:`ParameterError` naming ``owner`` for a
    unit it cannot read."""
    if unit in ("", "1"):
        return 0.0
    num, _, den = unit.partition("/")
    total = 0.0
    for part, sign in ((num, 1.0), (den, -1.0)):
        if not part:
            continue
        for tok in part.split("*"):
            m = _TOKEN.match(tok.strip())
            if m is None or m.group(1) not in BASE_EXPONENTS:
                raise ParameterError(owner, unit, "a unit of " + ", ".join(BASE_EXPONENTS))
            power = m.group(2)
            if power is None:
                p = 1.0
            else:
                try:
                    p = float(power)
                except ValueError:
                    if record is None or not hasattr(record, power):
                        raise ParameterError(
                            owner, unit, f"an exponent the record declares ({power!r} is not)"
                        ) from None
                    p = float(getattr(record, power))
            total += sign * p * BASE_EXPONENTS[m.group(1)]
    return total


def similar(record, s: float, owner: str | None = None):
    """``record`` (a declared record: a test, a contact law, a wall material) in units s
    times larger: every float field times s to its unit's exponent, lists of lengths
    elementwise, nested records likewise, integers, strings, booleans and None as they
    are. The result is built through the record's constructor, so it is validated as any
    record is. ``s`` > 0 and finite [-].

    For the laws whose rule is the similarity (K ~ R^(2-n), f0 ~ R^2) this is that rule; a
    record with a field in a unit not listed in :data:`BASE_EXPONENTS` is refused."""
    name = owner or type(record).__name__
    if not (isinstance(s, (int, float)) and math.isfinite(s) and s > 0):
        raise ParameterError(f"{name}.similar.s", s, "a finite factor > 0")
    changes = {}
    for info in describe(type(record)):
        value = getattr(record, info.name)
        where = f"{name}.{info.name}"
        if value is None or isinstance(value, (bool, str)):
            continue
        if info.kind == "record":
            changes[info.name] = similar(value, s, where)
            continue
        if info.kind in ("int", "str", "bool", "dict"):
            continue
        try:
            factor = s ** unit_exponent(info.unit, record, where)
            scaled = (
                tuple(float(v) * factor for v in value)
                if info.kind == "list"
                else float(value) * factor
            )
        except OverflowError:
            factor, scaled = math.inf, math.inf
        if factor == 1.0:
            continue
        if not all(math.isfinite(v) for v in np.atleast_1d(scaled)):
            raise ParameterError(where, value, f"a value that stays finite at the factor {s:g}")
        changes[info.name] = scaled
    return dataclasses.replace(record, **changes) if changes else record
