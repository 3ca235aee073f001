"""Declared parameters: one source of truth for names, units, bounds and defaults.

Every field of an engine parameter record (contact laws, :class:`engine.UniaxialTest`,
:class:`engine.StudySpec`, :class:`engine.ScalingRule`) is declared with :func:`param`: its
unit, its bounds and a one-line description travel in the dataclass field's metadata.
:func:`check_fields` validates a record against them (raising :class:`ParameterError` that
names the field and the limit), and :func:`describe` lists them for other layers (the job
service builds its request schema from it), so the engine and the API cannot drift apart.
Checks that relate two fields (``k2 >= k1``) stay in the record's ``__post_init__``. A
record's JSON form is derived from the same declarations (:func:`to_dict`, :func:`from_dict`,
the :class:`Record` mixin), so that no record writes its own.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import typing
from collections.abc import Callable
from dataclasses import MISSING, dataclass, field
from typing import Any

from .errors import ParameterError

_KEY = "demscale"


@dataclass(frozen=True)
class ParamInfo:
    """What :func:`param` declares about one field.

    Attributes: ``name``; ``unit`` (SI, ``"1"`` for dimensionless, ``""`` for none);
    ``doc``; the bounds ``gt``/``ge``/``lt``/``le`` (None: unbounded); ``kind`` (``"float"``,
    ``"int"``, ``"bool"``, ``"str"``, ``"record"``, ``"list"`` or ``"dict"``); ``choices`` (allowed
    values of a string); ``nullable`` (None is allowed); ``default``; ``required`` (no default);
    ``max_items`` (longest list); ``types`` (a record field that takes one of several record
    classes, e.g. a contact law: a callable giving them, and the JSON form carries a
    ``"type"`` tag); ``parse`` (a callable reading the field's JSON value where the generic
    reading does not, e.g. a preset with overrides, a rule given by name); ``omit_default``
    (the JSON form leaves the field out while it holds its default: a field added to a
    record whose JSON forms are stored and compared, so that a record made before it, or
    without it, keeps its JSON form; the value is compared with ``==``, for defaults such
    as None).
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
    types: Callable[[], tuple[type, ...]] | None = None
    parse: Callable[[Any], Any] | None = None
    omit_default: bool = False

    def limit_text(self) -> str:
        """The allowed range in words, e.g. ``"in (0, 0.5)"`` or ``"> 0 N/m"``."""
        if self.choices is not None:
            return "one of " + ", ".join(repr(c) for c in self.choices)
        if self.kind == "bool":
            return "true or false"
        if self.kind not in ("float", "int"):  # text, a record, a list, a mapping
            what = {"str": "text", "record": "an object of its fields", "list": "a list"}
            text = what.get(self.kind, "an object")
            return text + " or null" if self.nullable else text
        unit = "" if self.unit in ("", "1") else f" {self.unit}"
        lo = _bound(self.gt, self.ge, "({:g}", "[{:g}")
        hi = _bound(self.lt, self.le, "{:g})", "{:g}]")
        what = "an integer" if self.kind == "int" else "a finite number"
        if lo and hi:
            text = f"in {lo}, {hi}{unit}"
        elif lo:
            text = _bound(self.gt, self.ge, "> {:g}", ">= {:g}") + unit
        elif hi:
            text = _bound(self.lt, self.le, "< {:g}", "<= {:g}") + unit
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


def _bound(strict, inclusive, strict_text: str, inclusive_text: str) -> str | None:
    """One end of a range in words: the strict bound in ``strict_text``, else the inclusive
    one in ``inclusive_text`` (format strings of the number), else None."""
    if strict is not None:
        return strict_text.format(strict)
    if inclusive is not None:
        return inclusive_text.format(inclusive)
    return None


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
    types: Callable[[], tuple[type, ...]] | None = None,
    parse: Callable[[Any], Any] | None = None,
    omit_default: bool = False,
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
            types=types,
            parse=parse,
            omit_default=omit_default,
        )
    }
    if default_factory is not MISSING:
        return field(default_factory=default_factory, metadata=md)
    return field(default=default, metadata=md)


def describe(cls) -> list[ParamInfo]:
    """The declared parameters of a record class, in field order."""
    return list(_describe(cls))


@functools.cache
def _describe(cls) -> tuple[ParamInfo, ...]:
    # once per class: every record checks its fields on construction (defaults are frozen
    # records or immutable values, so the one ParamInfo per field may be shared)
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
    return tuple(out)


