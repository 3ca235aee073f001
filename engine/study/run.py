"""Running a scaling study: every run of a :class:`StudySpec`, in this process or as tasks on
any :class:`concurrent.futures.Executor`, then errors, noise floor and verdicts
(docs/PHYSICS.md sections 5 and 7).

The spec is in :mod:`engine.study.spec`, its runs in :mod:`engine.study.plan`, the metrics in
:mod:`engine.study.metrics`, the verdict logic in :mod:`engine.study.judge`, the report in
:mod:`engine.study.report` (built by :mod:`engine.study.advice`). Runs are
independent: a coarse run's time step is known before its reference runs, so all runs can go
side by side; the comparison is made when they are all done. A failed coarse run is recorded
with its error while the others go on; ``on_run`` hears of every finished run at once (to
store it), and ``completed`` hands back stored runs so that a resumed study runs only what is
missing."""

from __future__ import annotations

import concurrent.futures as cf
import os
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

from ..core.errors import ParameterError, StopRequested
from ..simulation.backend import check_backend
from ..uniaxial.checkpoint import CHECKPOINT_INTERVAL, Checkpoint, check_interval
from ..uniaxial.results import Progress, UniaxialResult
from .channel import task_progress, wait_tasks
from .kinds import kind_of
from .loop import StudyLoop
from .plan import PlannedRun, StudyPlan, as_plan
from .results import RunFailed, StudyResult
from .spec import StudySpec

#: The ``stage`` of the report that announces the runs a ``decide`` round has added (its
#: ``message`` names them), made before any of them runs.
ADDED = "added"


@dataclass(frozen=True)
class StudyProgress:
    """What a study progress callback receives: overall ``fraction`` in [0, 1], the run
    (``run_index`` of ``n_runs``, ``run_key``), its ``stage`` and simulated ``time`` [s].

    ``fraction`` is the share of the study's work done (its runs' estimated particle-steps)
    and never goes back: a ``decide`` study counts the most its later rounds may add as
    work still to do (:func:`engine.study.stopping.most_added`), so a round's added runs take
    their share from that reserve, and whatever a round does not add is a step forward.
    ``runs_done`` runs have an outcome (finished or failed) of the ``n_runs`` known so far,
    ``added`` of which a ``decide`` study has added; ``run_fraction`` is the run's own
    fraction (None in a report on the study as a whole). A round's runs are announced by a
    report with ``stage`` :data:`ADDED` before any of them runs (its ``message`` names
    them, ``run_key`` the first)."""

    fraction: float
    run_index: int
    n_runs: int
    run_key: str
    stage: str
    time: float
    message: str = ""
    runs_done: int | None = None
    added: int = 0
    run_fraction: float | None = None


class Eta:
    """Seconds a job (a study, a calibration) has left, from its progress fraction: the
    mean rate since the first fraction it was given, (1 - f) (t - t0) / (f - f0), once the
    fraction has moved :attr:`min_fraction` and :attr:`min_seconds` have passed (None
    before: no rate yet). A study's fraction is a share of its estimated particle-steps
    (StudyProgress), so this is its remaining work at the rate measured so far (the first
    run's kernel compilation counted in). ``clock``: seconds, monotonic."""

    min_fraction = 0.005
    min_seconds = 5.0

    def __init__(self, clock: Callable[[], float] | None = None):
        import time

        self.clock = clock or time.monotonic
        self.start: tuple[float, float] | None = None

    def __call__(self, fraction: float) -> float | None:
        """The seconds left at ``fraction`` (None while unknown)."""
        now = self.clock()
        if self.start is None:
            self.start = (now, fraction)
            return None
        t0, f0 = self.start
        if fraction >= 1.0:
            return 0.0
        moved, waited = fraction - f0, now - t0
        if moved < self.min_fraction or waited < self.min_seconds:
            return None
        return (1.0 - fraction) * waited / moved


