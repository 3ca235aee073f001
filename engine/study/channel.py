"""Progress and stop requests between a study and its runs when the runs are tasks in other
processes or on other hosts (:func:`engine.run_study` with an executor).

A channel is a picklable object that travels with every task. Inside the task the run reports
its progress through it and asks it whether to stop; the study reads the progress of every
running task and requests a stop through it. :class:`FileChannel` keeps both in a folder: a
small JSON file per run, replaced atomically, and a ``STOP`` marker. It works for a process
pool on one machine and for cluster workers that share the folder's filesystem (the usual
set-up of a SLURM or Dask cluster with a network home or scratch); a task that cannot reach
the folder runs on, reports only when it finishes and is stopped only when it has not started.
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

#: Shortest interval between two progress writes of one run [s].
REPORT_INTERVAL = 0.5


class FileChannel:
    """Progress and stop requests through the files of ``directory``.

    Task side: :meth:`report`, :meth:`stop_requested`. Study side: :meth:`reset` (before the
    runs start), :meth:`read`, :meth:`request_stop`.
    """

    def __init__(self, directory) -> None:
        self.directory = str(directory)

    def _path(self, name: str) -> Path:
        return Path(self.directory) / name

    # ------------------------------------------------------------------ study side
    def reset(self) -> None:
        """An empty channel: no progress files, no stop request."""
        d = Path(self.directory)
        d.mkdir(parents=True, exist_ok=True)
        for p in d.iterdir():
            if p.suffix in (".json", ".tmp") or p.name == "STOP":
                p.unlink(missing_ok=True)

    def request_stop(self) -> None:
        """Ask every running task to stop at its next progress report."""
        self._path("STOP").touch()

    def read(self) -> dict[str, dict]:
        """The last report of every run that reported: key -> {fraction, stage, time}."""
        out = {}
        for p in Path(self.directory).glob("*.json"):
            try:
                out[p.stem] = json.loads(p.read_text())
            except (OSError, ValueError):  # replaced while read: the next poll has it
                continue
        return out

    # ------------------------------------------------------------------ task side
    def report(self, key: str, fraction: float, stage: str, sim_time: float) -> None:
        """Write the run's progress: ``fraction`` of the run in [0, 1], its ``stage`` and
        simulated time [s]."""
        tmp = self._path(f"{key}.{os.getpid()}.tmp")
        try:
            tmp.write_text(json.dumps({"fraction": fraction, "stage": stage, "time": sim_time}))
            os.replace(tmp, self._path(f"{key}.json"))
        except OSError:  # the folder is not reachable from this host: run on silently
            tmp.unlink(missing_ok=True)

    def stop_requested(self) -> bool:
        """Whether the study asked its tasks to stop."""
        return self._path("STOP").exists()


def task_progress(channel, key: str):
    """The progress callback of a run executed as a task: reports to ``channel`` at most
    every :data:`REPORT_INTERVAL` seconds (and at the run's end) and returns False, which
    stops the run, once a stop is requested."""
    last = [-1e9]

    def callback(pr) -> bool | None:
        now = time.monotonic()
        if now - last[0] < REPORT_INTERVAL and pr.fraction < 1.0:
            return None
        last[0] = now
        channel.report(key, float(pr.fraction), pr.stage, float(pr.time))
        return False if channel.stop_requested() else None

    return callback


def wait_tasks(futures: dict, keys, channel, poll_interval: float, on_done, on_running) -> None:
    """Wait for the tasks ``futures`` (future -> index; ``keys[index]``: the run key each
    reports under) the way a study or a calibration does: ``on_done(index, future)`` as each
    ends; with a ``channel``, every ``poll_interval`` seconds [s] in which none ended,
    ``on_running([(index, report), ...])`` with the last report of each running task that
    has reported (:meth:`FileChannel.read`). Whatever leaves the wait (an exception, e.g. a
    stop raised by a callback) cancels the tasks not yet started."""
    import concurrent.futures as cf

    pending = set(futures)
    try:
        while pending:
            done, pending = cf.wait(
                pending,
                timeout=poll_interval if channel is not None else None,
                return_when=cf.FIRST_COMPLETED,
            )
            for fut in done:
                on_done(futures[fut], fut)
            if channel is not None and pending and not done:
                seen = channel.read()
                running = [
                    (futures[f], seen[keys[futures[f]]])
                    for f in pending
                    if keys[futures[f]] in seen
                ]
                if running:
                    on_running(running)
    finally:
        for fut in futures:
            fut.cancel()
