"""A powder's laboratory measurements as calibration targets (docs/CALIBRATION.md).

A uniaxial powder tester measures what :func:`engine.run_uniaxial` simulates: porosity
against vertical stress on confined loading (and unloading), the loading and unloading
stiffness, the lateral stress ratio K0 where the tester has a lateral sensor (a lambda
tester), and the unconfined strength after consolidation at one or several consolidation
stresses (the tester's flow function). :class:`LabTargets` holds them with their
uncertainties (one standard deviation: the measured repeatability) and the tester they come
from, as a declared record (JSON form, units, bounds: ``engine.core.records``), so that a
target the test cannot reproduce is refused with the field and the reason:

- unconfined strength points (``strength``) from a shear tester (``tester``
  ``"ring_shear"``, ``"jenike"`` or ``"ft4"``): the strength after K0 consolidation in a
  uniaxial tester is systematically lower than a shear tester's at the same stress, so the
  uniaxial test must not be fitted to it (a shear tester's yield loci go in ``shear``, the
  shear test's targets, below);
- K0 without a lateral sensor (only a ``"lambda"`` tester measures it);
- a porosity outside what this engine's sphere packings were measured to reach in
  confined compression (:data:`POROSITY_RANGE`, ``python -m benchmarks.porosity_range``):
  a calibration would distort every other parameter trying;
- a negative uncertainty, a non-positive stress (the declared bounds);
- a value without its uncertainty (``sd`` of every point, ``<name>_sd`` of every scalar
  target given): it would be taken as exact.

A shear tester's flow function (ring shear, ASTM D6773; Jenike, ASTM D6128; the FT4 shear
cell) is what :func:`engine.run_shear` simulates: ``shear`` holds its yield loci
(:class:`ShearLocus`: the pre-shear normal stress sigma_pre, its steady shear stress tau_pre
if given, the points of incipient failure (sigma_n, tau) and the bulk density, each value
with its 1-sd uncertainty), and ``shear_tester`` names the tester (null: ``tester``, where
that is a shear tester). A data set may hold uniaxial and shear data together: ``tester``
names the tester of the uniaxial data (compression, stiffnesses, K0, strength), whose
refusals above stay; ``shear_tester`` the shear data's. Refused, naming the field
(``LabTargets.shear[0].points[2].sigma_n``):

- a point at or above its locus's sigma_pre: a point of incipient failure is sheared at a
  normal stress below the pre-shear's (at or above it the sample consolidates further
  instead of failing: the point is not on that locus);
- a locus with fewer than two points, or with two at the same sigma_n: a yield locus is a
  line fitted through the points, and one point (or one normal stress) gives no line;
  repeats at one sigma_n are given as their mean and sd;
- a locus whose fitted line falls with sigma_n (a yield locus rises with the normal
  stress: its slope is tan(phi), phi > 0);
- tau <= 0, sigma_n or sigma_pre <= 0, a negative sd (the declared bounds); a value
  without its sd; two loci at the same sigma_pre (one locus per consolidation: give the
  repeats' points as their means).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..core.errors import ParameterError
from ..core.records import Record, check_fields, from_dict, param

#: Testers whose data a target may come from. ``uniaxial``: confined compression and
#: unconfined strength (no lateral sensor); ``lambda``: the same with a lateral stress
#: sensor (K0); ``ring_shear``, ``jenike`` and ``ft4`` (the FT4's rotational shear cell):
#: shear testers, whose flow function the uniaxial test does not reproduce (their yield
#: loci are the shear test's targets, ``LabTargets.shear``).
TESTERS = ("uniaxial", "lambda", "ring_shear", "jenike", "ft4")
SHEAR_TESTERS = ("ring_shear", "jenike", "ft4")
#: Most points of incipient failure per yield locus: the shear test's most shear points
#: (engine.shear.spec.MAX_POINTS).
MAX_LOCUS_POINTS = 8
#: Most yield loci (pre-shear stresses) a data set holds: each is a shear test per
#: calibration run.
MAX_LOCI = 6

#: Porosities this engine's sphere packings reach in confined compression [-], measured, not
#: assumed (``python -m benchmarks.porosity_range``; stored in
#: benchmarks/results/porosity_range/summary.json; docs/CALIBRATION.md "The porosity
#: range"): 40 runs (4 failed), Bond number 0-1e4 (and kadh = K2), mu_s 0.1-1 with mu_r
#: 0-0.3, size spread p = 0 and 0.49, at 0.5-20 kPa on loading and unloading, whole sample
#: and interior:
#: lowest 0.330 (no adhesion, low friction, p = 0.49, interior at 20 kPa), highest 0.585
#: (Bo = 1e4, high friction, p = 0.49, whole sample at 0.5 kPa), each widened by two pooled
#: seed sd (0.0055) and rounded outward to 0.01. tests/engine/test_porosity_range.py holds
#: it equal to the stored measurement.
POROSITY_RANGE = (0.31, 0.60)


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


@dataclass(frozen=True)
class LocusPoint(Record):
    """One point of incipient failure of a shear tester's yield locus: the shear stress at
    failure tau under the normal stress sigma_n, each with its 1-sd uncertainty."""

    sigma_n: float = param(unit="Pa", gt=0, doc="normal stress of the shear to failure sigma_n")
    sigma_n_sd: float = param(unit="Pa", ge=0, doc="its uncertainty (1 sd; required)")
    tau: float = param(unit="Pa", gt=0, doc="shear stress at failure tau (> 0)")
    tau_sd: float = param(unit="Pa", ge=0, doc="its uncertainty (1 sd; required)")

    def __post_init__(self) -> None:
        check_fields(self)


#: Each optional value of a locus and the field of its uncertainty, which must come with it.
LOCUS_UNCERTAINTY_OF = {"tau_pre": "tau_pre_sd", "bulk_density": "bulk_density_sd"}


def _uncertainty(unit: str):
    """The field ``<name>_sd`` of an optional scalar target ``<name>``: its uncertainty,
    one standard deviation in the value's ``unit``, >= 0; a value given without it is
    refused (module docstring)."""
    return param(
        None, unit=unit, ge=0, nullable=True, doc="its uncertainty (1 sd; required with it)"
    )


@dataclass(frozen=True)
class ShearLocus(Record):
    """One yield locus of a shear tester (ASTM D6773, D6128): the sample pre-sheared to
    steady flow at ``sigma_pre``, then sheared to failure at each point's sigma_n <
    sigma_pre; the bulk density of the pre-sheared sample (module docstring for what is
    refused and why)."""

    sigma_pre: float = param(unit="Pa", gt=0, doc="normal stress of the pre-shear sigma_pre")
    points: tuple[LocusPoint, ...] = param(
        unit="",
        kind="list",
        max_items=MAX_LOCUS_POINTS,
        doc="points of incipient failure (at least 2, each sigma_n < sigma_pre, all different)",
    )
    tau_pre: float | None = param(
        None, unit="Pa", gt=0, nullable=True, doc="shear stress of the pre-shear's steady flow"
    )
    tau_pre_sd: float | None = _uncertainty("Pa")
    bulk_density: float | None = param(
        None, unit="kg/m^3", gt=0, nullable=True, doc="bulk density of the pre-sheared sample"
    )
    bulk_density_sd: float | None = _uncertainty("kg/m^3")

    def __post_init__(self) -> None:
        o = "ShearLocus"
        check_fields(self)
        if not isinstance(self.points, (list, tuple)):
            raise ParameterError(f"{o}.points", self.points, "a list of points")
        points = [_point(LocusPoint, p, f"{o}.points[{k}]") for k, p in enumerate(self.points)]
        object.__setattr__(self, "points", tuple(points))
        if not 2 <= len(points) <= MAX_LOCUS_POINTS:
            raise ParameterError(
                f"{o}.points",
                len(points),
                f"2 to {MAX_LOCUS_POINTS} points",
                "a yield locus is a line fitted through its points of incipient failure: one "
                "point gives no line",
            )
        for k, p in enumerate(points):
            if not p.sigma_n < self.sigma_pre:
                raise ParameterError(
                    f"{o}.points[{k}].sigma_n",
                    p.sigma_n,
                    f"below sigma_pre = {self.sigma_pre:g} Pa",
                    "a point of incipient failure is sheared at a normal stress below the "
                    "pre-shear's; at or above it the sample consolidates further instead of "
                    "failing, and the point is not on this locus",
                )
        seen: dict[float, int] = {}
        for k, p in enumerate(points):
            if p.sigma_n in seen:
                raise ParameterError(
                    f"{o}.points[{k}].sigma_n",
                    p.sigma_n,
                    f"a normal stress no other point of the locus has (points[{seen[p.sigma_n]}] "
                    "has it)",
                    "each point is one shear to failure of the simulated locus; give repeats "
                    "at one sigma_n as their mean and sd",
                )
            seen[p.sigma_n] = k
        if not self.slope() > 0:
            raise ParameterError(
                f"{o}.points",
                self.slope(),
                "points whose fitted line tau = c + sigma_n tan(phi) has tan(phi) > 0",
                "a yield locus rises with the normal stress: its slope is tan(phi), phi the "
                "angle of internal friction > 0",
            )
        for value, sd in LOCUS_UNCERTAINTY_OF.items():
            if getattr(self, value) is not None and getattr(self, sd) is None:
                raise ParameterError(
                    f"{o}.{sd}",
                    None,
                    f"the uncertainty (1 sd) of {value} = {getattr(self, value):g}, >= 0",
                    "a measured value comes with its repeatability; without one the "
                    "calibration would take it as exact",
                )

    @classmethod
    def from_dict(cls, data: dict) -> ShearLocus:
        """The locus from its JSON form; an error in a point is named by its place
        (``ShearLocus.points[2].tau``)."""
        if isinstance(data, dict) and isinstance(data.get("points"), (list, tuple)):
            data = {
                **data,
                "points": [
                    _point(LocusPoint, v, f"ShearLocus.points[{k}]")
                    for k, v in enumerate(data["points"])
                ],
            }
        return from_dict(cls, data)

    def slope(self) -> float:
        """tan(phi) of the least-squares line through the points [-] (the laboratory's
        linearised yield locus)."""
        from ..shear.locus import fit_line

        # in units of sigma_pre (the slope is the same): no overflow or underflow of the sums
        # for stresses of any magnitude the bounds admit; nan where no line fits
        s = self.sigma_pre
        try:
            with np.errstate(all="ignore"):
                m = fit_line([p.sigma_n / s for p in self.points], [p.tau / s for p in self.points])
            m = m[1]
        except (ValueError, ZeroDivisionError):
            return math.nan
        return m if math.isfinite(m) else math.nan

    def tau_sd(self, k: int) -> float:
        """The uncertainty (1 sd) of the shear stress at failure of point ``k`` with that of
        its normal stress carried along the locus [Pa]: sqrt(tau_sd^2 + (tan(phi)
        sigma_n_sd)^2), tan(phi) the laboratory locus's slope (a first-order
        errors-in-variables variance: a normal stress off by d sigma moves the failure
        shear stress by tan(phi) d sigma)."""
        p = self.points[k]
        return math.hypot(p.tau_sd, self.slope() * p.sigma_n_sd)


def _point(cls, raw: dict, where: str):
    """A :class:`CompressionPoint`, :class:`StrengthPoint`, :class:`ShearLocus` or
    :class:`LocusPoint` from its JSON form (or the record itself); its errors named at
    ``where`` (``LabTargets.strength[0]``) and the field."""
    try:
        if isinstance(raw, cls):
            return raw
        if not isinstance(raw, dict):
            raise ParameterError(cls.__name__, raw, f"a {cls.__name__} (an object of its fields)")
        return cls.from_dict(raw)
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
    loading_stiffness_sd: float | None = _uncertainty("Pa")
    unloading_stiffness: float | None = param(
        None, unit="Pa", gt=0, nullable=True, doc="confined unloading stiffness"
    )
    unloading_stiffness_sd: float | None = _uncertainty("Pa")
    k0: float | None = param(
        None, unit="1", gt=0, lt=1.5, nullable=True, doc="lateral stress ratio on loading"
    )
    k0_sd: float | None = _uncertainty("1")
    strength: tuple[StrengthPoint, ...] = param(
        (), unit="", kind="list", max_items=16, doc="unconfined strength (flow function)"
    )
    shear_tester: str | None = param(
        None,
        unit="",
        kind="str",
        choices=SHEAR_TESTERS,
        nullable=True,
        doc="the shear tester of the yield loci (null: tester, where that is a shear tester)",
    )
    shear: tuple[ShearLocus, ...] = param(
        (),
        unit="",
        kind="list",
        max_items=MAX_LOCI,
        doc="a shear tester's yield loci, one per pre-shear stress (the shear test's targets)",
    )

    def __post_init__(self) -> None:
        check_fields(self)
        for name, cls in ITEMS.items():
            items = getattr(self, name)
            if not isinstance(items, (list, tuple)):
                raise ParameterError(f"LabTargets.{name}", items, f"a list of {cls.__name__}")
            items = list(items)
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
                    "spheres do not reach it in confined compression: the range this "
                    "engine's packings were measured to reach at 0.5-20 kPa with adhesion, "
                    "friction and polydispersity from none to strong (python -m "
                    "benchmarks.porosity_range); a calibration would distort the other "
                    "parameters trying (such a powder needs non-spherical particles, "
                    "another law or another fill)",
                )
        if self.strength and self.tester in SHEAR_TESTERS:
            raise ParameterError(
                "LabTargets.strength",
                f"{len(self.strength)} points from a {self.tester} tester",
                "a flow function measured in a uniaxial tester",
                "strength after K0 consolidation in a uniaxial tester is systematically lower "
                "than a shear tester's at the same stress: the uniaxial test cannot be fitted "
                "to a ring-shear, Jenike or FT4 flow function; give its yield loci as shear "
                "(the shear test's targets)",
            )
        if self.k0 is not None and self.tester != "lambda":
            raise ParameterError(
                "LabTargets.k0",
                self.k0,
                "measured by a tester with a lateral stress sensor (tester 'lambda')",
            )
        self._check_shear()
        if not self.names():
            raise ParameterError("LabTargets", "no target", "at least one measurement")

    def _check_shear(self) -> None:
        """The shear data's own rules across loci and with the tester (module docstring)."""
        if len(self.shear) > MAX_LOCI:
            raise ParameterError(
                "LabTargets.shear",
                len(self.shear),
                f"at most {MAX_LOCI} yield loci",
                "each locus is a shear test in every calibration run",
            )
        if self.shear and self.resolved_shear_tester() is None:
            raise ParameterError(
                "LabTargets.shear_tester",
                None,
                f"one of {list(SHEAR_TESTERS)}",
                f"the yield loci come from a shear tester, and tester = {self.tester!r} is "
                "not one: name it",
            )
        if self.shear_tester is not None and not self.shear:
            raise ParameterError(
                "LabTargets.shear_tester",
                self.shear_tester,
                "given with yield loci (shear) only",
                "it names the tester of shear data this set does not hold",
            )
        seen: dict[float, int] = {}
        for i, locus in enumerate(self.shear):
            if locus.sigma_pre in seen:
                raise ParameterError(
                    f"LabTargets.shear[{i}].sigma_pre",
                    locus.sigma_pre,
                    f"a pre-shear stress no other locus has (shear[{seen[locus.sigma_pre]}] "
                    "has it)",
                    "one locus per consolidation: give repeated loci's points as their means "
                    "and sds",
                )
            seen[locus.sigma_pre] = i

    def resolved_shear_tester(self) -> str | None:
        """The tester of the yield loci: ``shear_tester``, else ``tester`` where that is a
        shear tester, else None."""
        if self.shear_tester is not None:
            return self.shear_tester
        return self.tester if self.tester in SHEAR_TESTERS else None

    @classmethod
    def from_dict(cls, data: dict) -> LabTargets:
        """The targets from their JSON form; an error in a point is named by its place
        (``LabTargets.compression[2].sd``), as the request holds it."""
        if isinstance(data, dict):
            data = dict(data)
            for name, item_cls in ITEMS.items():
                items = data.get(name)
                if isinstance(items, (list, tuple)):
                    data[name] = [
                        _point(item_cls, v, f"LabTargets.{name}[{k}]") if isinstance(v, dict) else v
                        for k, v in enumerate(items)
                    ]
        return from_dict(cls, data)

    def names(self) -> list[str]:
        """The targets this record holds (``shear`` last: the shear test's)."""
        out = self.uniaxial_names()
        if self.shear:
            out.append("shear")
        return out

    def uniaxial_names(self) -> list[str]:
        """The targets of the uniaxial test this record holds."""
        out = []
        if self.compression:
            out.append("compression")
        for n in ("loading_stiffness", "unloading_stiffness", "k0"):
            if getattr(self, n) is not None:
                out.append(n)
        if self.strength:
            out.append("strength")
        return out


#: The list fields of :class:`LabTargets` and the record of their items.
ITEMS = {"compression": CompressionPoint, "strength": StrengthPoint, "shear": ShearLocus}


__all__ = [
    "LOCUS_UNCERTAINTY_OF",
    "MAX_LOCI",
    "MAX_LOCUS_POINTS",
    "POROSITY_RANGE",
    "SHEAR_TESTERS",
    "TESTERS",
    "UNCERTAINTY_OF",
    "CompressionPoint",
    "LabTargets",
    "LocusPoint",
    "ShearLocus",
    "StrengthPoint",
]