def duration_words(seconds: float | None) -> str:
    """A duration as a person reads it: "45 s", "3 min 20 s", "1 h 05 min"; "-" for None."""
    if seconds is None:
        return "-"
    s = max(0, round(seconds))
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60:02d} s"
    return f"{s // 3600} h {s % 3600 // 60:02d} min"


StudyCallback = Callable[[StudyProgress], object]
RunCallback = Callable[[str, "UniaxialResult | str"], object]


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
    with a ``channel`` (:mod:`engine.study.channel`) it reports its progress there and stops with
    :class:`engine.StopRequested` when the study asks it to."""
    if threads is not None:
        import numba

        numba.set_num_threads(max(1, min(threads, numba.config.NUMBA_NUM_THREADS)))
    if channel is not None and channel.stop_requested():
        raise StopRequested(f"run {key} not started: the study was stopped")
    return run_test(
        test,
        None if channel is None else task_progress(channel, key),
        checkpoint,
        backend,
        limit,
    )


def run_test(test, progress=None, checkpoint=None, backend=None, limit=None):
    """One run of a study's test by its kind's run (:mod:`engine.study.kinds`: the uniaxial
    test's :func:`engine.run_uniaxial` with its ``checkpoint``, ``backend`` and wall-time
    ``limit``; the shear test's :func:`engine.run_shear` on the CPU with its ``checkpoint``,
    which honours neither of the others: :func:`check_kind_options` refuses them before any
    run starts)."""
    kind = kind_of(test)
    return kind.run(
        test,
        progress=progress,
        checkpoint=checkpoint if kind.checkpoints else None,
        backend=backend,
        **_limit_args(limit),
    )


def check_kind_options(spec: StudySpec, options: RunOptions) -> None:
    """The options a study's reference kind does not honour (:mod:`engine.study.kinds`: a
    wall-time limit, a backend): :class:`engine.ParameterError` naming the option, before
    any run starts."""
    kind = kind_of(spec.reference)
    if options.max_run_wall_time is not None and not kind.wall_time_limit:
        raise ParameterError(
            "RunOptions.max_run_wall_time",
            options.max_run_wall_time,
            f"None for a {kind.name} study (its run has no wall-time limit)",
        )
    if kind.backends is not None and options.backend not in (None, *kind.backends):
        raise ParameterError(
            "RunOptions.backend",
            options.backend,
            f"one of {', '.join(repr(b) for b in kind.backends)} for a {kind.name} study",
        )


def _limit_args(limit: tuple | None) -> dict:
    """run_uniaxial's arguments for a (max_wall_time, setting name) pair."""
    if limit is None or limit[0] is None:
        return {}
    return {"max_wall_time": limit[0], "wall_time_setting": limit[1]}


