"""Running a scaling study: every run of a :class:`StudySpec`, in this process or as tasks on
any :class:`concurrent.futures.Executor`, then errors, noise floor and verdicts
(docs/PHYSICS.md sections 5 and 7).

The spec and its runs are in :mod:`engine.study_spec`, the metrics in :mod:`engine.metrics`,
the verdict logic in :mod:`engine.advisor`. Runs are independent: a coarse run's time step is
known before its reference runs, so all runs can go side by side; the comparison is made
when they are all done. A failed coarse run is recorded with its error while the others go
on; ``on_run`` hears of every finished run at once (to store it), and ``completed`` hands
back stored runs so that a resumed study runs only what is missing.
"""

from __future__ import annotations

import concurrent.futures as cf
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from .advisor import advise, judge_groups
from .channel import task_progress
from .errors import StopRequested
from .metrics import (
    METRIC_COLUMNS,
    SHAPE_NAMES,
    metric_names,
    metric_values,
    relative_error,
    shape_errors,
)
from .study_spec import (
    NAMED_RULES,
    PlannedRun,
    ScalingRule,
    StudySpec,
    default_study,
    estimated_steps,
    run_key,
)
from .uniaxial import Progress, UniaxialResult, run_uniaxial

__all__ = ["NAMED_RULES", "TABLE_UNITS", "PlannedRun", "RunFailed", "RunResult", "ScalingRule",
           "StudyProgress", "StudyResult", "StudySpec", "default_study", "run_key",
           "run_study"]

#: Units of the columns of :attr:`StudyResult.table`.
TABLE_UNITS = {
    "run": "",
    "radius": "m",
    "rule": "",
    "seed": "",
    "scale": "1",
    "particles": "1",
    "steps": "1",
    "dt": "s",
    "wall_time": "s",
    "particle_steps": "1",
    "speedup": "1",
    "thickness_diameters": "1",
    "height_diameters": "1",
    "unconfined_failure": "1",
    "unconfined_strength": "Pa",
    **dict.fromkeys(METRIC_COLUMNS.values(), "1"),
    **dict.fromkeys(SHAPE_NAMES, "1"),
}



@dataclass(frozen=True)
class StudyProgress:
    """What a study progress callback receives: overall ``fraction`` in [0, 1], the run
    (``run_index`` of ``n_runs``, ``run_key``), its ``stage`` and simulated ``time`` [s]."""

    fraction: float
    run_index: int
    n_runs: int
    run_key: str
    stage: str
    time: float
    message: str = ""


@dataclass
class RunResult:
    """One finished run: its key, radius [m], rule (None for a reference), seed, the
    :class:`UniaxialResult`, its errors (verdict metrics against the mean reference, shape
    measures against the reference of its seed; zeros for references), its speed-up over
    the mean reference wall time and its scale s = R / R_ref."""

    key: str
    radius: float
    rule: ScalingRule | None
    seed: int
    result: UniaxialResult
    errors: dict[str, float]
    speedup: float = 1.0
    scale: float = 1.0

    def row(self) -> dict:
        """The run's row of the study table."""
        s = self.result.scalars
        row = {
            "run": self.key, "radius": self.radius,
            "rule": "reference" if self.rule is None else self.rule.name, "seed": self.seed,
            "scale": self.scale,
            "particles": int(s["particles"]), "steps": int(s["steps"]), "dt": s["dt"],
            "wall_time": s["wall_time"], "particle_steps": s["particle_steps"],
            "speedup": self.speedup, "thickness_diameters": s["thickness_diameters"],
            "height_diameters": s["height_diameters"],
        }
        if "unconfined_strength" in s:
            row["unconfined_failure"] = s["unconfined_failure"]
            row["unconfined_strength"] = s["unconfined_strength"]
        row.update(self.errors)
        return row


