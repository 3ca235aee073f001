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
import os
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from .adaptive import Addition, next_runs
from .advisor import advise, judge_groups
from .backend import check_backend
from .channel import task_progress
from .checkpoint import CHECKPOINT_INTERVAL, Checkpoint, check_interval
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

__all__ = [
    "NAMED_RULES",
    "TABLE_UNITS",
    "PlannedRun",
    "RunFailed",
    "RunResult",
    "ScalingRule",
    "StudyProgress",
    "StudyResult",
    "StudySpec",
    "default_study",
    "plan_runs",
    "run_key",
    "run_study",
]

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
            "run": self.key,
            "radius": self.radius,
            "rule": "reference" if self.rule is None else self.rule.name,
            "seed": self.seed,
            "scale": self.scale,
            "particles": int(s["particles"]),
            "steps": int(s["steps"]),
            "dt": s["dt"],
            "wall_time": s["wall_time"],
            "particle_steps": s["particle_steps"],
            "speedup": self.speedup,
            "thickness_diameters": s["thickness_diameters"],
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
        return {
            "table": self.table,
            "groups": self.groups,
            "advisor": self.advisor,
            "failed": self.failed,
            "units": TABLE_UNITS,
        }

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


def _execute(
    test,
    threads: int | None = None,
    key: str = "",
    channel=None,
    checkpoint: Checkpoint | None = None,
    limit: tuple | None = None,
    backend: str | None = None,
) -> UniaxialResult:
    """One run as a task (a picklable top-level function for process and cluster pools);
    with a ``channel`` (:mod:`engine.channel`) it reports its progress there and stops with
    :class:`engine.StopRequested` when the study asks it to."""
    if threads is not None:
        import numba

        numba.set_num_threads(max(1, min(threads, numba.config.NUMBA_NUM_THREADS)))
    if channel is not None and channel.stop_requested():
        raise StopRequested(f"run {key} not started: the study was stopped")
    return run_uniaxial(
        test,
        progress=None if channel is None else task_progress(channel, key),
        checkpoint=checkpoint,
        backend=backend,
        **_limit_args(limit),
    )


def _limit_args(limit: tuple | None) -> dict:
    """run_uniaxial's arguments for a (max_wall_time, setting name) pair."""
    if limit is None or limit[0] is None:
        return {}
    return {"max_wall_time": limit[0], "wall_time_setting": limit[1]}


def _weights(planned: list[PlannedRun]) -> np.ndarray:
    cost = np.array([estimated_steps(p.test) * p.test.n_particles for p in planned])
    return cost / cost.sum()