@dataclass(frozen=True)
class RunOptions:
    """How a study's runs are run, not what they are: one record that studies, the service
    and any other loop over uniaxial runs share (:func:`run_study`'s ``options``).

    Attributes:
        executor: None runs the runs one after another here; any
            :class:`concurrent.futures.Executor` (a ``ProcessPoolExecutor`` with the
            "spawn" or "forkserver" context, ``distributed.Client(...).get_executor()``)
            runs them as tasks. Results are bit-identical either way.
        task_threads: engine threads per task on an executor (1: one core per task).
        channel: with an executor, how tasks in other processes or hosts report progress
            and hear a stop request (:class:`engine.FileChannel`); reset when the study
            starts.
        poll_interval: seconds between two reads of the ``channel`` [s].
        checkpoints: a folder (shared with the executor's processes or hosts) where each
            run in flight keeps its :class:`engine.Checkpoint` ``<key>.ckpt``, written every
            ``checkpoint_interval`` seconds of wall time [s]; a run started again (the study
            resumed after a crash) goes on from its checkpoint, bit-identically. A run's
            checkpoint is removed once its outcome is stored (``on_run`` has returned).
        max_run_wall_time: a run that goes on longer than this [s] of wall time fails with
            :class:`engine.WallTimeExceeded` (in this process and on any executor; the study
            goes on with the others); ``wall_time_setting`` names the limit in the message.
        backend: where each run runs, ``"cpu"``, ``"cuda"`` or ``"auto"`` (see
            :class:`engine.Simulation`; on an executor, decided where the task runs); None:
            ``DEMSCALE_BACKEND`` there, else the CPU.

    Checked when made: :class:`engine.ParameterError` naming the field for a wall time or
    interval that is not > 0 s or an unknown backend; ``ValueError`` for a
    ``ProcessPoolExecutor`` that forks (:func:`check_executor`)."""

    executor: cf.Executor | None = None
    task_threads: int | None = 1
    channel: object = None
    poll_interval: float = 1.0
    checkpoints: str | os.PathLike | None = None
    checkpoint_interval: float = CHECKPOINT_INTERVAL
    max_run_wall_time: float | None = None
    wall_time_setting: str = "max_run_wall_time"
    backend: str | None = None

    def __post_init__(self) -> None:
        check_executor(self.executor)
        if self.max_run_wall_time is not None:
            check_interval(self.max_run_wall_time, "RunOptions.max_run_wall_time")
        if self.checkpoints is not None:
            check_interval(self.checkpoint_interval, "RunOptions.checkpoint_interval")
        check_interval(self.poll_interval, "RunOptions.poll_interval")
        object.__setattr__(self, "backend", check_backend(self.backend, "RunOptions.backend"))


def run_study(
    study: StudySpec | StudyPlan,
    progress: StudyCallback | None = None,
    executor: cf.Executor | None = None,
    *,
    completed: dict | None = None,
    on_run: RunCallback | None = None,
    options: RunOptions | None = None,
    decided: list[dict] | None = None,
    **how,
) -> StudyResult:
    """Run every run of ``study`` that is not in ``completed``, then judge the study.

    Args:
        study: the study: its spec (planned here, once: :func:`engine.plan`) or its plan.
        progress: receives :class:`StudyProgress` (in this process, within each run; with
            an executor, as runs finish, and with a ``channel`` also every
            ``poll_interval`` seconds from the running tasks, the fraction summed over the
            runs); returning ``False`` stops the study with :class:`engine.StopRequested`
            (with an executor, runs not yet started are cancelled; running ones stop at
            their next report through the ``channel``, or are left to finish without one).
        executor: shorthand for ``options.executor``.
        completed: key -> :class:`UniaxialResult` (or an error text for a failed run) of
            runs already done, e.g. read back from storage when a study resumes.
        on_run: called with (key, UniaxialResult or error text) as soon as a run ends;
            where it takes a keyword ``added``, also with the additions of the round that
            added the run (``[{run, round, kind, reason}, ...]``, the run's own among them;
            None for a planned run), to store with it (:func:`engine.io.store.save_run`).
        decided: the added runs a store holds (:func:`engine.io.store.stored_additions`),
            taken as their rounds' decisions (:class:`engine.study.loop.StudyLoop`).
        options: how the runs are run (:class:`RunOptions`); ``how``: any of its fields as
            keywords, on top of ``options`` (``run_study(spec, checkpoints="ckpt")``).

    Raises: :class:`RunFailed` as soon as every reference run has failed; what
    :class:`RunOptions` raises, at once, before any run starts (a ``TypeError`` names a
    keyword that is not one of its fields).
    """
    options = options if options is not None else RunOptions()
    unknown = sorted(set(how) - set(RunOptions.__dataclass_fields__))
    if unknown:
        raise TypeError(f"run_study() got unexpected keyword argument(s): {', '.join(unknown)}")
    if executor is not None:
        how["executor"] = executor
    if how:
        options = replace(options, **how)
    executor, task_threads, channel = options.executor, options.task_threads, options.channel
    poll_interval, checkpoints = options.poll_interval, options.checkpoints
    checkpoint_interval, backend = options.checkpoint_interval, options.backend
    limit = (options.max_run_wall_time, options.wall_time_setting)
    check_kind_options(study.spec if isinstance(study, StudyPlan) else study, options)
    study = as_plan(study)  # planned once, the options found runnable first
    loop = StudyLoop(study, dict(completed or {}), decided)
    outcomes = loop.outcomes
    progress = _monotone_progress(progress)
    tell_added = on_run is not None and _takes_added(on_run)

    refs = [q.key for q in study.runs if q.is_reference]

    def checkpoint(p: PlannedRun) -> Checkpoint | None:
        if checkpoints is None:
            return None
        return Checkpoint(Path(checkpoints) / f"{p.key}.ckpt", checkpoint_interval)

    def record(p: PlannedRun, outcome) -> None:
        loop.tell(p.key, outcome)
        if tell_added:
            on_run(p.key, outcome, added=loop.round_of(p.key))
        elif on_run is not None:
            on_run(p.key, outcome)
        if checkpoints is not None:  # stored: the run is never resumed again
            checkpoint(p).remove()
        if p.is_reference and all(isinstance(outcomes.get(k), str) for k in refs):
            # every reference failed: nothing can be compared, stop at once
            raise RunFailed(refs[0], outcomes[refs[0]])

    if executor is not None and channel is not None:
        channel.reset()

    def run(todo: list[int], tally: _Tally) -> None:
        if executor is None:
            _run_here(tally, todo, progress, record, checkpoint, limit, backend)
        else:
            _run_on(
                executor,
                tally,
                todo,
                progress,
                record,
                task_threads,
                channel,
                poll_interval,
                checkpoint,
                limit,
                backend,
            )

    announced = 0
    # ask / tell: each ask returns the runs still to run, with a decide study's next round
    # planned (by the allocator) once the runs it is planned from have finished
    while asked := {p.key for p in loop.ask()}:
        planned = loop.planned
        todo = [i for i, p in enumerate(planned) if p.key in asked]
        # the work still to come counts in: the fraction never goes back (StudyProgress)
        tally = _Tally(planned, loop.weights(), outcomes, len(loop.added))
        if len(loop.added) > announced:
            _announce(tally, loop.added[announced:], progress)
            announced = len(loop.added)
        run(todo, tally)
    return loop.result()


