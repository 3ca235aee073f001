"""The embedded worker: one ``python -m service.worker`` subprocess started and stopped with
the API, for the single-machine default. It runs in its own session (a Ctrl-C at the
terminal reaches only the API, which then stops the worker with SIGTERM so that its study
goes back to the queue) and exits by itself if the API process dies."""

from __future__ import annotations

import logging
import os
import signal
import subprocess
import sys
import threading
import time

from .settings import Settings

log = logging.getLogger("demscale.api")

#: Settings a child process does not inherit.
_SECRETS = ("api_token", "api_token_file")


def settings_env(settings: Settings) -> dict[str, str]:
    """Environment that gives a child process the same settings (absolute paths), without
    the API tokens: a worker serves no requests and need not know them."""
    env = dict(os.environ)
    for name, value in settings.model_dump(exclude=set(_SECRETS)).items():
        if value is not None:
            env[f"DEMSCALE_{name.upper()}"] = str(value)
    for name in _SECRETS:
        env.pop(f"DEMSCALE_{name.upper()}", None)
    env["DEMSCALE_DATA_DIR"] = str(settings.data_dir.resolve())
    url = settings.sqlalchemy_url
    if url.startswith("sqlite:///") and not url.startswith("sqlite:////"):
        url = f"sqlite:///{os.path.abspath(url[len('sqlite:///') :])}"
    env["DEMSCALE_DATABASE_URL"] = url
    return env


class EmbeddedWorker:
    """Starts the worker subprocess, restarts it if it dies (at most ``max_restarts`` times
    in a row within a minute), and stops it with SIGTERM."""

    def __init__(self, settings: Settings, max_restarts: int = 5):
        self.settings = settings
        self.max_restarts = max_restarts
        self.process: subprocess.Popen | None = None
        self._stopping = threading.Event()
        self._watch = threading.Thread(target=self._supervise, name="embedded-worker", daemon=True)

    def _spawn(self) -> subprocess.Popen:
        cmd = [sys.executable, "-m", "service.worker", "--parent-pid", str(os.getpid())]
        path = self.settings.worker_log_path
        if path is None:  # the API's own output
            proc = subprocess.Popen(cmd, env=settings_env(self.settings), start_new_session=True)
        else:  # a file of its own, appended across restarts (0600: the service's umask)
            path.parent.mkdir(parents=True, exist_ok=True)
            with open(path, "ab") as out:
                proc = subprocess.Popen(
                    cmd,
                    env=settings_env(self.settings),
                    start_new_session=True,
                    stdout=out,
                    stderr=subprocess.STDOUT,
                )
        log.info("embedded worker started (pid %d), its log: %s", proc.pid, path or "this output")
        return proc

    def start(self) -> None:
        """Start the worker and its supervisor thread."""
        self.process = self._spawn()
        self._watch.start()

    def _supervise(self) -> None:
        restarts, since = 0, time.monotonic()
        while not self._stopping.wait(1.0):
            proc = self.process
            if proc is None or proc.poll() is None:
                continue
            if time.monotonic() - since > 60:
                restarts, since = 0, time.monotonic()
            if restarts >= self.max_restarts:
                log.error("embedded worker keeps dying (exit %s); not restarting", proc.returncode)
                return
            log.warning("embedded worker exited with %s; restarting", proc.returncode)
            restarts += 1
            self.process = self._spawn()

    @property
    def alive(self) -> bool:
        """Whether the worker process is running."""
        return self.process is not None and self.process.poll() is None

    def stop(self) -> None:
        """SIGTERM the worker, wait for it to requeue its study and exit, kill it if late."""
        self._stopping.set()
        proc = self.process
        if proc is None or proc.poll() is not None:
            return
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(timeout=self.settings.shutdown_grace + 10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        log.info("embedded worker stopped (exit %s)", proc.returncode)