@dataclass
class StudyResult:
    """Result of :func:`run_study`: ``runs`` (key -> :class:`RunResult`, references
    first), ``table`` (one row per run, units in :data:`TABLE_UNITS`), ``groups`` (mean and
    spread over seeds per radius and rule), ``advisor`` (verdicts, noise floor, warnings,
    adhesion exponent; see :func:`engine.advisor.advise`) and ``failed`` (key -> error text
    of the runs that failed)."""

    spec: StudySpec
    runs: dict[str, RunResult]
    table: list[dict]
    groups: list[dict]
    advisor: dict
    failed: dict[str, str] = field(default_factory=dict)

    def to_summary(self) -> dict:
        """JSON-friendly summary: table, groups, advisor, failed runs and units."""
        return {"table": self.table, "groups": self.groups, "advisor": self.advisor,
                "failed": self.failed, "units": TABLE_UNITS}

    def figure(self, kind: str):
        """A matplotlib Figure (no pyplot) of ``kind`` in :data:`engine.plots.KINDS`."""
        from .plots import figure, study_plot_data

        return figure(kind, *study_plot_data(self))

    def save_plots(self, directory) -> list:
        """Write every plot kind as PNG into ``directory``; returns the paths."""
        from .plots import save_all, study_plot_data

        return save_all(directory, *study_plot_data(self))


StudyCallback = Callable[[StudyProgress], object]
RunCallback = Callable[[str, "UniaxialResult | str"], object]


class RunFailed(RuntimeError):
    """A run of a study failed (its stage did not end, or it went unstable); ``run_key``
    names it and ``__cause__`` holds the engine's error. A study raises it only when no
    reference run succeeded; failed coarse runs are listed in ``StudyResult.failed``."""

    def __init__(self, run_key: str, error: Exception | str):
        self.run_key = run_key
        self.text = error if isinstance(error, str) else f"{type(error).__name__}: {error}"
        super().__init__(f"run {run_key} failed: {self.text}")

    def __reduce__(self):  # pickles with its fields (see engine.errors)
        return type(self), (self.run_key, self.text)


def _execute(test, threads: int | None = None, key: str = "", channel=None
             ) -> UniaxialResult:
    """One run as a task (a picklable top-level function for process and cluster pools);
    with a ``channel`` (:mod:`engine.channel`) it reports its progress there and stops with
    :class:`engine.StopRequested` when the study asks it to."""
    if threads is not None:
        import numba

        numba.set_num_threads(max(1, min(threads, numba.config.NUMBA_NUM_THREADS)))
    if channel is not None and channel.stop_requested():
        raise StopRequested(f"run {key} not started: the study was stopped")
    return run_uniaxial(test, progress=None if channel is None else task_progress(channel, key))


def _weights(planned: list[PlannedRun]) -> np.ndarray:
    cost = np.array([estimated_steps(p.test) * p.test.n_particles for p in planned])
    return cost / cost.sum()


def run_study(spec: StudySpec, progress: StudyCallback | None = None,
              executor: cf.Executor | None = None, *, completed: dict | None = None,
              on_run: RunCallback | None = None, task_threads: int | None = 1,
              channel=None, poll_interval: float = 1.0) -> StudyResult:
    """Run every run of ``spec`` that is not in ``completed``, then judge the study.

    Args:
        spec: the study.
        progress: receives :class:`StudyProgress` (in this process, within each run; with
            an executor, as runs finish, and with a ``channel`` also every
            ``poll_interval`` seconds from the running tasks, the fraction summed over the
            runs); returning ``False`` stops the study with :class:`engine.StopRequested`
            (with an executor, runs not yet started are cancelled; running ones stop at
            their next report through the ``channel``, or are left to finish without one).
        executor: None runs the runs one after another here; any
            :class:`concurrent.futures.Executor` (a ``ProcessPoolExecutor`` with the
            "spawn" or "forkserver" context, ``distributed.Client(...).get_executor()``)
            runs them as tasks. Results are bit-identical either way.
        completed: key -> :class:`UniaxialResult` (or an error text for a failed run) of
            runs already done, e.g. read back from storage when a study resumes.
        on_run: called with (key, UniaxialResult or error text) as soon as a run ends.
        task_threads: engine threads per task on an executor (1: one core per task).
        channel: with an executor, how tasks in other processes or hosts report progress
            and hear a stop request (:class:`engine.FileChannel`); reset when the study
            starts.
        poll_interval: seconds between two reads of the ``channel`` [s].

    Raises: :class:`RunFailed` as soon as every reference run has failed; ``ValueError``
    at once, before any run starts, for a ``ProcessPoolExecutor`` that forks
    (:func:`check_executor`).
    """
    check_executor(executor)
    planned = spec.planned_runs()
    weights = _weights(planned)
    outcomes: dict[str, UniaxialResult | str] = dict(completed or {})
    todo = [i for i, p in enumerate(planned) if p.key not in outcomes]

    refs = [q.key for q in planned if q.is_reference]

    def record(p: PlannedRun, outcome) -> None:
        outcomes[p.key] = outcome
        if on_run is not None:
            on_run(p.key, outcome)
        if p.is_reference and all(isinstance(outcomes.get(k), str) for k in refs):
            # every reference failed: nothing can be compared, stop at once
            raise RunFailed(refs[0], outcomes[refs[0]])

    if executor is None:
        _run_here(planned, todo, weights, outcomes, progress, record)
    else:
        if channel is not None:
            channel.reset()
        _run_on(executor, planned, todo, weights, outcomes, progress, record, task_threads,
                channel, poll_interval)
    return assemble(spec, planned, outcomes)


