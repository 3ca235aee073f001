"""The one progress display of a study, for ``demscale study`` (from the engine's reports)
and ``demscale job`` (from the service's): the overall fraction of the planned and added
work, which only moves forward, the runs done of the runs known so far (added runs said
when they are added, before they run), the stage of the run in progress and the time left.

On a terminal it is a live rich bar; otherwise (a log, a pipe, CI) one line per event: a
run finished or failed, runs added, the status changed, and a line a minute while a long
run goes on. Both forms print the same words (:func:`line`). :class:`StudyBars` adds
``demscale study``'s bar per run, fed by the engine's progress reports."""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

from engine.study.run import duration_words

#: Seconds between two "still running" lines where the output is not a terminal.
QUIET_LINE_INTERVAL = 60.0


@dataclass(frozen=True)
class State:
    """What the display shows: ``fraction`` of the work done [-], ``runs_done`` of
    ``n_runs`` known (``added`` of them added by a ``decide`` study), the ``run`` in
    progress and its ``stage``, the seconds left (``eta``, None while unknown) and, for a
    job, its ``status``."""

    fraction: float = 0.0
    runs_done: int | None = None
    n_runs: int = 0
    added: int = 0
    run: str | None = None
    stage: str | None = None
    eta: float | None = None
    status: str | None = None


def runs_words(s: State) -> str:
    """ "3/21 runs done", "22/24 runs done (3 added)"."""
    if s.runs_done is None:
        return f"{s.n_runs} runs"
    added = f" ({s.added} added)" if s.added else ""
    return f"{s.runs_done}/{s.n_runs} runs done{added}"


def now_words(s: State) -> str:
    """The run in progress and its stage, "ref-s2: consolidation" (empty without one)."""
    if not s.run:
        return ""
    return f"{s.run}: {s.stage}" if s.stage else s.run


def finished(s: State) -> bool:
    """Whether every run known has its outcome, or the job has ended."""
    ended = s.status not in (None, "queued", "running")
    return ended or s.fraction >= 1.0 or (s.runs_done is not None and s.runs_done >= s.n_runs)


def eta_words(s: State) -> str:
    """ "ETA 3 min 20 s" (the time left at the rate so far), "ETA -" while unknown; empty
    once :func:`finished`."""
    return "" if finished(s) else f"ETA {duration_words(s.eta)}"


def line(s: State, event: str | None = None) -> str:
    """One line of the display: "[ 12.3 %] 3/21 runs done · ETA 9 min 40 s · ref-s1 done"
    (``event`` last; without one, the run in progress and its stage)."""
    parts = [f"[{100 * s.fraction:5.1f} %]"]
    if s.status is not None and s.status != "running":
        parts.append(s.status)
    parts.append(runs_words(s))
    if not finished(s):
        parts.append(eta_words(s))
    what = event if event is not None else now_words(s)
    text = f"{parts[0]} " + " · ".join(parts[1:])
    return f"{text} · {what}" if what else text


class StudyDisplay:
    """A study's progress on ``console`` (rich): a live bar on a terminal (``live`` None:
    whether the console is one), one line per event otherwise; nothing with ``quiet``.
    The fraction shown never goes back. ``progress`` is the rich Progress (its tasks are
    kept up to date whether it draws or not): callers may add a bar per run to it."""

    def __init__(
        self,
        console,
        live: bool | None = None,
        quiet: bool = False,
        title: str = "study",
        clock=time.monotonic,
    ):
        from rich.progress import (
            BarColumn,
            Progress,
            TaskProgressColumn,
            TextColumn,
            TimeElapsedColumn,
        )

        self.console = console
        self.quiet = quiet
        self.live = (console.is_terminal if live is None else live) and not quiet
        self.clock = clock
        self.state = State()
        self.last_line = -float("inf")
        self.progress = Progress(
            TextColumn("{task.description}"),
            BarColumn(),
            TaskProgressColumn(),
            TextColumn("{task.fields[stage]}"),
            TimeElapsedColumn(),
            TextColumn("{task.fields[eta]}"),
            console=console,
            disable=not self.live,
        )
        self.study = self.progress.add_task(f"[bold]{title}", total=1.0, stage="", eta="")

    def __enter__(self) -> StudyDisplay:
        self.progress.start()
        return self

    def __exit__(self, *exc) -> None:
        if exc[0] is None and self.state.status in (None, "succeeded"):
            # done: the bar full (the last report came before the last step)
            self._show(replace(self.state, fraction=1.0, eta=0.0))
        self.progress.stop()

    def _show(self, state: State) -> State:
        """``state`` with its fraction held at the largest shown so far."""
        state = replace(state, fraction=max(state.fraction, self.state.fraction))
        self.state = state
        stage = f"{runs_words(state)}  {now_words(state)}".rstrip()
        eta = eta_words(state)
        self.progress.update(self.study, completed=state.fraction, stage=stage, eta=eta)
        return state

    def update(self, state: State) -> None:
        """A report: the bar moves (live), or a line where the runs done, their number or
        the status changed, or a minute has passed since the last line."""
        before = self.state
        state = self._show(state)
        if self.live or self.quiet:
            return
        changed = (state.runs_done, state.n_runs, state.status) != (
            before.runs_done,
            before.n_runs,
            before.status,
        )
        if changed or self.clock() - self.last_line >= QUIET_LINE_INTERVAL:
            self._print(line(state))

    def event(self, state: State, text: str, style: str | None = None) -> None:
        """Something happened (a run finished, runs were added): said in one line, above
        the live bar or as a line of the log, with the progress it leaves."""
        state = self._show(state)
        if self.quiet:
            return
        if self.live:
            self.console.print(text, style=style, markup=False, highlight=False, soft_wrap=True)
        else:
            self._print(line(state, text), style)

    def _print(self, text: str, style: str | None = None) -> None:
        self.last_line = self.clock()
        self.console.print(text, style=style, markup=False, highlight=False, soft_wrap=True)


