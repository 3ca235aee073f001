"""A scaling study's report, typed (docs/PHYSICS.md section 7): what the study's judged
look means for a user, as frozen records that the figures, the command line, the service
and the benchmarks read by attribute.

:class:`StudyReport` holds the verdict of every coarse variant (:class:`Verdict`, one
:class:`MetricVerdict` per verdict metric), the resolution controls' two errors and the
protocol check (verdicts too), per rule the recommendation (:class:`RuleAnswer`: the
coarsest radius judged ``equivalent`` in a fixed sequence, its law and speed-up), the
fitted adhesion exponent (:class:`AdhesionFit`), the resolution curve, the references'
noise floor and scalars (:class:`ReferenceSummary`), the adaptive rounds
(:class:`AdaptiveSummary`) and the lines of advice. It is built once, by
:func:`engine.study.advice.build_report` from the study's final look.

``to_dict()`` gives the JSON a study's summary has always carried under ``"advisor"``,
key for key and in the same order (the service's API and the stores keep serving it);
``from_dict()`` reads it back, also from summaries stored by earlier versions (a key they
lack takes its default). Fields that the JSON carries only for some records (a rule
error's ``control_seeds``, a variant's ``speedup``) are None where absent; the few whose
JSON value may itself be null while present follow the rule stated on their record.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field, fields, replace


def _list(v):
    """A stored pair or sequence as JSON's list (None stays None)."""
    return None if v is None else list(v)


def _tuple(v):
    return None if v is None else tuple(v)


def _json(v):
    """A field's value as JSON: a record's ``to_dict()``, a tuple as a list, a mapping as a
    dict (copied)."""
    if hasattr(v, "to_dict"):
        return v.to_dict()
    if isinstance(v, tuple):
        return [_json(x) for x in v]
    if isinstance(v, Mapping):
        return {k: _json(x) for k, x in v.items()}
    return v


def _plain(rec, *names) -> dict:
    """The JSON of record ``rec``: its fields ``names`` (default: all) in order."""
    return {n: _json(getattr(rec, n)) for n in names or (f.name for f in fields(rec))}


def _record(cls, d: Mapping, **made):
    """A record of ``cls`` from its JSON ``d``: each field its key's value (a key ``d``
    lacks: the field's default), the fields in ``made`` as given (converted values)."""
    names = (f.name for f in fields(cls))
    return cls(**{n: made[n] if n in made else d[n] for n in names if n in made or n in d})


# ------------------------------------------------------------------------ one metric
@dataclass(frozen=True)
class Bias:
    """A metric's signed error over its levels with its two-sided interval at
    ``confidence`` [-]; ``direction`` "high" or "low" where the interval excludes 0,
    else None (engine.study.comparison.judge_metric)."""

    direction: str | None
    error: float
    interval: tuple[float, float]
    confidence: float | None = None

    def to_dict(self) -> dict:
        out = _plain(self, "direction", "error", "interval")
        if self.confidence is not None:
            out["confidence"] = self.confidence
        return out

    @classmethod
    def from_dict(cls, d: Mapping) -> Bias:
        return cls(d.get("direction"), d["error"], _tuple(d["interval"]), d.get("confidence"))


@dataclass(frozen=True)
class BiasedMetric:
    """A verdict's metric whose bias interval excludes 0: its name, direction, signed
    error [-] and interval [-]."""

    metric: str
    direction: str
    error: float
    interval: tuple[float, float]

    def to_dict(self) -> dict:
        return _plain(self)

    @classmethod
    def from_dict(cls, d: Mapping) -> BiasedMetric:
        return cls(d["metric"], d["direction"], d["error"], _tuple(d["interval"]))


@dataclass(frozen=True)
class SeedsNeeded:
    """Seeds an undecided metric would need to be decided if its means and spreads stayed
    as observed: more coarse seeds alone (``coarse``) or more of both sides each
    (``coarse_and_reference``), None past the cap, and the verdict they would give
    (engine.study.seeds.seeds_needed)."""

    coarse: int | None
    coarse_and_reference: int | None
    verdict: str | None

    def to_dict(self) -> dict:
        return _plain(self)

    @classmethod
    def from_dict(cls, d: Mapping) -> SeedsNeeded:
        return cls(d.get("coarse"), d.get("coarse_and_reference"), d.get("verdict"))