def check_executor(executor: cf.Executor | None) -> None:
    """Refuse an executor that cannot run engine tasks: a ``ProcessPoolExecutor`` whose
    processes are forked (Python's default context on Linux before 3.14). A process that has
    run the engine holds GNU OpenMP threads, and its forked children die at their first run
    ("fork() called from a process already using GNU OpenMP, this is unsafe"), which breaks
    the pool (``BrokenProcessPool``) mid-study. Raises ``ValueError`` naming the fix."""
    if not isinstance(executor, cf.ProcessPoolExecutor):
        return
    context = getattr(executor, "_mp_context", None)
    method = context.get_start_method() if context is not None else None
    if method == "fork":
        raise ValueError(
            "run_study: this ProcessPoolExecutor forks its processes, and a forked engine "
            "process dies (GNU OpenMP is not fork-safe), breaking the pool: create it with "
            "the spawn or forkserver context, e.g. ProcessPoolExecutor(n, mp_context="
            "multiprocessing.get_context('spawn'))")


def _done_weight(planned, weights, outcomes) -> float:
    """The share of the study's estimated cost already done (runs with an outcome)."""
    return float(sum(w for p, w in zip(planned, weights) if p.key in outcomes))


def _run_here(planned, todo, weights, outcomes, progress, record) -> None:
    done_weight = _done_weight(planned, weights, outcomes)
    for i in todo:
        p = planned[i]

        def report(pr: Progress, i=i, p=p, base=done_weight):
            if progress is None:
                return None
            frac = base + weights[i] * pr.fraction
            return progress(StudyProgress(float(min(frac, 1.0)), i, len(planned), p.key,
                                          pr.stage, pr.time, pr.message))

        # a first report names the run before its packing and kernels are built, so a run
        # that fails there is not blamed on the previous one
        if report(Progress(0.0, "setup", 0.0, 0.0, 0, "building the packing")) is False:
            raise StopRequested(f"stopped by the progress callback before run {p.key}")
        try:
            outcome = run_uniaxial(p.test, progress=report)
        except StopRequested:
            raise
        except Exception as e:
            outcome = f"{type(e).__name__}: {e}"
        record(p, outcome)
        done_weight += weights[i]


def _run_on(executor, planned, todo, weights, outcomes, progress, record, threads, channel,
            poll_interval) -> None:
    # in planned order: the references first (the longest runs, needed by every comparison)
    futures = {executor.submit(_execute, planned[i].test, threads, planned[i].key, channel): i
               for i in todo}
    done_weight = _done_weight(planned, weights, outcomes)
    pending = set(futures)

    def ask(report: StudyProgress) -> None:
        if progress is not None and progress(report) is False:
            if channel is not None:
                channel.request_stop()  # running tasks stop at their next report
            raise StopRequested(f"stopped by the progress callback during run {report.run_key}")

    try:
        while pending:
            done, pending = cf.wait(pending, timeout=poll_interval if channel else None,
                                    return_when=cf.FIRST_COMPLETED)
            for fut in done:
                i = futures[fut]
                p = planned[i]
                try:
                    outcome = fut.result()
                except (cf.CancelledError, StopRequested):
                    continue  # stopped, not failed: a resume runs it again
                except cf.BrokenExecutor:
                    # the pool itself died (a worker process killed): an interruption, not a
                    # failure of the run; finished runs were reported, a resume runs the rest
                    raise
                except Exception as e:
                    outcome = f"{type(e).__name__}: {e}"
                record(p, outcome)
                done_weight += weights[i]
                ask(StudyProgress(float(min(done_weight, 1.0)), i, len(planned), p.key, "done",
                                  0.0, "run finished" if not isinstance(outcome, str) else outcome))
            if channel is not None and pending and not done:
                _report_running(channel, planned, weights, [futures[f] for f in pending],
                                done_weight, ask)
    finally:
        for fut in futures:
            fut.cancel()