def _takes_added(callback) -> bool:
    """Whether ``on_run`` names a parameter ``added`` (the round of an added run); a
    callback of ``(key, outcome)`` alone, or one that passes ``**kwargs`` on, is called as
    before."""
    import inspect

    try:
        params = inspect.signature(callback).parameters
    except (TypeError, ValueError):  # a builtin without a signature (dict.__setitem__)
        return False
    return "added" in params


def _monotone_progress(progress: StudyCallback | None) -> StudyCallback | None:
    """The callback with a fraction that never goes backwards: runs of other processes
    report out of order, and a ``decide`` round that adds more than its reserve (a budget
    overrun by an estimate) would lower it; the fraction shown is held instead."""
    if progress is None:
        return None
    last = [0.0]

    def call(report: StudyProgress):
        if report.fraction < last[0]:
            report = replace(report, fraction=last[0])
        last[0] = report.fraction
        return progress(report)

    return call


@dataclass
class _Tally:
    """A pass's runs (``planned``, each with its share ``weights`` of the study's work) and
    the ``outcomes`` so far; ``added``: how many of them a ``decide`` study added."""

    planned: list
    weights: object
    outcomes: dict
    added: int

    def done_weight(self) -> float:
        """The share of the study's work already done (runs with an outcome)."""
        return _done_weight(self.planned, self.weights, self.outcomes)

    def report(self, fraction, i, stage, time, message="", run_fraction=None) -> StudyProgress:
        return StudyProgress(
            float(min(fraction, 1.0)),
            i,
            len(self.planned),
            self.planned[i].key,
            stage,
            time,
            message,
            sum(1 for p in self.planned if p.key in self.outcomes),
            self.added,
            run_fraction,
        )