def check_fields(obj, owner: str | None = None) -> None:
    """Validate (and normalise: numbers become ``float`` or ``int``) every declared field of
    the frozen dataclass ``obj``; raise :class:`ParameterError` naming ``owner.field``."""
    owner = owner or type(obj).__name__
    for info in _describe(type(obj)):
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


# ------------------------------------------------------------------ JSON form
def to_dict(obj) -> dict:
    """The JSON form of a declared record, derived from its fields: every declared field in
    order (but one declared ``omit_default`` while it holds its default); a nested record as
    an object (one whose field declares ``types``, a tagged union such as a contact law, with
    its ``"type"`` first); tuples as lists. Inverse: :func:`from_dict`."""
    return {
        info.name: _to_json(getattr(obj, info.name), info)
        for info in _describe(type(obj))
        if not (info.omit_default and getattr(obj, info.name) == info.default)
    }


def _to_json(value: Any, info: ParamInfo | None = None) -> Any:
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        out = to_dict(value)
        if info is not None and info.types is not None:
            return {"type": type(value).__name__, **out}
        return out
    if isinstance(value, (list, tuple)):
        return [_to_json(v) for v in value]
    if isinstance(value, dict):
        return {k: _to_json(v) for k, v in value.items()}
    return value


def from_dict(cls, data: Any, owner: str | None = None):
    """The record ``cls`` built from its JSON form (:func:`to_dict`), derived from its
    declared fields: unknown keys, a nested record of an unknown ``type``, a list or an object
    where none belongs are refused with :class:`ParameterError` naming the field; a field
    with a ``parse`` hook (a preset, a rule given by name) is read by it; the record's own
    checks then run as on any construction."""
    owner = owner or cls.__name__
    if not isinstance(data, dict):
        raise ParameterError(owner, data, "an object of its fields")
    infos = {info.name: info for info in _describe(cls)}
    unknown = set(data) - set(infos)
    if unknown:
        raise ParameterError(owner, sorted(unknown), f"fields among {sorted(infos)}")
    required = [
        f.name
        for f in dataclasses.fields(cls)
        if f.init
        and f.default is dataclasses.MISSING
        and f.default_factory is dataclasses.MISSING
        and f.name not in data
    ]
    if required:
        raise ParameterError(f"{owner}.{required[0]}", None, "given (the field is required)")
    hints = _hints(cls)
    kwargs = {name: _from_json(raw, infos[name], hints[name], cls) for name, raw in data.items()}
    return cls(**kwargs)


def _record_class(hint: Any) -> type | None:
    """The one record class a type hint names (``X`` or ``X | None``), else None."""
    args = typing.get_args(hint) if typing.get_args(hint) else (hint,)
    records = [a for a in args if dataclasses.is_dataclass(a)]
    return records[0] if len(records) == 1 else None


def _from_json(raw: Any, info: ParamInfo, hint: Any, cls: type) -> Any:
    path = f"{cls.__name__}.{info.name}"
    if info.parse is not None:
        return info.parse(raw)
    if raw is None:
        return None
    if info.kind == "record":
        if not isinstance(raw, dict):
            return raw  # a record already (check_fields or __post_init__ judges it)
        if info.types is not None:
            classes = {c.__name__: c for c in info.types()}
            raw = dict(raw)
            # no tag: the class of the field's default
            kind = raw.pop("type", type(info.default).__name__)
            if kind not in classes:
                raise ParameterError(f"{path}.type", kind, "one of " + ", ".join(classes))
            return from_dict(classes[kind], raw)
        record = _record_class(hint)
        return raw if record is None else from_dict(record, raw)
    if info.kind == "list":
        if not isinstance(raw, (list, tuple)):
            raise ParameterError(path, raw, "a list")
        item = typing.get_args(hint)[0] if typing.get_args(hint) else None
        record = _record_class(item) if item is not None else None
        return tuple(
            from_dict(record, v) if record is not None and isinstance(v, dict) else v for v in raw
        )
    if info.kind == "dict" and not isinstance(raw, dict):
        raise ParameterError(path, raw, "an object")
    return raw


@functools.cache
def _hints(cls) -> dict[str, Any]:
    return typing.get_type_hints(cls)


class Record:
    """Mixin of the declared records: their JSON form, derived from the declared fields."""

    def to_dict(self) -> dict:
        """JSON-friendly form (:func:`engine.core.records.to_dict`; inverse :meth:`from_dict`)."""
        return to_dict(self)

    @classmethod
    def from_dict(cls, data: dict):
        """The record from its JSON form (:func:`engine.core.records.from_dict`): unknown keys
        and values of the wrong shape raise :class:`engine.ParameterError` naming the field."""
        return from_dict(cls, data)
