"""What a scaling study gives back, assembled from its runs' outcomes: errors against the
reference, the table and groups, and the typed report (engine.study.report; docs/PHYSICS.md
sections 5 and 7). Recomputable at any time from stored runs (:func:`assemble`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..uniaxial.results import UniaxialResult
from .advice import answer_lines, build_report
from .kinds import kind_of
from .look import judge_look
from .metrics import metric_column
from .plan import PROTOCOL, PlannedRun
from .report import AdaptiveSummary, StudyReport
from .spec import ScalingRule, StudySpec


def table_units(spec: StudySpec) -> dict:
    """Units of the columns of a study's table: its reference kind's
    (:mod:`engine.study.kinds`: ``TABLE_UNITS``, ``SHEAR_TABLE_UNITS``)."""
    return dict(kind_of(spec.reference).table_units)


@dataclass
class RunResult:
    """One finished run: its key, radius [m], rule (None for a reference or a control), seed,
    the :class:`UniaxialResult`, its errors (verdict metrics against the mean reference, shape
    measures against the reference of its seed; zeros for references), its speed-up over
    the median reference wall time (stepping only: kernel compilation is set-up time, and
    the median keeps a first run's one-off compilation of the measuring kernels out), its
    speed-up in particle-steps (the cost that does not depend on the machine or its load),
    its scale s = R / R_ref (a control: that of the coarse radius it stands for) and whether
    it is a resolution ``control``."""

    key: str
    radius: float
    rule: ScalingRule | None
    seed: int
    result: UniaxialResult
    errors: dict[str, float]
    speedup: float = 1.0
    scale: float = 1.0
    control: bool = False
    speedup_steps: float = 1.0
    protocol: bool = False

    @property
    def is_reference(self) -> bool:
        return self.rule is None and not self.control and not self.protocol

    @property
    def label(self) -> str:
        """``"reference"``, ``"control"``, ``"protocol"`` or the rule's name."""
        if self.control:
            return "control"
        if self.protocol:
            return PROTOCOL
        return "reference" if self.rule is None else self.rule.name

    def row(self) -> dict:
        """The run's row of the study table (a shear run's: its locus's scalars in place of
        the uniaxial strength; no overburden: gravity is off from its consolidation on)."""
        s = self.result.scalars
        row = {
            "run": self.key,
            "radius": self.radius,
            "rule": self.label,
            "seed": self.seed,
            "scale": self.scale,
            "particles": int(s["particles"]),
            "steps": int(s["steps"]),
            "dt": s["dt"],
            "wall_time": s["wall_time"],
            "particle_steps": s["particle_steps"],
            "speedup": self.speedup,
            "speedup_steps": self.speedup_steps,
            "thickness_diameters": s["thickness_diameters"],
            "height_diameters": s["height_diameters"],
        }
        row.update(kind_of(self.result).row_scalars(self.result))
        row.update(self.errors)
        return row


@dataclass
class StudyResult:
    """Result of :func:`run_study`: ``runs`` (key -> :class:`RunResult`, references
    first), ``table`` (one row per run, units in its kind's ``table_units``), ``groups`` (mean and
    spread over seeds per radius and rule), ``report`` (the typed
    :class:`engine.study.report.StudyReport`: verdicts, recommendation, noise floor,
    warnings, adhesion exponent) and ``failed`` (key -> error text of the runs that
    failed)."""

    spec: StudySpec
    runs: dict[str, RunResult]
    table: list[dict]
    groups: list[dict]
    report: StudyReport
    failed: dict[str, str] = field(default_factory=dict)

    def to_summary(self) -> dict:
        """JSON-friendly summary: the answer (the study's decision in one line, then the
        line that qualifies it), table, groups, the report (under ``"advisor"``, the key
        summaries have always had), failed runs and units."""
        return {
            "answer": answer_lines(self.report, self.spec.reference.radius),
            "table": self.table,
            "groups": self.groups,
            "advisor": self.report.to_dict(),
            "failed": self.failed,
            "units": table_units(self.spec),
        }

    def figure(self, kind: str):
        """A matplotlib Figure (no pyplot) of ``kind`` in :data:`engine.io.figures.KINDS`
        (a shear study's: :data:`engine.io.figures.SHEAR_KINDS`)."""
        from ..io.figures import figure, study_plot_data

        return figure(kind, *study_plot_data(self))

    def save_plots(self, directory) -> list:
        """Write every plot kind of the study as PNG into ``directory``
        (:func:`engine.io.figures.kinds_of`); returns the paths."""
        from ..io.figures import save_all, study_plot_data

        return save_all(directory, *study_plot_data(self))


class RunFailed(RuntimeError):
    """A run of a study failed (its stage did not end, or it went unstable); ``run_key``
    names it and ``__cause__`` holds the engine's error. A study raises it only when no
    reference run succeeded; failed coarse runs are listed in ``StudyResult.failed``."""

    def __init__(self, run_key: str, error: Exception | str):
        self.run_key = run_key
        self.text = error if isinstance(error, str) else f"{type(error).__name__}: {error}"
        super().__init__(f"run {run_key} failed: {self.text}")

    def __reduce__(self):  # pickles with its fields (see engine.core.errors)
        return type(self), (self.run_key, self.text)


def assemble(
    spec: StudySpec,
    planned: list[PlannedRun],
    outcomes: dict,
    look: int = 1,
    adaptive: AdaptiveSummary | None = None,
) -> StudyResult:
    """Errors, table, groups and report from the runs' outcomes (key -> a result of the
    test's kind, or error text), the verdicts judged at ``look`` of ``spec.looks``
    (engine.study.stopping.final_look): the runs measured and judged once, by
    :func:`engine.study.look.judge_look` (the adaptive loop's arithmetic), then tabled and
    reported (:func:`engine.study.advice.build_report`; ``adaptive``: the study's rounds,
    where it decides). Recomputable at any time from stored runs."""
    at = judge_look(spec, planned, outcomes, look)
    failed, refs, names = at.failed, at.refs, at.names
    if not refs:
        key = next(p.key for p in planned if p.is_reference)
        raise RunFailed(key, failed.get(key, "no reference run succeeded"))
    ref_wall = float(np.median([r.scalars["wall_time"] for r in refs.values()]))
    ref_steps = float(np.median([r.scalars["particle_steps"] for r in refs.values()]))
    runs: dict[str, RunResult] = {}
    for p in planned:
        if p.key not in at.values:
            continue
        res, errors = outcomes[p.key], at.errors[p.key]
        if p.is_reference:
            runs[p.key] = RunResult(p.key, p.radius, None, p.seed, res, errors, 1.0, 1.0)
            continue
        runs[p.key] = RunResult(
            p.key,
            p.radius,
            p.rule,
            p.seed,
            res,
            errors,
            ref_wall / res.scalars["wall_time"],
            p.radius / spec.reference.radius,
            p.control,
            ref_steps / res.scalars["particle_steps"],
            p.protocol,
        )
    table = [r.row() for r in runs.values()]
    groups = _groups(spec, runs, names, at.shapes)
    report = build_report(spec, at, runs, groups, planned, adaptive)
    return StudyResult(spec, runs, table, groups, report, failed)


def _groups(spec: StudySpec, runs: dict[str, RunResult], names, shapes) -> list[dict]:
    """Mean and spread (sample standard deviation; 0 with one seed) over seeds of the
    errors, wall time and speed-up of every (radius, rule) with at least one run."""
    out = []
    cols_err = [metric_column(n) for n in names] + list(shapes)
    for r in spec.coarse_radii:
        for rule in spec.rules:
            members = [x for x in runs.values() if x.rule == rule and x.radius == r]
            if not members:
                continue
            a, b, c = rule.exponents(spec.reference.pair_law)
            g = {
                "radius": r,
                "rule": rule.name,
                "scale": r / spec.reference.radius,
                "stiffness_exponent": a,
                "adhesion_exponent": b,
                "adhesive_exponent": c,
                "dt": rule.dt,
                "seeds": len(members),
                "thickness_diameters": members[0].result.scalars["thickness_diameters"],
            }
            cols = {n: [m.errors[n] for m in members] for n in cols_err}
            for k in ("wall_time", "height_diameters"):
                cols[k] = [m.result.scalars[k] for m in members]
            cols["speedup"] = [m.speedup for m in members]
            cols["speedup_steps"] = [m.speedup_steps for m in members]
            if getattr(spec.reference, "unconfined", False):
                cols["unconfined_strength"] = [
                    m.result.scalars["unconfined_strength"] for m in members
                ]
                g["failed_runs"] = int(
                    sum(m.result.scalars["unconfined_failure"] == 1.0 for m in members)
                )
            for n, v in cols.items():
                g[n] = float(np.mean(v))
                g[n + "_std"] = float(np.std(v, ddof=1)) if len(v) > 1 else 0.0
            out.append(g)
    return out
