"""A powder's laboratory measurements as calibration targets (docs/CALIBRATION.md).

A uniaxial powder tester measures what :func:`engine.run_uniaxial` simulates: porosity
against vertical stress on confined loading (and unloading), the loading and unloading
stiffness, the lateral stress ratio K0 where the tester has a lateral sensor (a lambda
tester), and the unconfined strength after consolidation at one or several consolidation
stresses (the tester's flow function). :class:`LabTargets` holds them with their
uncertainties (one standard deviation: the measured repeatability) and the tester they come
from, as a declared record (JSON form, units, bounds: ``engine.core.records``), so that a
target the test cannot reproduce is refused with the field and the reason:

- a flow function from a shear tester (``tester`` ``"ring_shear"`` or ``"jenike"``): the
  strength after K0 consolidation in a uniaxial tester is systematically lower than a shear
  tester's at the same stress, so this simulation must not be fitted to it;
- K0 without a lateral sensor (only a ``"lambda"`` tester measures it);
- a porosity that spheres cannot reach (:data:`POROSITY_RANGE`): a calibration would
  distort every other parameter trying;
- a negative uncertainty, a non-positive stress (the declared bounds);
- a value without its uncertainty (``sd`` of every point, ``<name>_sd`` of every scalar
  target given): it would be taken as exact.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..core.errors import ParameterError
from ..core.records import Record, check_fields, from_dict, param

#: Testers whose data a target may come from. ``uniaxial``: confined compression and
#: unconfined strength (no lateral sensor); ``lambda``: the same with a lateral stress
#: sensor (K0); ``ring_shear`` and ``jenike``: shear testers, whose flow function this
#: simulation does not reproduce.
TESTERS = ("uniaxial", "lambda", "ring_shear", "jenike")
SHEAR_TESTERS = ("ring_shear", "jenike")

#: Porosities spheres of this engine's size spread reach in confined compression [-]: from
#: about 0.34 (a polydisperse bed near random close packing) to about 0.50 (a loose cohesive
#: bed at low stress); monodisperse beds stay in about 0.36-0.46.
POROSITY_RANGE = (0.34, 0.50)


@dataclass(frozen=True)
class CompressionPoint(Record):
    """One point of the confined compression curve: porosity at a vertical stress."""

    stress: float = param(unit="Pa", gt=0, doc="vertical stress")
    porosity: float = param(unit="1", gt=0, lt=1, doc="porosity measured at that stress")
    sd: float = param(unit="1", ge=0, lt=1, doc="its uncertainty (1 sd; required)")
    branch: str = param(
        "loading",
        unit="",
        kind="str",
        choices=("loading", "unloading"),
        doc="branch of the curve the point is on",
    )

    def __post_init__(self) -> None:
        check_fields(self)


@dataclass(frozen=True)
class StrengthPoint(Record):
    """One point of the flow function: unconfined strength after consolidation."""

    consolidation_stress: float = param(unit="Pa", gt=0, doc="consolidation stress sigma_1")
    strength: float = param(unit="Pa", ge=0, doc="unconfined strength sigma_c")
    sd: float = param(unit="Pa", ge=0, doc="its uncertainty (1 sd; required)")

    def __post_init__(self) -> None:
        check_fields(self)


def _point(cls, raw: dict, where: str):
    """A :class:`CompressionPoint` or :class:`StrengthPoint` from its JSON form; its errors
    named at ``where`` (``LabTargets.strength[0]``) and the field."""
    try:
        return from_dict(cls, raw)
    except ParameterError as e:
        part = e.field.split(".", 1)[1] if "." in e.field else ""
        raise ParameterError(
            where + (f".{part}" if part else ""), e.value, e.limit, e.why
        ) from None


#: Each scalar target and the field of its uncertainty, which must come with it: a value
#: without one would be taken as exact (the calibration weighs each target by it).
UNCERTAINTY_OF = {
    "loading_stiffness": "loading_stiffness_sd",
    "unloading_stiffness": "unloading_stiffness_sd",
    "k0": "k0_sd",
}


@dataclass(frozen=True)
class LabTargets(Record):
    """A powder's laboratory data, with uncertainties (1 sd) and the tester named (module
    docstring). Every field but ``tester`` is optional; at least one target is needed."""

    tester: str = param(unit="", kind="str", choices=TESTERS, doc="the tester the data come from")
    material: str = param("", unit="", kind="str", doc="what was measured (free text)")
    compression: tuple[CompressionPoint, ...] = param(
        (), unit="", kind="list", max_items=64, doc="porosity against vertical stress"
    )
    loading_stiffness: float | None = param(
        None, unit="Pa", gt=0, nullable=True, doc="confined loading stiffness"
    )
    loading_stiffness_sd: float | None = param(
        None, unit="Pa", ge=0, nullable=True, doc="its uncertainty (1 sd; required with it)"
    )
    unloading_stiffness: float | None = param(
        None, unit="Pa", gt=0, nullable=True, doc="confined unloading stiffness"
    )
    unloading_stiffness_sd: float | None = param(
        None, unit="Pa", ge=0, nullable=True, doc="its uncertainty (1 sd; required with it)"
    )
    k0: float | None = param(
        None, unit="1", gt=0, lt=1.5, nullable=True, doc="lateral stress ratio on loading"
    )
    k0_sd: float | None = param(
        None, unit="1", ge=0, nullable=True, doc="its uncertainty (1 sd; required with it)"
    )
    strength: tuple[StrengthPoint, ...] = param(
        (), unit="", kind="list", max_items=16, doc="unconfined strength (flow function)"
    )

    def __post_init__(self) -> None:
        check_fields(self)
        for name, cls in (("compression", CompressionPoint), ("strength", StrengthPoint)):
            items = list(getattr(self, name))
            for k, item in enumerate(items):
                if isinstance(item, dict):  # its JSON form; an error named by its place
                    items[k] = item = _point(cls, item, f"LabTargets.{name}[{k}]")
                if not isinstance(item, cls):
                    raise ParameterError(f"LabTargets.{name}[{k}]", item, f"a {cls.__name__}")
            object.__setattr__(self, name, tuple(items))
        for value, sd in UNCERTAINTY_OF.items():
            if getattr(self, value) is not None and getattr(self, sd) is None:
                raise ParameterError(
                    f"LabTargets.{sd}",
                    None,
                    f"the uncertainty (1 sd) of {value} = {getattr(self, value):g}, >= 0",
                    "a measured value comes with its repeatability; without one the "
                    "calibration would take it as exact",
                )
        lo, hi = POROSITY_RANGE
        for k, p in enumerate(self.compression):
            if not lo <= p.porosity <= hi:
                raise ParameterError(
                    f"LabTargets.compression[{k}].porosity",
                    p.porosity,
                    f"in [{lo:g}, {hi:g}]",
                    "spheres do not reach it in confined compression; a calibration would "
                    "distort the other parameters trying (a powder this loose needs "
                    "non-spherical particles or another law)",
                )
        if self.strength and self.tester in SHEAR_TESTERS:
            raise ParameterError(
                "LabTargets.strength",
                f"{len(self.strength)} points from a {self.tester} tester",
                "a flow function measured in a uniaxial tester",
                "strength after K0 consolidation in a uniaxial tester is systematically lower "
                "than a shear tester's at the same stress: this simulation cannot be fitted "
                "to a ring-shear or Jenike flow function",
            )
        if self.k0 is not None and self.tester != "lambda":
            raise ParameterError(
                "LabTargets.k0",
                self.k0,
                "measured by a tester with a lateral stress sensor (tester 'lambda')",
            )
        if not self.names():
            raise ParameterError("LabTargets", "no target", "at least one measurement")

    @classmethod
    def from_dict(cls, data: dict) -> LabTargets:
        """The targets from their JSON form; an error in a point is named by its place
        (``LabTargets.compression[2].sd``), as the request holds it."""
        if isinstance(data, dict):
            data = dict(data)
            for name, item_cls in (("compression", CompressionPoint), ("strength", StrengthPoint)):
                items = data.get(name)
                if isinstance(items, (list, tuple)):
                    data[name] = [
                        _point(item_cls, v, f"LabTargets.{name}[{k}]") if isinstance(v, dict) else v
                        for k, v in enumerate(items)
                    ]
        return from_dict(cls, data)

    def names(self) -> list[str]:
        """The targets this record holds."""
        out = []
        if self.compression:
            out.append("compression")
        for n in ("loading_stiffness", "unloading_stiffness", "k0"):
            if getattr(self, n) is not None:
                out.append(n)
        if self.strength:
            out.append("strength")
        return out


__all__ = [
    "POROSITY_RANGE",
    "SHEAR_TESTERS",
    "TESTERS",
    "UNCERTAINTY_OF",
    "CompressionPoint",
    "LabTargets",
    "StrengthPoint",
]