class StudyBars:
    """The progress display of ``demscale study`` (:class:`StudyDisplay`: its bar with
    the fraction of the planned and added work, the runs done, the stage and the time left
    on a terminal; a line per event otherwise; nothing but the runs' results when not
    ``enabled``) with a bar per run. ``update`` is the study's progress callback;
    ``finished`` hears of each run's outcome. ``live``: draw bars (None: on a terminal)."""

    def __init__(self, planned, console, enabled: bool = True, live: bool | None = None):
        from engine.study.plan import cost_weights
        from engine.study.run import Eta

        self.planned = planned
        self.console = console
        self.weights = [float(w) for w in cost_weights(planned)]
        self.bases = [sum(self.weights[:i]) for i in range(len(planned))]
        self.display = StudyDisplay(console, live=live, quiet=not enabled)
        self.progress = self.display.progress
        self.study = self.display.study
        self.eta = Eta()
        self.width = max(len(p.key) for p in planned)
        self.runs = {
            p.key: self.progress.add_task(
                f"  {p.key:<{self.width}} {p.test.n_particles:>6} particles",
                total=1.0,
                stage="waiting",
                eta="",
            )
            for p in planned
        }

    def _task(self, key: str):
        """The bar of run ``key``; a run a study added (``decide``) gets one when it starts."""
        if key not in self.runs:
            self.runs[key] = self.progress.add_task(
                f"  {key:<{self.width}} (added)", total=1.0, stage="waiting", eta=""
            )
        return self.runs[key]

    def __enter__(self) -> StudyBars:
        self.display.__enter__()
        return self

    def __exit__(self, *exc) -> None:
        self.display.__exit__(*exc)

    def update(self, p) -> None:
        """The study's progress callback (an :class:`engine.StudyProgress`)."""
        from engine.study.run import ADDED

        state = State(
            p.fraction,
            p.runs_done,
            p.n_runs,
            p.added,
            None if p.stage in (ADDED, "done") else p.run_key,
            p.stage,
            self.eta(p.fraction),
        )
        if p.stage == ADDED:  # a decide round's runs, said before any of them runs
            self.display.event(state, f"+ {p.message}")
            return
        self.display.update(state)
        if p.stage == "done":  # on an executor: a run has finished
            return
        i = p.run_index
        task = self._task(p.run_key)
        if p.run_fraction is not None:
            run_fraction = p.run_fraction
        elif i < len(self.planned) and self.planned[i].key == p.run_key:
            run_fraction = (p.fraction - self.bases[i]) / self.weights[i]
        else:  # an added run of a report without its own fraction: its stage only
            self.progress.update(task, stage=p.stage)
            return
        self.progress.update(task, completed=min(max(run_fraction, 0.0), 1.0), stage=p.stage)

    def finished(self, key: str, outcome) -> None:
        """A run ended with a :class:`engine.UniaxialResult` or an error text."""
        task = self._task(key)
        # the run has its outcome: one more done than the last report counted
        state = self.display.state
        state = replace(state, runs_done=(state.runs_done or 0) + 1, run=None)
        if isinstance(outcome, str):
            self.progress.update(task, stage="failed")
            self._say(state, f"{key} failed: {outcome}", "red")
            return
        s = outcome.scalars
        self.progress.update(task, completed=1.0, stage="done")
        strength = s.get("unconfined_strength")
        extra = f", unconfined strength {strength:.4g} Pa" if strength is not None else ""
        if "cohesion" in s:  # a shear run: its yield locus
            extra = (
                f", cohesion {s['cohesion']:.4g} Pa, friction angle "
                f"{s['friction_angle']:.3g} deg, ffc {s['ffc']:.3g}"
            )
        self._say(
            state,
            f"{key} done: {s['particles']:.0f} particles, {s['steps']:.0f} steps, "
            f"{s['wall_time']:.1f} s{extra}",
        )

    def _say(self, state, text: str, style: str | None = None) -> None:
        """A run's outcome: in the display's events, and printed even without bars."""
        if self.display.quiet:
            self.console.print(text, style=style, markup=False, highlight=False, soft_wrap=True)
        else:
            self.display.event(state, text, style)