def run_study(
    spec: StudySpec,
    progress: StudyCallback | None = None,
    executor: cf.Executor | None = None,
    *,
    completed: dict | None = None,
    on_run: RunCallback | None = None,
    task_threads: int | None = 1,
    channel=None,
    poll_interval: float = 1.0,
    checkpoints: str | os.PathLike | None = None,
    checkpoint_interval: float = CHECKPOINT_INTERVAL,
    max_run_wall_time: float | None = None,
    wall_time_setting: str = "max_run_wall_time",
    backend: str | None = None,
) -> StudyResult:
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
        checkpoints: a folder (shared with the executor's processes or hosts) where each
            run in flight keeps its :class:`engine.Checkpoint` ``<key>.ckpt``, written every
            ``checkpoint_interval`` seconds of wall time [s]; a run started again (the study
            resumed after a crash) goes on from its checkpoint, bit-identically. A run's
            checkpoint is removed once ``on_run`` has returned (its outcome is stored).
        max_run_wall_time: a run that goes on longer than this [s] of wall time fails with
            :class:`engine.WallTimeExceeded` (in this process and on any executor; the study
            goes on with the others); ``wall_time_setting`` names the limit in the message.
        backend: where each run runs, ``"cpu"``, ``"cuda"`` or ``"auto"`` (see
            :class:`engine.Simulation`; on an executor, decided where the task runs); None:
            ``DEMSCALE_BACKEND`` there, else the CPU.

    Raises: :class:`RunFailed` as soon as every reference run has failed; ``ValueError``
    at once, before any run starts, for a ``ProcessPoolExecutor`` that forks
    (:func:`check_executor`).
    """
    check_executor(executor)
    if max_run_wall_time is not None:
        check_interval(max_run_wall_time, "run_study.max_run_wall_time")
    limit = (max_run_wall_time, wall_time_setting)
    backend = check_backend(backend, "run_study.backend")
    planned = spec.planned_runs()
    weights = _weights(planned)
    outcomes: dict[str, UniaxialResult | str] = dict(completed or {})
    progress = _monotone_progress(progress)

    refs = [q.key for q in planned if q.is_reference]

    if checkpoints is not None:
        check_interval(checkpoint_interval, "run_study.checkpoint_interval")

    def checkpoint(p: PlannedRun) -> Checkpoint | None:
        if checkpoints is None:
            return None
        return Checkpoint(Path(checkpoints) / f"{p.key}.ckpt", checkpoint_interval)

    def record(p: PlannedRun, outcome) -> None:
        outcomes[p.key] = outcome
        if on_run is not None:
            on_run(p.key, outcome)
        if checkpoints is not None:  # stored: the run is never resumed again
            checkpoint(p).remove()
        if p.is_reference and all(isinstance(outcomes.get(k), str) for k in refs):
            # every reference failed: nothing can be compared, stop at once
            raise RunFailed(refs[0], outcomes[refs[0]])

    if executor is not None and channel is not None:
        channel.reset()

    def run(todo: list[int]) -> None:
        if executor is None:
            _run_here(
                planned, todo, weights, outcomes, progress, record, checkpoint, limit, backend
            )
        else:
            _run_on(
                executor,
                planned,
                todo,
                weights,
                outcomes,
                progress,
                record,
                task_threads,
                channel,
                poll_interval,
                checkpoint,
                limit,
                backend,
            )

    while True:
        planned, added, stopped = plan_runs(spec, outcomes)
        weights = _weights(planned)
        todo = [i for i, p in enumerate(planned) if p.key not in outcomes]
        if not todo:
            break
        run(todo)
    planned, added, stopped = plan_runs(spec, outcomes)
    result = assemble(spec, planned, outcomes)
    if spec.decide:
        result.advisor["adaptive"] = _adaptive_summary(spec, planned, added, stopped)
    return result


def plan_runs(spec: StudySpec, outcomes: dict) -> tuple[list[PlannedRun], list[dict], str | None]:
    """Every run of ``spec`` given the ``outcomes`` so far: the planned runs, then, with
    ``decide``, the runs each round adds (engine.adaptive), replayed from the outcomes round
    by round (deterministic: a resumed study, or a report from stored runs, finds the same
    runs). Returns (runs, the added runs as {run, round, kind, reason}, why the study stopped
    adding: None while some run of the last round is still to run)."""
    planned = spec.planned_runs()
    added: list[dict] = []
    if not spec.decide:
        return planned, added, None
    spent = 0.0
    for round_no in range(1, spec.rounds + 1):
        if any(p.key not in outcomes for p in planned):
            return planned, added, None
        new = _added_runs(spec, planned, outcomes, round_no, spent)
        if not new:
            return (
                planned,
                added,
                _stop_reason(
                    spec,
                    planned,
                    outcomes,
                    "no undecided verdict can be decided within the seed "
                    "caps and budget (each reason says how many seeds it would need)",
                ),
            )
        for p, a in new:
            planned.append(p)
            spent += estimated_steps(p.test) * p.test.n_particles
            added.append({"run": p.key, "round": a.round, "kind": a.kind, "reason": a.reason})
    if any(p.key not in outcomes for p in planned):
        return planned, added, None
    return planned, added, _stop_reason(spec, planned, outcomes, f"all {spec.rounds} rounds run")


def _stop_reason(spec, planned, outcomes, otherwise: str) -> str:
    names, ref_values, variants = _judged_values(spec, planned, outcomes)
    if not ref_values:
        return "no reference run finished"
    _, verdicts = judge_groups(spec, ref_values, variants, names, looks=spec.looks)
    return (
        otherwise
        if any(v["verdict"] == "undecided" for v in verdicts)
        else ("every verdict decided")
    )


def _adaptive_summary(
    spec: StudySpec, planned: list[PlannedRun], added: list[dict], stopped: str | None
) -> dict:
    keys = {a["run"] for a in added}
    return {
        "planned_runs": len(planned) - len(added),
        "added_runs": added,
        "looks": spec.looks,
        "stopped": stopped,
        "budget": spec.budget,
        "added_particle_steps": float(
            sum(estimated_steps(p.test) * p.test.n_particles for p in planned if p.key in keys)
        ),
    }


def _monotone_progress(progress: StudyCallback | None) -> StudyCallback | None:
    """The callback with a fraction that never goes backwards (runs of other processes
    report out of order, and an adaptive study's added runs enlarge the whole)."""
    if progress is None:
        return None
    last = [0.0]

    def call(report: StudyProgress):
        last[0] = max(last[0], report.fraction)
        if report.fraction < last[0]:
            report = replace(report, fraction=last[0])
        return progress(report)

    return call


def _judged_values(spec: StudySpec, planned: list[PlannedRun], outcomes: dict):
    """Metric values of the finished references and of every variant's finished seeds that
    :func:`assemble` judges (a run whose curves cannot be compared is left out there too)."""
    names = metric_names(spec.reference.unconfined)
    ok = [p for p in planned if p.key in outcomes and not isinstance(outcomes[p.key], str)]
    refs = {p.seed: outcomes[p.key] for p in ok if p.is_reference}
    ref_values = [metric_values(r) for r in refs.values()]
    variants: dict[tuple, list[dict]] = {}
    for p in ok:
        if p.is_reference:
            continue
        res = outcomes[p.key]
        try:
            shape_errors(res, refs.get(p.seed, next(iter(refs.values()))))
        except (ValueError, StopIteration):
            continue
        variants.setdefault((p.radius, p.rule.name), []).append(metric_values(res))
    return names, ref_values, variants


def _added_runs(
    spec: StudySpec, planned: list[PlannedRun], outcomes: dict, round_no: int, spent: float
) -> list[tuple[PlannedRun, Addition]]:
    """The runs round ``round_no`` adds (engine.adaptive), as planned runs with new seeds."""
    names, ref_values, variants = _judged_values(spec, planned, outcomes)
    if not ref_values:
        return []
    _, verdicts = judge_groups(spec, ref_values, variants, names, looks=spec.looks)
    cost = {}
    for p in planned:
        k = "reference" if p.is_reference else (p.radius, p.rule.name)
        cost.setdefault(k, estimated_steps(p.test) * p.test.n_particles)
    budget_left = None if spec.budget is None else spec.budget - spent
    attempted: dict = {}
    for p in planned:
        k = "reference" if p.is_reference else (p.radius, p.rule.name)
        attempted[k] = attempted.get(k, 0) + 1
    adds = next_runs(spec, ref_values, variants, verdicts, cost, round_no, budget_left, attempted)
    dt_ref = spec.reference.resolved_dt()
    used: dict = {}
    for p in planned:
        used.setdefault(None if p.is_reference else (p.radius, p.rule.name), set()).add(p.seed)
    rules = {r.name: r for r in spec.rules}
    out = []
    for a in adds:
        seeds = used.setdefault(a.variant, set())
        seed = max(seeds | used.get(None, set())) + 1
        seeds.add(seed)
        ref = replace(spec.reference, seed=seed)
        if a.kind == "reference":
            out.append(
                (PlannedRun(run_key(ref.radius, None, seed), ref.radius, None, seed, ref), a)
            )
        else:
            radius, rule = a.variant[0], rules[a.variant[1]]
            out.append(
                (
                    PlannedRun(
                        run_key(radius, rule, seed),
                        radius,
                        rule,
                        seed,
                        rule.apply(ref, radius, dt_ref),
                    ),
                    a,
                )
            )
    return out


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
            "multiprocessing.get_context('spawn'))"
        )


def _done_weight(planned, weights, outcomes) -> float:
    """The share of the study's estimated cost already done (runs with an outcome)."""
    return float(sum(w for p, w in zip(planned, weights) if p.key in outcomes))


def _run_here(
    planned, todo, weights, outcomes, progress, record, checkpoint, limit, backend=None
) -> None:
    done_weight = _done_weight(planned, weights, outcomes)
    for i in todo:
        p = planned[i]

        def report(pr: Progress, i=i, p=p, base=done_weight):
            if progress is None:
                return None
            frac = base + weights[i] * pr.fraction
            return progress(
                StudyProgress(
                    float(min(frac, 1.0)), i, len(planned), p.key, pr.stage, pr.time, pr.message
                )
            )

        # a first report names the run before its packing and kernels are built, so a run
        # that fails there is not blamed on the previous one
        if report(Progress(0.0, "setup", 0.0, 0.0, 0, "building the packing")) is False:
            raise StopRequested(f"stopped by the progress callback before run {p.key}")
        try:
            outcome = run_uniaxial(
                p.test,
                progress=report,
                checkpoint=checkpoint(p),
                backend=backend,
                **_limit_args(limit),
            )
        except StopRequested:
            raise
        except Exception as e:
            outcome = f"{type(e).__name__}: {e}"
        record(p, outcome)
        done_weight += weights[i]


def _run_on(
    executor,
    planned,
    todo,
    weights,
    outcomes,
    progress,
    record,
    threads,
    channel,
    poll_interval,
    checkpoint,
    limit,
    backend=None,
) -> None:
    # in planned order: the references first (the longest runs, needed by every comparison)
    futures = {
        executor.submit(
            _execute,
            planned[i].test,
            threads,
            planned[i].key,
            channel,
            checkpoint(planned[i]),
            limit,
            backend,
        ): i
        for i in todo
    }
    done_weight = _done_weight(planned, weights, outcomes)
    pending = set(futures)

    def ask(report: StudyProgress) -> None:
        if progress is not None and progress(report) is False:
            if channel is not None:
                channel.request_stop()  # running tasks stop at their next report
            raise StopRequested(f"stopped by the progress callback during run {report.run_key}")

    try:
        while pending:
            done, pending = cf.wait(
                pending, timeout=poll_interval if channel else None, return_when=cf.FIRST_COMPLETED
            )
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
                ask(
                    StudyProgress(
                        float(min(done_weight, 1.0)),
                        i,
                        len(planned),
                        p.key,
                        "done",
                        0.0,
                        "run finished" if not isinstance(outcome, str) else outcome,
                    )
                )
            if channel is not None and pending and not done:
                _report_running(
                    channel, planned, weights, [futures[f] for f in pending], done_weight, ask
                )
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
    ask(
        StudyProgress(
            float(min(frac, 1.0)),
            i,
            len(planned),
            planned[i].key,
            r["stage"],
            float(r["time"]),
            f"{len(running)} runs in progress",
        )
    )


def assemble(spec: StudySpec, planned: list[PlannedRun], outcomes: dict) -> StudyResult:
    """Errors, groups, noise floor, verdicts and advisor from the runs' outcomes (key ->
    :class:`UniaxialResult` or error text). Recomputable at any time from stored runs."""
    failed = {p.key: outcomes[p.key] for p in planned if isinstance(outcomes.get(p.key), str)}
    missing = [p.key for p in planned if p.key not in outcomes]
    for k in missing:
        failed[k] = "not run"
    refs = {
        p.seed: outcomes[p.key]
        for p in planned
        if p.is_reference and p.key in outcomes and not isinstance(outcomes[p.key], str)
    }
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
        errors = {
            METRIC_COLUMNS[n]: (
                0.0 if p.is_reference else relative_error(n, values[n], floor_mean[n], cons)
            )
            for n in names
        }
        if p.is_reference:
            errors.update(dict.fromkeys(SHAPE_NAMES, 0.0))
            runs[p.key] = RunResult(p.key, p.radius, None, p.seed, res, errors, 1.0, 1.0)
            continue
        try:
            errors.update(shape_errors(res, refs.get(p.seed, first_ref)))
        except ValueError as e:
            failed[p.key] = f"not comparable: {e}"
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
        )
        variants.setdefault((p.radius, p.rule.name), []).append(values)
    table = [r.row() for r in runs.values()]
    groups = _groups(spec, runs, names)
    noise, verdicts = judge_groups(spec, ref_values, variants, names, looks=spec.looks)
    keys_of: dict[tuple, list[str]] = {}
    for p in planned:
        if not p.is_reference:
            keys_of.setdefault((p.radius, p.rule.name), []).append(p.key)
    for v in verdicts:
        g = next(g for g in groups if g["radius"] == v["radius"] and g["rule"] == v["rule"])
        v.update(
            speedup=g["speedup"],
            thickness_diameters=g["thickness_diameters"],
            height_diameters=g["height_diameters"],
        )
    if spec.reference.unconfined:
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
    if spec.reference.unconfined:
        ref_strength = float(np.mean([r.scalars["unconfined_strength"] for r in refs.values()]))
    advisor = advise(spec, groups, verdicts, ref_strength)
    advisor["noise_floor"] = noise
    advisor["reference"] = _reference_summary(refs, names, ref_values)
    return StudyResult(spec, runs, table, groups, advisor, failed)


def _note_failure_kinds(refs: dict, runs: dict[str, RunResult], verdicts: list[dict]) -> None:
    """Name the kinds of strength a verdict compares whenever they are mixed: how many of the
    references and of the variant's runs failed at a peak (engine.uniaxial.failed_by_curve)
    and how many hardened (their strength is the largest stress up to the strain limit)."""
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
                f"; strength compares mixed kinds: {sum(ref_flags)} of "
                f"{len(ref_flags)} references and {sum(flags)} of {len(flags)} "
                "runs of this variant failed at a peak, the others hardened to "
                "the strain limit (their strength is the largest stress reached)"
            )


def _reference_summary(refs: dict, names, ref_values: list[dict]) -> dict:
    """Mean and spread over reference seeds of the scalars a user quotes."""
    out = {"seeds": sorted(refs)}
    for k in (
        "unconfined_strength",
        "unconfined_failure",
        "loading_stiffness",
        "unloading_stiffness",
        "consolidated_porosity",
        "consolidated_porosity_interior",
        "wall_time",
        "particles",
    ):
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
            if spec.reference.unconfined:
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