@dataclass(frozen=True)
class MetricVerdict:
    """One verdict metric of one group against the references (or its radius's controls):
    the record of engine.study.comparison.judge_metric. Errors and intervals are relative
    [-]; ``tolerance`` [-]; ``level`` the level index that decides (None for one level);
    ``df`` the interval's degrees of freedom; ``uncertainty`` the RMS standard error on the
    compared scale. ``level_error``, ``differs_error`` and ``scale`` exist only where the
    spreads are known (``compared``); ``left_out``: runs left out of the metric (None: none).
    """

    metric: str
    tolerance: float | None = None
    seeds: int = 0
    reference_seeds: int = 0
    alpha_equivalent: float | None = None
    alpha_differs: float | None = None
    interval: tuple[float, float] | None = None
    differs_interval: tuple[float, float] | None = None
    level: int | None = None
    df: float | None = None
    uncertainty: float | None = None
    needs: SeedsNeeded | None = None
    paired: bool = False
    against: str = "reference"
    pooled: bool = False
    pool_df: float | None = None
    screen: str | None = None
    bias: Bias | None = None
    verdict: str = "undecided"
    error: float | None = None
    signed_error: float | None = None
    level_error: float | None = None
    differs_error: float | None = None
    scale: str | None = None
    left_out: int | None = None

    @property
    def compared(self) -> bool:
        """Whether an interval was computed (both spreads known)."""
        return self.scale is not None

    def to_dict(self) -> dict:
        names = [f.name for f in fields(self)]
        out = _plain(self, *names[: names.index("verdict")])
        if self.left_out is not None:
            out["left_out"] = self.left_out
        out.update(error=self.error, signed_error=self.signed_error)
        if self.compared:
            out.update(_plain(self, "level_error", "differs_error", "scale"))
        out["verdict"] = self.verdict
        return out

    @classmethod
    def from_dict(cls, d: Mapping) -> MetricVerdict:
        needs, bias = d.get("needs"), d.get("bias")
        return _record(
            cls,
            d,
            interval=_tuple(d.get("interval")),
            differs_interval=_tuple(d.get("differs_interval")),
            needs=None if needs is None else SeedsNeeded.from_dict(needs),
            bias=None if bias is None else Bias.from_dict(bias),
        )


# --------------------------------------------------------------------------- a group
@dataclass(frozen=True)
class Verdict:
    """The verdict of one group of runs over its metrics (engine.study.reasons.judged): a
    coarse variant against the references (``what`` None), a radius's resolution controls
    against them (``what`` "resolution", with ``diameters_across``, None where unknown), a
    variant against its controls (``what`` "rule", with ``control_seeds`` and
    ``paired_seeds``) or the protocol check (``what`` "protocol").

    ``radius`` [m]; ``rule`` the rule's name ("control", "protocol" for those groups);
    ``verdict`` "equivalent", "differs" or "undecided" with its ``reason``; ``to_decide``
    what would decide it; ``seeds`` the group's seeds; ``biased`` its biased metrics.
    A variant of the study's verdicts also carries its mean ``speedup`` [-], the cell's
    ``thickness_diameters`` and ``height_diameters`` [-], in an unconfined study the runs
    that failed at a peak (``failed_runs``, ``reference_failed_runs``), and
    ``missing_runs`` (run key -> why) where some of its runs did not finish. A variant none
    of whose runs finished was never judged (``judged`` False: no ``to_decide``, no
    ``biased`` in its JSON)."""

    radius: float
    rule: str
    verdict: str = "undecided"
    reason: str = ""
    seeds: int = 0
    metrics: tuple[MetricVerdict, ...] = ()
    to_decide: str | None = None
    biased: tuple[BiasedMetric, ...] = ()
    judged: bool = True
    control_seeds: int | None = None
    paired_seeds: int | None = None
    diameters_across: float | None = None
    speedup: float | None = None
    thickness_diameters: float | None = None
    height_diameters: float | None = None
    failed_runs: int | None = None
    reference_failed_runs: int | None = None
    missing_runs: Mapping[str, str] | None = None
    what: str | None = None

    def metric(self, name: str) -> MetricVerdict | None:
        """The verdict of metric ``name`` (None where it was not judged)."""
        return next((m for m in self.metrics if m.metric == name), None)

    def to_dict(self) -> dict:
        """The verdict's JSON: the keys in the order its judging wrote them, each optional
        one only where the record has it (class docstring)."""
        names = ["radius", "rule", "verdict", "reason", "to_decide", "seeds", "biased"]
        if not self.judged:
            names = [n for n in names if n not in ("to_decide", "biased")]
        out = _plain(self, *names, "metrics")
        for name in _OPTIONAL_KEYS:
            value = getattr(self, name)
            if value is not None or (name == "diameters_across" and self.what == "resolution"):
                out[name] = _json(value)
        return out

    @classmethod
    def from_dict(cls, d: Mapping) -> Verdict:
        missing = d.get("missing_runs")
        return _record(
            cls,
            d,
            metrics=tuple(MetricVerdict.from_dict(m) for m in d.get("metrics") or ()),
            biased=tuple(BiasedMetric.from_dict(b) for b in d.get("biased") or ()),
            judged="to_decide" in d or "biased" in d,
            missing_runs=None if missing is None else dict(missing),
        )


