"""What a scaling study gives back, assembled from its runs' outcomes: errors against the
reference, the table and groups, noise floor, verdicts and advice (docs/PHYSICS.md sections 5
and 7). Recomputable at any time from stored runs (:func:`assemble`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..uniaxial.results import UniaxialResult
from .advisor import advise
from .kinds import kind_of
from .look import judge_look
from .metrics import metric_column, metric_values
from .plan import PROTOCOL, PlannedRun
from .resolution import curve_lines, diameters_needed, resolution_curves
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
    spread over seeds per radius and rule), ``advisor`` (verdicts, noise floor, warnings,
    adhesion exponent; see :func:`engine.study.advisor.advise`) and ``failed`` (key -> error text
    of the runs that failed)."""

    spec: StudySpec
    runs: dict[str, RunResult]
    table: list[dict]
    groups: list[dict]
    advisor: dict
    failed: dict[str, str] = field(default_factory=dict)

    def to_summary(self) -> dict:
        """JSON-friendly summary: the answer (the study's decision in one line, then the
        line that qualifies it), table, groups, advisor, failed runs and units."""
        from .advisor import answer_lines

        return {
            "answer": answer_lines(self.advisor, self.spec.reference.radius),
            "table": self.table,
            "groups": self.groups,
            "advisor": self.advisor,
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
    spec: StudySpec, planned: list[PlannedRun], outcomes: dict, look: int = 1
) -> StudyResult:
    """Errors, groups, noise floor, verdicts and advisor from the runs' outcomes (key ->
    :class:`UniaxialResult` or error text), the verdicts judged at ``look`` of ``spec.looks``
    (engine.study.stopping.final_look): the runs measured and judged once, by
    :func:`engine.study.look.judge_look` (the adaptive loop's arithmetic), then tabled and
    advised. Recomputable at any time from stored runs."""
    at = judge_look(spec, planned, outcomes, look)
    failed, refs, names = at.failed, at.refs, at.names
    if not refs:
        key = next(p.key for p in planned if p.is_reference)
        raise RunFailed(key, failed.get(key, "no reference run succeeded"))
    unconfined = getattr(spec.reference, "unconfined", False)
    ref_values = at.ref_values
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
    controls, half, verdicts = at.controls, at.half, at.verdicts
    table = [r.row() for r in runs.values()]
    groups = _groups(spec, runs, names, at.shapes)
    keys_of: dict[tuple, list[str]] = {}
    for p in planned:
        if not p.is_reference and not p.control and not p.protocol:
            keys_of.setdefault((p.radius, p.rule.name), []).append(p.key)
    for v in verdicts:
        g = next(g for g in groups if g["radius"] == v["radius"] and g["rule"] == v["rule"])
        v.update(
            speedup=g["speedup"],
            thickness_diameters=g["thickness_diameters"],
            height_diameters=g["height_diameters"],
        )
    if unconfined:
        _note_failure_kinds(refs, runs, verdicts)
    judged = {(v["radius"], v["rule"]) for v in verdicts}
    for variant, keys in keys_of.items():
        lost = {k: failed[k] for k in keys if k in failed}
        if variant not in judged:
            verdicts.append(
                {
                    "radius": variant[0],
                    "rule": variant[1],
                    "verdict": "undecided",
                    "reason": "no run of this variant finished",
                    "seeds": 0,
                    "metrics": [],
                }
            )
        if lost:
            v = next(v for v in verdicts if (v["radius"], v["rule"]) == variant)
            v["missing_runs"] = lost
            v["reason"] += "; missing: " + "; ".join(f"{k} ({t})" for k, t in lost.items())
    ref_strength = None
    if unconfined:
        ref_strength = float(np.mean([r.scalars["unconfined_strength"] for r in refs.values()]))
    resolution, rule_errors = at.resolution, at.rule_errors
    strengths = None
    if unconfined:
        strengths = {"reference": [r.scalars["unconfined_strength"] for r in refs.values()]}
        strengths["variants"], strengths["controls"] = {}, {}
        for r in runs.values():
            if r.is_reference or r.protocol:
                continue
            st = r.result.scalars["unconfined_strength"]
            if r.control:
                strengths["controls"].setdefault(r.radius, []).append(st)
            else:
                strengths["variants"].setdefault((r.radius, r.rule.name), []).append(st)
    advisor = advise(spec, groups, verdicts, ref_strength, resolution, rule_errors, strengths)
    advisor["resolution_curve"] = None
    if controls:
        ctl_runs: dict[float, list] = {}
        for r in runs.values():
            if r.control:
                ctl_runs.setdefault(r.radius, []).append(
                    (r.result.scalars["thickness_diameters"], metric_values(r.result))
                )
        ref_runs = [
            (x.scalars["thickness_diameters"], v) for x, v in zip(refs.values(), ref_values)
        ]
        curve = resolution_curves(ref_runs, ctl_runs, names, getattr(spec, "confidence", 0.95))
        for n, c in curve["metrics"].items():  # the fewest diameters across each property needs
            if n in spec.tolerances:
                c["needed"] = diameters_needed(c, spec.tolerances[n])
        advisor["resolution_curve"] = curve
        lines = curve_lines(curve)
        advisor["control_lines"] = advisor["control_lines"] + lines
        if lines:
            advisor["message"] = "; ".join([advisor["message"], *lines])
    advisor["protocol"] = None
    if half:
        check = at.protocol
        advisor["protocol"] = check
        line = protocol_line(check)
        advisor["control_lines"] = [*advisor["control_lines"], line]
        advisor["message"] = "; ".join([advisor["message"], line])
    advisor["noise_floor"] = at.noise_floor
    advisor["reference"] = _reference_summary(
        refs, names, ref_values, kind_of(spec.reference).summary_scalars
    )
    return StudyResult(spec, runs, table, groups, advisor, failed)


