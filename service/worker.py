"""The worker process: ``python -m service.worker``.

It recovers studies whose worker died (stale heartbeat: requeued, or failed after
``DEMSCALE_MAX_ATTEMPTS`` claims), claims queued studies one at a time and runs them. SIGTERM
(or SIGINT) stops it cleanly: the engine stops at its next progress report and the study goes
back to the queue; if the engine does not stop within ``DEMSCALE_SHUTDOWN_GRACE`` seconds
(e.g. it is compiling a kernel) the study is requeued anyway and the process exits.
"""

from __future__ import annotations

import argparse
import logging
import os
import signal
import socket
import threading
import uuid
from datetime import timedelta

from sqlmodel import Session

from . import checkpoints, transitions
from .db import engine_for
from .execute import StudyExecution, execution_for
from .models import Status, utcnow
from .settings import Settings, get_settings, secure_data_dir

log = logging.getLogger("demscale.worker")


class Worker:
    """Claims and runs studies until asked to stop."""

    def __init__(self, settings: Settings, parent_pid: int | None = None, once: bool = False):
        self.settings = settings
        self.parent_pid = parent_pid
        self.once = once
        self.id = f"{socket.gethostname()}:{os.getpid()}:{uuid.uuid4().hex[:6]}"
        self.db = engine_for(settings)
        self.shutdown = threading.Event()
        self.current: StudyExecution | None = None

    def request_shutdown(self, signum: int | None = None, _frame=None) -> None:
        """Stop after the current study stops; force it after the grace period."""
        if self.shutdown.is_set():
            return
        log.info("worker %s: shutting down (signal %s)", self.id, signum)
        self.shutdown.set()
        threading.Thread(target=self._deadline, name="shutdown-deadline", daemon=True).start()

    def _deadline(self) -> None:
        current = self.current
        if current is None or current.done.wait(self.settings.shutdown_grace):
            return
        log.warning(
            "study %s did not stop within %.0f s: requeued, exiting",
            current.study_id,
            self.settings.shutdown_grace,
        )
        with Session(self.db) as s:
            transitions.release(s, current.study_id, self.id)
        os._exit(0)

    def recover(self) -> None:
        """Requeue (or fail) the studies of dead workers."""
        cutoff = utcnow() - timedelta(seconds=self.settings.stale_after)

        def advanced(sid, since) -> bool:
            return checkpoints.advanced_since(self.settings.checkpoints_dir(sid), since)

        with Session(self.db) as s:
            for sid, status in transitions.recover_stale(
                s, cutoff, self.settings.max_attempts, advanced
            ):
                log.warning("study %s had a dead worker: now %s", sid, status.value)
                if status is not Status.queued:  # ended: its checkpoints will not be resumed
                    checkpoints.remove_all(self.settings.checkpoints_dir(sid))
                else:  # its next attempts checkpoint more often (DEMSCALE_..._AFTER_CRASH)
                    checkpoints.note_crash(self.settings.crash_log(sid))

    def parent_gone(self) -> bool:
        """Whether the embedding API process has exited."""
        return self.parent_pid is not None and os.getppid() != self.parent_pid

    def run(self) -> None:
        """The main loop."""
        log.info("worker %s: started", self.id)
        while not self.shutdown.is_set():
            if self.parent_gone():
                log.info("worker %s: parent process gone, exiting", self.id)
                break
            self.recover()
            with Session(self.db) as s:
                study = transitions.claim_next(s, self.id)
            if study is None:
                self.shutdown.wait(self.settings.poll_interval)
                continue
            log.info(
                "worker %s: claimed %s %s (attempt %d)",
                self.id,
                study.kind.value,
                study.id,
                study.attempts,
            )
            self.current = execution_for(self.settings, self.id, study, self.shutdown)
            try:
                self.current.run()
            finally:
                self.current = None
            if self.once:
                break
        log.info("worker %s: stopped", self.id)


def main(argv: list[str] | None = None) -> None:
    """Command line: ``python -m service.worker [--once] [--parent-pid PID]``."""
    ap = argparse.ArgumentParser(
        prog="python -m service.worker",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    ap.add_argument("--once", action="store_true", help="exit after one study")
    ap.add_argument(
        "--parent-pid",
        type=int,
        default=None,
        help="exit when this process (the embedding API) is gone",
    )
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(levelname)s %(message)s")
    settings = get_settings()
    secure_data_dir(settings)  # results 0600 in 0700 directories
    worker = Worker(settings, parent_pid=args.parent_pid, once=args.once)
    signal.signal(signal.SIGTERM, worker.request_shutdown)
    signal.signal(signal.SIGINT, worker.request_shutdown)
    worker.run()


if __name__ == "__main__":
    main()
