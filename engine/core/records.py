"""Declared parameters: one source of truth for names, units, bounds and defaults.

Every field of an engine parameter record (contact laws, :class:`engine.UniaxialTest`,
:class:`engine.StudySpec`, :class:`engine.ScalingRule`) is declared with :func:`param`: its
unit, its bounds and a one-line description travel in the dataclass field's metadata.
:func:`check_fields` validates a record against them (raising :class:`ParameterError` that
names the field and the limit), and :func:`describe` lists them for other layers (the job
service builds its request schema from it), so the engine and the API cannot drift apart.
Checks that relate two fields (``k2 >= k1``) stay in the record's ``__post_init__``.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import MISSING, dataclass, field
from typing import Any

from .errors import ParameterError

_KEY = "demscale"


@dataclass(frozen=True)
class ParamInfo:
    """What :func:`param` declares about one field.

    Attributes: ``name``; ``unit`` (SI, ``"1"`` for dimensionless, ``""`` for none);
    ``doc``; the bounds ``gt``/``ge``/``lt``/``le`` (None: unbounded); ``kind`` (``"float"``,
    ``"int"``, ``"bool"``, ``"str"``, ``"record"`` or ``"list"``); ``choices`` (allowed
    values of a string); ``nullable`` (None is allowed); ``default``; ``required`` (no default);
    ``max_items`` (longest list).
    """

    name: str
    unit: str
    doc: str
    kind: str = "float"
    gt: float | None = None
    ge: float | None = None
    lt: float | None = None
    le: float | None = None
    choices: tuple | None = None
    nullable: bool = False
    default: Any = None
    required: bool = False
    max_items: int | None = None

    def limit_text(self) -> str:
        """The allowed range in words, e.g. ``"in (0, 0.5)"`` or ``"> 0 N/m"``."""
        if self.choices is not None:
            return "one of " + ", ".join(repr(c) for c in self.choices)
        if self.kind == "bool":
            return "true or false"
        unit = "" if self.unit in ("", "1") else f" {self.unit}"
        lo = (
            f"({self.gt:g}"
            if self.gt is not None
            else f"[{self.ge:g}"
            if self.ge is not None
            else None
        )
        hi = (
            f"{self.lt:g})"
            if self.lt is not None
            else f"{self.le:g}]"
            if self.le is not None
            else None
        )
        what = "an integer" if self.kind == "int" else "a finite number"
        if lo and hi:
            text = f"in {lo}, {hi}{unit}"
        elif lo:
            text = (f"> {self.gt:g}" if self.gt is not None else f">= {self.ge:g}") + unit
        elif hi:
            text = (f"< {self.lt:g}" if self.lt is not None else f"<= {self.le:g}") + unit
        else:
            text = what + unit
        if self.nullable:
            text += " or null"
        return text

    def accepts(self, v: float) -> bool:
        return (
            (self.gt is None or v > self.gt)
            and (self.ge is None or v >= self.ge)
            and (self.lt is None or v < self.lt)
            and (self.le is None or v <= self.le)
        )


def param(
    default: Any = MISSING,
    *,
    unit: str,
    doc: str,
    gt: float | None = None,
    ge: float | None = None,
    lt: float | None = None,
    le: float | None = None,
    kind: str = "float",
    choices: tuple | None = None,
    nullable: bool = False,
    default_factory: Any = MISSING,
    max_items: int | None = None,
) -> Any:
    """A dataclass field carrying its unit, bounds and description (see :class:`ParamInfo`)."""
    md = {
        _KEY: dict(
            unit=unit,
            doc=doc,
            gt=gt,
            ge=ge,
            lt=lt,
            le=le,
            kind=kind,
            choices=choices,
            nullable=nullable,
            max_items=max_items,
        )
    }
    if default_factory is not MISSING:
        return field(default_factory=default_factory, metadata=md)
    return field(default=default, metadata=md)


def describe(cls) -> list[ParamInfo]:
    """The declared parameters of a record class, in field order."""
    out = []
    for f in dataclasses.fields(cls):
        md = f.metadata.get(_KEY)
        if md is None:
            continue
        default, required = f.default, False
        if f.default_factory is not MISSING:
            default = f.default_factory()
        elif default is MISSING:
            default, required = None, True
        out.append(ParamInfo(name=f.name, default=default, required=required, **md))
    return out


def check_fields(obj, owner: str | None = None) -> None:
    """Validate (and normalise: numbers become ``float`` or ``int``) every declared field of
    the frozen dataclass ``obj``; raise :class:`ParameterError` naming ``owner.field``."""
    owner = owner or type(obj).__name__
    for info in describe(type(obj)):
        v = getattr(obj, info.name)
        name = f"{owner}.{info.name}"
        if v is None:
            if info.nullable:
                continue
            raise ParameterError(name, v, info.limit_text())
        if info.kind == "bool":
            if not isinstance(v, bool):
                raise ParameterError(name, v, "true or false")
        elif info.kind == "str":
            if not isinstance(v, str) or (info.choices is not None and v not in info.choices):
                raise ParameterError(name, v, info.limit_text())
        elif info.kind in ("float", "int"):
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                what = "an integer" if info.kind == "int" else "a real number"
                raise ParameterError(name, v, f"{what} {info.limit_text()}")
            if info.kind == "int":
                if isinstance(v, float) and not v.is_integer():
                    raise ParameterError(name, v, info.limit_text())
                v = int(v)
            else:
                v = float(v)
                if not math.isfinite(v):
                    raise ParameterError(name, v, "a finite number")
            if not info.accepts(v):
                raise ParameterError(name, v, info.limit_text())
            object.__setattr__(obj, info.name, v)