def protocol_line(check: dict) -> str:
    """The advisor's line on the protocol check (docs/PHYSICS.md section 7.6)."""
    says = {
        "equivalent": "is quasi-static and its time step converged: halving the inertial "
        "number (or platen speed) and the time step changes no metric beyond its tolerance",
        "differs": "is NOT converged: halving the inertial number (or platen speed) and the "
        "time step changes a metric beyond its tolerance",
        "undecided": "is not shown converged: halving the inertial number (or platen speed) "
        "and the time step leaves a metric undecided",
    }
    return f"protocol check: the study's protocol {says[check['verdict']]} ({check['reason']})"


def _note_failure_kinds(refs: dict, runs: dict[str, RunResult], verdicts: list[dict]) -> None:
    """Say what a strength verdict compared: only the runs that failed at a peak
    (engine.study.noise; engine.uniaxial.measures.failed_by_curve) where any run of the
    study failed, with how many references and runs of the variant hardened instead (their
    "strength" is the largest stress up to the strain limit, another quantity)."""
    ref_flags = [r.scalars["unconfined_failure"] == 1.0 for r in refs.values()]
    for v in verdicts:
        flags = [
            r.result.scalars["unconfined_failure"] == 1.0
            for r in runs.values()
            if r.rule is not None and r.rule.name == v["rule"] and r.radius == v["radius"]
        ]
        v["failed_runs"] = sum(flags)
        v["reference_failed_runs"] = sum(ref_flags)
        if flags and len(set(flags + ref_flags)) > 1:
            v["reason"] += (
                f"; strength compares failed runs only: {sum(ref_flags)} of "
                f"{len(ref_flags)} references and {sum(flags)} of {len(flags)} runs of this "
                "variant failed at a peak, the others hardened to the strain limit and are "
                "left out of it"
            )


def _reference_summary(refs: dict, names, ref_values: list[dict], scalars) -> dict:
    """Mean and spread over reference seeds of the scalars a user quotes (``scalars``: the
    reference kind's, :mod:`engine.study.kinds`)."""
    out = {"seeds": sorted(refs)}
    for k in scalars:
        v = [r.scalars[k] for r in refs.values() if k in r.scalars]
        if v:
            out[k] = float(np.mean(v))
            out[k + "_std"] = float(np.std(v, ddof=1)) if len(v) > 1 else 0.0
    return out


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