def _announce(tally: _Tally, new: list[dict], progress) -> None:
    """The :data:`ADDED` report of the runs a round has just added (``new``, as
    :attr:`engine.study.loop.StudyLoop.added` lists them), before any of them runs."""
    if progress is None:
        return
    keys = [a["run"] for a in new]
    i = next(i for i, p in enumerate(tally.planned) if p.key == keys[0])
    rounds = sorted({a["round"] for a in new})
    which = ", ".join(str(r) for r in rounds)
    message = (
        f"round {which} adds {len(keys)} run{'s' if len(keys) > 1 else ''} until decided: "
        + ", ".join(keys)
    )
    if progress(tally.report(tally.done_weight(), i, ADDED, 0.0, message)) is False:
        raise StopRequested(f"stopped by the progress callback before run {keys[0]}")


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


def _run_here(tally, todo, progress, record, checkpoint, limit, backend=None) -> None:
    planned, weights = tally.planned, tally.weights
    done_weight = tally.done_weight()
    for i in todo:
        p = planned[i]

        def report(pr: Progress, i=i, base=done_weight):
            if progress is None:
                return None
            frac = base + weights[i] * pr.fraction
            return progress(tally.report(frac, i, pr.stage, pr.time, pr.message, pr.fraction))

        # a first report names the run before its packing and kernels are built, so a run
        # that fails there is not blamed on the previous one
        if report(Progress(0.0, "setup", 0.0, 0.0, 0, "building the packing")) is False:
            raise StopRequested(f"stopped by the progress callback before run {p.key}")
        try:
            outcome = run_test(p.test, report, checkpoint(p), backend, limit)
        except StopRequested:
            raise
        except Exception as e:
            outcome = f"{type(e).__name__}: {e}"
        record(p, outcome)
        done_weight += weights[i]


def _run_on(
    executor,
    tally,
    todo,
    progress,
    record,
    threads,
    channel,
    poll_interval,
    checkpoint,
    limit,
    backend=None,
) -> None:
    planned, weights = tally.planned, tally.weights
    # the longest first (by estimated work; planned order among equals: the references
    # lead the pilot): the last runs of a round are the short ones, so the cores idle least
    # at its end, where the next round waits for all of it
    todo = sorted(todo, key=lambda i: -weights[i])
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
    done_weight = tally.done_weight()

    def ask(report: StudyProgress) -> None:
        if progress is not None and progress(report) is False:
            if channel is not None:
                channel.request_stop()  # running tasks stop at their next report
            raise StopRequested(f"stopped by the progress callback during run {report.run_key}")

    def done(i: int, fut) -> None:
        nonlocal done_weight
        p = planned[i]
        try:
            outcome = fut.result()
        except (cf.CancelledError, StopRequested):
            return  # stopped, not failed: a resume runs it again
        except cf.BrokenExecutor:
            # the pool itself died (a worker process killed): an interruption, not a
            # failure of the run; finished runs were reported, a resume runs the rest
            raise
        except Exception as e:
            outcome = f"{type(e).__name__}: {e}"
        record(p, outcome)
        done_weight += weights[i]
        message = "run finished" if not isinstance(outcome, str) else outcome
        ask(tally.report(done_weight, i, "done", 0.0, message, 1.0))

    def running(reports) -> None:
        _report_running(tally, reports, done_weight, ask)

    wait_tasks(futures, [p.key for p in planned], channel, poll_interval, done, running)


def _report_running(tally, running, done_weight, ask) -> None:
    """One progress report of the ``running`` runs ((planned index, channel report) each):
    the study's fraction summed over the runs, named after the least advanced one."""
    weights = tally.weights
    frac = done_weight + sum(weights[i] * min(max(r["fraction"], 0.0), 1.0) for i, r in running)
    i, r = min(running, key=lambda ir: ir[1]["fraction"])
    message = f"{len(running)} runs in progress"
    ask(tally.report(frac, i, r["stage"], float(r["time"]), message, float(r["fraction"])))