def _report_running(channel, planned, weights, pending, done_weight, ask) -> None:
    """One progress report from the channel of the ``pending`` runs (their planned indices):
    the study's fraction summed over the runs, named after the least advanced running run."""
    seen = channel.read()
    running = [(i, seen[planned[i].key]) for i in pending if planned[i].key in seen]
    if not running:
        return
    frac = done_weight + sum(weights[i] * min(max(r["fraction"], 0.0), 1.0) for i, r in running)
    i, r = min(running, key=lambda ir: ir[1]["fraction"])
    ask(StudyProgress(float(min(frac, 1.0)), i, len(planned), planned[i].key, r["stage"],
                      float(r["time"]), f"{len(running)} runs in progress"))


def assemble(spec: StudySpec, planned: list[PlannedRun], outcomes: dict) -> StudyResult:
    """Errors, groups, noise floor, verdicts and advisor from the runs' outcomes (key ->
    :class:`UniaxialResult` or error text). Recomputable at any time from stored runs."""
    failed = {p.key: outcomes[p.key] for p in planned if isinstance(outcomes.get(p.key), str)}
    missing = [p.key for p in planned if p.key not in outcomes]
    for k in missing:
        failed[k] = "not run"
    refs = {p.seed: outcomes[p.key] for p in planned
            if p.is_reference and p.key in outcomes and not isinstance(outcomes[p.key], str)}
    if not refs:
        key = next(p.key for p in planned if p.is_reference)
        raise RunFailed(key, failed.get(key, "no reference run succeeded"))
    names = metric_names(spec.reference.unconfined)
    ref_values = [metric_values(r) for r in refs.values()]
    ref_wall = float(np.mean([r.scalars["wall_time"] for r in refs.values()]))
    cons = spec.reference.consolidation_stress
    floor_mean = {n: np.mean([v[n] for v in ref_values], axis=0) for n in names}
    first_ref = next(iter(refs.values()))
    runs: dict[str, RunResult] = {}
    variants: dict[tuple, list[dict]] = {}
    for p in planned:
        res = outcomes.get(p.key)
        if res is None or isinstance(res, str):
            continue
        values = metric_values(res)
        errors = {METRIC_COLUMNS[n]: (0.0 if p.is_reference else
                                      relative_error(n, values[n], floor_mean[n], cons))
                  for n in names}
        if p.is_reference:
            errors.update(dict.fromkeys(SHAPE_NAMES, 0.0))
            runs[p.key] = RunResult(p.key, p.radius, None, p.seed, res, errors, 1.0, 1.0)
            continue
        try:
            errors.update(shape_errors(res, refs.get(p.seed, first_ref)))
        except ValueError as e:
            failed[p.key] = f"not comparable: {e}"
            continue
        runs[p.key] = RunResult(p.key, p.radius, p.rule, p.seed, res, errors,
                                ref_wall / res.scalars["wall_time"],
                                p.radius / spec.reference.radius)
        variants.setdefault((p.radius, p.rule.name), []).append(values)
    table = [r.row() for r in runs.values()]
    groups = _groups(spec, runs, names)
    noise, verdicts = judge_groups(spec, ref_values, variants, names)
    keys_of: dict[tuple, list[str]] = {}
    for p in planned:
        if not p.is_reference:
            keys_of.setdefault((p.radius, p.rule.name), []).append(p.key)
    for v in verdicts:
        g = next(g for g in groups if g["radius"] == v["radius"] and g["rule"] == v["rule"])
        v.update(speedup=g["speedup"], thickness_diameters=g["thickness_diameters"],
                 height_diameters=g["height_diameters"])
    if spec.reference.unconfined:
        _note_failure_kinds(refs, runs, verdicts)
    judged = {(v["radius"], v["rule"]) for v in verdicts}
    for variant, keys in keys_of.items():
        lost = {k: failed[k] for k in keys if k in failed}
        if variant not in judged:
            verdicts.append({"radius": variant[0], "rule": variant[1], "verdict": "undecided",
                             "reason": "no run of this variant finished", "seeds": 0,
                             "metrics": []})
        if lost:
            v = next(v for v in verdicts if (v["radius"], v["rule"]) == variant)
            v["missing_runs"] = lost
            v["reason"] += "; missing: " + "; ".join(f"{k} ({t})" for k, t in lost.items())
    ref_strength = None
    if spec.reference.unconfined:
        ref_strength = float(np.mean([r.scalars["unconfined_strength"] for r in refs.values()]))
    advisor = advise(spec, groups, verdicts, ref_strength)
    advisor["noise_floor"] = noise
    advisor["reference"] = _reference_summary(refs, names, ref_values)
    return StudyResult(spec, runs, table, groups, advisor, failed)