#: A verdict's keys that its JSON carries only where the record has them, in that order.
_OPTIONAL_KEYS = (
    "control_seeds",
    "paired_seeds",
    "diameters_across",
    "speedup",
    "thickness_diameters",
    "height_diameters",
    "failed_runs",
    "reference_failed_runs",
    "missing_runs",
    "what",
)


def _verdicts(items) -> tuple[Verdict, ...]:
    return tuple(Verdict.from_dict(v) for v in items or ())


# -------------------------------------------------------------------- the answer
@dataclass(frozen=True)
class StoppedAt:
    """Where a rule's fixed sequence of radii stopped: the first radius [m] (fine to
    coarse) not judged ``equivalent`` and its verdict."""

    radius: float
    verdict: str

    def to_dict(self) -> dict:
        return _plain(self)


@dataclass(frozen=True)
class RuleAnswer:
    """The recommendation for one rule: the coarsest radius [m] judged ``equivalent`` in
    the fixed sequence fine to coarse (None: none), the reference's law scaled to it
    (``{"type": ..., fields in SI units}``), its mean speed-up over the reference [-],
    every radius judged ``equivalent`` [m] and where the sequence stopped."""

    coarsest_radius: float | None
    coarsest_law: Mapping | None
    speedup: float | None
    radii_equivalent: tuple[float, ...]
    sequence_stopped_at: StoppedAt | None

    def to_dict(self) -> dict:
        return _plain(self)

    @classmethod
    def from_dict(cls, d: Mapping) -> RuleAnswer:
        stop = d.get("sequence_stopped_at")
        law = d.get("coarsest_law")
        return cls(
            d.get("coarsest_radius"),
            None if law is None else dict(law),
            d.get("speedup"),
            tuple(d.get("radii_equivalent") or ()),
            None if stop is None else StoppedAt(stop["radius"], stop["verdict"]),
        )


@dataclass(frozen=True)
class AdhesionAtRadius:
    """The adhesion exponent at one coarse radius (engine.study.advice.adhesion_advice):
    the rule's exponent b whose strength is closest to the reference's (``best``, with its
    strength error ``err_strength`` [-]) and the fitted one (None: no fit) with what it
    was fitted against and its interval (None: unbounded). ``fieller``: the fit is
    Fieller's with its interval (the JSON then carries ``fitted_reference_interval``)."""

    best: float
    err_strength: float
    fitted: float | None
    fitted_against: str | None
    fitted_reference: float | None
    interval: tuple[float, float] | None
    fieller: bool = False

    def to_dict(self) -> dict:
        out = {
            "best": self.best,
            "err_strength": self.err_strength,
            "fitted": self.fitted,
            "fitted_against": self.fitted_against,
            "fitted_reference": self.fitted_reference,
            "interval": _list(self.interval),
        }
        if self.fieller:
            out["fitted_reference_interval"] = _list(self.interval)
        return out

    @classmethod
    def from_dict(cls, d: Mapping) -> AdhesionAtRadius:
        return cls(
            d["best"],
            d["err_strength"],
            d.get("fitted"),
            d.get("fitted_against"),
            d.get("fitted_reference"),
            _tuple(d.get("interval")),
            "fitted_reference_interval" in d,
        )


@dataclass(frozen=True)
class AdhesionFit:
    """The adhesion exponent per coarse radius for the family of rules that differ only in
    it (stiffness exponent ``stiffness_exponent`` and time-step rule ``dt``); ``by_radius``
    is keyed by the radius in metres as ``f"{r:g}"``."""

    stiffness_exponent: float
    dt: str
    by_radius: Mapping[str, AdhesionAtRadius]

    def to_dict(self) -> dict:
        return {
            "stiffness_exponent": self.stiffness_exponent,
            "dt": self.dt,
            "by_radius": {r: a.to_dict() for r, a in self.by_radius.items()},
        }

    @classmethod
    def from_dict(cls, d: Mapping) -> AdhesionFit:
        by = {r: AdhesionAtRadius.from_dict(a) for r, a in (d.get("by_radius") or {}).items()}
        return cls(d["stiffness_exponent"], d["dt"], by)