def _note_failure_kinds(refs: dict, runs: dict[str, RunResult], verdicts: list[dict]) -> None:
    """Say so in a verdict when the reference fails (peak strength) but the variant hardens
    (fallback strength), or the other way round: the strengths are then of different kinds."""
    def fails(results) -> bool:
        flags = [r.scalars["unconfined_failure"] for r in results]
        return bool(flags) and sum(flags) >= len(flags) / 2

    ref_fails = fails(refs.values())
    for v in verdicts:
        members = [r.result for r in runs.values() if r.rule is not None
                   and r.rule.name == v["rule"] and r.radius == v["radius"]]
        if members and fails(members) != ref_fails:
            kinds = ("fails at a peak", "hardens without failing")
            v["reason"] += (f"; the reference {kinds[0] if ref_fails else kinds[1]} but this "
                            f"variant {kinds[1] if ref_fails else kinds[0]}: the strengths "
                            "compared are of different kinds (peak against fallback)")


def _reference_summary(refs: dict, names, ref_values: list[dict]) -> dict:
    """Mean and spread over reference seeds of the scalars a user quotes."""
    out = {"seeds": sorted(refs)}
    for k in ("unconfined_strength", "unconfined_failure", "loading_stiffness",
              "unloading_stiffness", "consolidated_porosity", "consolidated_porosity_interior",
              "wall_time", "particles"):
        v = [r.scalars[k] for r in refs.values() if k in r.scalars]
        if v:
            out[k] = float(np.mean(v))
            out[k + "_std"] = float(np.std(v, ddof=1)) if len(v) > 1 else 0.0
    return out


def _groups(spec: StudySpec, runs: dict[str, RunResult], names) -> list[dict]:
    """Mean and spread (sample standard deviation; 0 with one seed) over seeds of the
    errors, wall time and speed-up of every (radius, rule) with at least one run."""
    out = []
    cols_err = [METRIC_COLUMNS[n] for n in names] + list(SHAPE_NAMES)
    for r in spec.coarse_radii:
        for rule in spec.rules:
            members = [x for x in runs.values() if x.rule == rule and x.radius == r]
            if not members:
                continue
            a, b, c = rule.exponents(spec.reference.pair_law)
            g = {"radius": r, "rule": rule.name, "scale": r / spec.reference.radius,
                 "stiffness_exponent": a, "adhesion_exponent": b, "adhesive_exponent": c,
                 "dt": rule.dt,
                 "seeds": len(members),
                 "thickness_diameters": members[0].result.scalars["thickness_diameters"]}
            cols = {n: [m.errors[n] for m in members] for n in cols_err}
            for k in ("wall_time", "height_diameters"):
                cols[k] = [m.result.scalars[k] for m in members]
            cols["speedup"] = [m.speedup for m in members]
            if spec.reference.unconfined:
                cols["unconfined_strength"] = [m.result.scalars["unconfined_strength"]
                                               for m in members]
            for n, v in cols.items():
                g[n] = float(np.mean(v))
                g[n + "_std"] = float(np.std(v, ddof=1)) if len(v) > 1 else 0.0
            out.append(g)
    return out