@dataclass(frozen=True)
class ResolutionCurve:
    """The resolution curve of each property (engine.study.resolution.resolution_curves:
    per metric the fitted line of log value against d / L, its bulk value, the reference's
    offset from it, the sizes it was fitted on and, for a metric with a tolerance, the
    diameters it ``needed``), at ``confidence``. The per-metric fits are the resolution
    module's own records (plain mappings, read by its functions and by
    engine.calibration)."""

    metrics: Mapping[str, Mapping]
    confidence: float = 0.95

    def to_dict(self) -> dict:
        return {
            "metrics": {n: dict(c) for n, c in self.metrics.items()},
            "confidence": self.confidence,
        }

    @classmethod
    def from_dict(cls, d: Mapping) -> ResolutionCurve:
        return cls(dict(d.get("metrics") or {}), d.get("confidence", 0.95))


@dataclass(frozen=True)
class ReferenceSummary:
    """The reference runs: their packing ``seeds`` and, per scalar a user quotes (the
    reference kind's ``summary_scalars``), the mean over seeds and its sample standard
    deviation, in SI units (``scalars``: name -> mean, ``name + "_std"`` -> spread)."""

    seeds: tuple[int, ...]
    scalars: Mapping[str, float] = field(default_factory=dict)

    def has(self, name: str) -> bool:
        """Whether the references measured scalar ``name``."""
        return name in self.scalars

    def mean(self, name: str) -> float | None:
        """The mean of scalar ``name`` over the reference seeds (None: not measured)."""
        return self.scalars.get(name)

    def std(self, name: str) -> float | None:
        """Its sample standard deviation (0 with one seed; None: not measured)."""
        return self.scalars.get(name + "_std")

    def to_dict(self) -> dict:
        return {"seeds": list(self.seeds), **self.scalars}

    @classmethod
    def from_dict(cls, d: Mapping) -> ReferenceSummary:
        return cls(tuple(d.get("seeds") or ()), {k: v for k, v in d.items() if k != "seeds"})


@dataclass(frozen=True)
class AdaptiveSummary:
    """The adaptive rounds of a study that decides (engine.study.loop.adaptive_summary):
    runs planned, the added runs (each ``{run, round, kind, reason}``), the looks it may
    take and the one judged at, why it stopped adding runs (None: not yet), its budget
    [particle-steps] and the particle-steps its rounds added. A report recomputed from
    stored runs may also list the runs still ``pending`` and the stored runs ``beyond``
    what its rule plays now (benchmarks.report)."""

    planned_runs: int
    added_runs: tuple[Mapping, ...]
    looks: int
    look: int
    stopped: str | None
    budget: float | None
    added_particle_steps: float
    pending: tuple[str, ...] | None = None
    beyond: tuple[str, ...] | None = None

    def to_dict(self) -> dict:
        out = {
            "planned_runs": self.planned_runs,
            "added_runs": [dict(a) for a in self.added_runs],
            "looks": self.looks,
            "look": self.look,
            "stopped": self.stopped,
            "budget": self.budget,
            "added_particle_steps": self.added_particle_steps,
        }
        for name in ("pending", "beyond"):
            if getattr(self, name) is not None:
                out[name] = list(getattr(self, name))
        return out

    @classmethod
    def from_dict(cls, d: Mapping) -> AdaptiveSummary:
        return _record(
            cls,
            d,
            added_runs=tuple(dict(a) for a in d.get("added_runs") or ()),
            pending=_tuple(d.get("pending")),
            beyond=_tuple(d.get("beyond")),
        )


# --------------------------------------------------------------------- the report
@dataclass(frozen=True)
class StudyReport:
    """What a study's runs mean for a user (module docstring): the ``tolerances`` [-] and
    ``confidence`` [-] it was judged at; per rule its :class:`RuleAnswer`; the variants'
    ``verdicts``; the finite-size ``warnings``; the resolution controls' ``resolution``
    errors and the variants' ``rule_errors`` against them; the ``control_lines`` said of
    the controls, the resolution curve and the protocol check; the ``adhesion_exponent``;
    the advice in one ``message``; the ``resolution_curve``; the ``protocol`` check's
    verdict; the references' relative ``noise_floor`` [-] per metric (None: one seed) and
    their ``reference`` summary; the ``adaptive`` rounds (None: the study does not
    decide)."""

    tolerances: Mapping[str, float]
    confidence: float
    rules: Mapping[str, RuleAnswer]
    verdicts: tuple[Verdict, ...]
    warnings: tuple[str, ...] = ()
    resolution: tuple[Verdict, ...] = ()
    rule_errors: tuple[Verdict, ...] = ()
    control_lines: tuple[str, ...] = ()
    adhesion_exponent: AdhesionFit | None = None
    message: str = ""
    resolution_curve: ResolutionCurve | None = None
    protocol: Verdict | None = None
    noise_floor: Mapping[str, float | None] = field(default_factory=dict)
    reference: ReferenceSummary | None = None
    adaptive: AdaptiveSummary | None = None

    def verdict(self, radius: float, rule: str) -> Verdict | None:
        """The verdict of variant (``radius`` [m], ``rule``), None where it is not in the
        study (radii compared to 1e-12 m)."""
        return next(
            (v for v in self.verdicts if v.rule == rule and abs(v.radius - radius) < 1e-12), None
        )

    def judged_groups(self) -> Iterator[tuple[str, Verdict]]:
        """Every judged group with what it is: ``("variant", v)`` for each verdict, then
        ``("resolution", v)``, ``("rule", v)`` and ``("protocol", v)``."""
        yield from (("variant", v) for v in self.verdicts)
        yield from (("resolution", v) for v in self.resolution)
        yield from (("rule", v) for v in self.rule_errors)
        if self.protocol is not None:
            yield "protocol", self.protocol

    def with_adaptive(self, adaptive: AdaptiveSummary | None) -> StudyReport:
        """This report with its adaptive rounds set."""
        return replace(self, adaptive=adaptive)

    def to_dict(self) -> dict:
        """The report as the JSON a study's summary carries under ``"advisor"``."""
        out = {
            "tolerances": dict(self.tolerances),
            "confidence": self.confidence,
            "rules": {name: a.to_dict() for name, a in self.rules.items()},
            "verdicts": [v.to_dict() for v in self.verdicts],
            "warnings": list(self.warnings),
            "resolution": [v.to_dict() for v in self.resolution],
            "rule_errors": [v.to_dict() for v in self.rule_errors],
            "control_lines": list(self.control_lines),
            "adhesion_exponent": None
            if self.adhesion_exponent is None
            else self.adhesion_exponent.to_dict(),
            "message": self.message,
            "resolution_curve": None
            if self.resolution_curve is None
            else self.resolution_curve.to_dict(),
            "protocol": None if self.protocol is None else self.protocol.to_dict(),
            "noise_floor": dict(self.noise_floor),
            "reference": None if self.reference is None else self.reference.to_dict(),
        }
        if self.adaptive is not None:
            out["adaptive"] = self.adaptive.to_dict()
        return out

    @classmethod
    def from_dict(cls, d: Mapping | None) -> StudyReport:
        """The report of a summary's ``"advisor"`` JSON (an empty report for None or {})."""
        d = d or {}
        adh, curve = d.get("adhesion_exponent"), d.get("resolution_curve")
        protocol, ref, adaptive = d.get("protocol"), d.get("reference"), d.get("adaptive")
        return cls(
            tolerances=dict(d.get("tolerances") or {}),
            confidence=d.get("confidence", 0.95),
            rules={n: RuleAnswer.from_dict(a) for n, a in (d.get("rules") or {}).items()},
            verdicts=_verdicts(d.get("verdicts")),
            warnings=tuple(d.get("warnings") or ()),
            resolution=_verdicts(d.get("resolution")),
            rule_errors=_verdicts(d.get("rule_errors")),
            control_lines=tuple(d.get("control_lines") or ()),
            adhesion_exponent=None if adh is None else AdhesionFit.from_dict(adh),
            message=d.get("message", ""),
            resolution_curve=None if curve is None else ResolutionCurve.from_dict(curve),
            protocol=None if protocol is None else Verdict.from_dict(protocol),
            noise_floor=dict(d.get("noise_floor") or {}),
            reference=None if ref is None else ReferenceSummary.from_dict(ref),
            adaptive=None if adaptive is None else AdaptiveSummary.from_dict(adaptive),
        )


__all__ = [
    "AdaptiveSummary",
    "AdhesionAtRadius",
    "AdhesionFit",
    "Bias",
    "BiasedMetric",
    "MetricVerdict",
    "ReferenceSummary",
    "ResolutionCurve",
    "RuleAnswer",
    "SeedsNeeded",
    "StoppedAt",
    "StudyReport",
    "Verdict",
]
