"""Fixtures of the service tests: a temporary database and data directory per test, an app
(TestClient) and a live uvicorn server on them, and real worker processes."""

from __future__ import annotations

import copy
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import httpx
import pytest
import uvicorn
from fastapi.testclient import TestClient

from service.app import create_app
from service.embedded import settings_env
from service.settings import Settings

REPO = Path(__file__).resolve().parents[2]

#: The bearer token of the test settings, and the header that sends it.
TOKEN = "test-token-0123456789abcdef"
AUTH = {"Authorization": f"Bearer {TOKEN}"}

#: About 30 particles, a reference and one coarse run with all stages: seconds per study.
TINY = {
    "name": "tiny",
    "reference": {
        "cell": [0.015, 0.015, 0.03],
        "output_interval": 1e-3,
        "platen_speed": 0.02,
        # the constant platen speed above (the default protocol's inertial number would
        # move it at 6.7 mm/s here: three times the steps for what these tests check)
        "inertial_number": None,
        "pair_law": {"type": "BilinearAdhesive", "k1": 5e3, "k2": 2.5e4, "f0": -0.05},
    },
    "coarse_radii": [3.1e-3],
    "rules": ["paper"],
    "controls": False,
    "protocol_check": False,
}

#: TINY with its resolution control (engine.study.plan.control_test): three runs.
TINY_CONTROLLED = {**TINY, "name": "tiny-controlled", "controls": True}

#: TINY with a smaller time step: long enough (seconds) to be interrupted mid-study.
#: (At the default protocol's inertial number, as it ran before TINY held the platen speed.)
SLOW = {
    **TINY,
    "name": "slow",
    "reference": {**TINY["reference"], "dt": 4e-6, "inertial_number": 5e-4},
}

#: Smaller still: no unconfined stages, a coarse time step; about a second per study.
TINIEST = {
    "name": "tiniest",
    "reference": {**TINY["reference"], "unconfined": False, "dt": 3e-5, "output_interval": 2e-3},
    "coarse_radii": [3.1e-3],
    "rules": ["paper"],
    "controls": False,
    "protocol_check": False,
}


@pytest.fixture
def settings(tmp_path: Path) -> Settings:
    """Settings on a fresh SQLite file and data directory, with fast worker timings."""
    return Settings(
        data_dir=tmp_path / "data",
        database_url=f"sqlite:///{tmp_path / 'db.sqlite'}",
        embedded_worker=False,
        heartbeat_interval=0.2,
        stale_after=2.0,
        poll_interval=0.1,
        shutdown_grace=15.0,
        max_attempts=3,
        max_particles_per_run=5000,
        max_particle_steps=2e9,
        api_token=TOKEN,
        submit_rate=1e6,  # tests submit in bursts; the limit has its own test
        submit_burst=10**6,
        auth_failure_rate=1e6,  # tests send wrong tokens on purpose; the limit has its test
        auth_failure_burst=10**6,
    )


@pytest.fixture
def client(settings: Settings) -> Iterator[TestClient]:
    """A TestClient on an app bound to the per-test settings, sending the test token."""
    with TestClient(create_app(settings), headers=AUTH) as c:
        yield c


def worker_env(settings: Settings) -> dict[str, str]:
    """Environment of a worker subprocess: the test settings, one numba thread (workers run
    side by side on few cores), the repository on the path."""
    env = settings_env(settings)
    env["NUMBA_NUM_THREADS"] = "1"
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(REPO), env.get("PYTHONPATH")]))
    return env


class Workers:
    """Starts ``python -m service.worker`` processes; kills leftovers at teardown."""

    def __init__(self, settings: Settings, log_dir: Path):
        self.settings = settings
        self.log_dir = log_dir
        self.procs: list[subprocess.Popen] = []

    def start(self, *args: str) -> subprocess.Popen:
        log = open(self.log_dir / f"worker-{len(self.procs)}.log", "wb")
        proc = subprocess.Popen(
            [sys.executable, "-m", "service.worker", *args],
            cwd=REPO,
            env=worker_env(self.settings),
            stdout=log,
            stderr=subprocess.STDOUT,
        )
        log.close()
        self.procs.append(proc)
        return proc

    def logs(self, tail: int | None = 3000) -> str:
        """The workers' logs (the last ``tail`` characters of each; None: all)."""
        return "\n".join(
            p.read_text(errors="replace")[-tail if tail else 0 :]
            for p in sorted(self.log_dir.glob("worker-*.log"))
        )

    def stop_all(self) -> None:
        for p in self.procs:
            if p.poll() is None:
                p.send_signal(signal.SIGKILL)
                p.wait()


@pytest.fixture
def workers(settings: Settings, tmp_path: Path) -> Iterator[Workers]:
    """Worker processes on the test's store; their logs are shown when the test fails."""
    w = Workers(settings, tmp_path)
    yield w
    w.stop_all()
    print(w.logs())


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_healthy(url: str, proc: subprocess.Popen, timeout: float, pause: float, what: str):
    """Poll ``url``/healthz every ``pause`` seconds until it answers 200; fail, naming
    ``what``, if ``proc`` (the process serving it) exits or ``timeout`` seconds pass."""
    deadline = time.monotonic() + timeout
    while True:
        try:
            if httpx.get(f"{url}/healthz", timeout=2).status_code == 200:
                return
        except httpx.HTTPError:
            pass
        assert proc.poll() is None, f"{what} exited"
        assert time.monotonic() < deadline, f"{what} did not come up"
        time.sleep(pause)


@pytest.fixture
def live_server(settings: Settings) -> Iterator[str]:
    """The app served by uvicorn on a free local port (real concurrency); yields its URL."""
    port = free_port()
    server = uvicorn.Server(
        uvicorn.Config(create_app(settings), host="127.0.0.1", port=port, log_level="warning")
    )
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    deadline = time.monotonic() + 20
    while not server.started:
        assert thread.is_alive() and time.monotonic() < deadline, "uvicorn did not start"
        time.sleep(0.02)
    yield f"http://127.0.0.1:{port}"
    server.should_exit = True
    thread.join(10)


def wait_for(
    get: Callable[[], dict],
    ok: Callable[[dict], bool],
    timeout: float,
    what: str,
    workers: Workers | None = None,
) -> dict:
    """Poll ``get()`` until ``ok`` holds for its answer; fail after ``timeout`` seconds."""
    deadline = time.monotonic() + timeout
    last: dict = {}
    while time.monotonic() < deadline:
        last = get()
        if ok(last):
            return last
        time.sleep(0.05)
    logs = workers.logs() if workers else ""
    pytest.fail(f"timed out waiting for {what}; last: {last}\n{logs}")


def changed(body: dict, path: tuple, value) -> dict:
    """``body`` with ``value`` at ``path`` (the key removed where ``value`` is ...)."""
    out = copy.deepcopy(body)
    node = out
    for key in path[:-1]:
        node = node[key]
    if value is ...:
        del node[path[-1]]
    else:
        node[path[-1]] = value
    return out


def changed_part(body: dict, part: str, change: Callable[[dict], object]) -> dict:
    """A deep copy of ``body`` whose ``part`` (a dict) ``change`` has edited in place."""
    out = copy.deepcopy(body)
    change(out[part])
    return out


#: How long a test waits for a job of seconds of simulation [s]: generous, it includes a
#: first compilation of the engine's kernels on a cold cache.
RUN_TIMEOUT = 240


def wait_finished(
    get: Callable[[], dict],
    what: str,
    workers: Workers | None = None,
    timeout: float = RUN_TIMEOUT,
    seen: list | None = None,
) -> dict:
    """Poll ``get()`` (:func:`wait_for`) until the job it reads has succeeded or failed;
    ``seen``, where given, collects every answer polled (the progress on the way)."""

    def finished(job: dict) -> bool:
        if seen is not None:
            seen.append(job)
        return job["status"] in ("succeeded", "failed")

    return wait_for(get, finished, timeout, what, workers)


def wait_succeeded(get: Callable[[], dict], what: str, workers: Workers | None = None, **kw):
    """:func:`wait_finished` (``kw``: its ``timeout`` and ``seen``), asserting that the job
    succeeded (else naming its error)."""
    done = wait_finished(get, what, workers, **kw)
    assert done["status"] == "succeeded", done["error"]
    return done


def wait_stopped(
    get: Callable[[], dict], timeout: float, what: str, workers: Workers | None = None
) -> dict:
    """Poll ``get()`` (:func:`wait_for`) until the job it reads is no longer running."""
    return wait_for(get, lambda job: job["status"] != "running", timeout, what, workers)


def data_files(settings: Settings) -> list[Path]:
    """Every file under the settings' data directory, sorted."""
    return sorted(p for p in settings.data_dir.rglob("*") if p.is_file())


def assert_refused(
    client: TestClient, settings: Settings, path: str, body: dict, loc: list, words: str
) -> None:
    """POST ``body`` to ``path`` (``/studies`` or ``/calibrations``) on an empty store: a 422
    with an error at ``loc`` whose message holds ``words``, and nothing half-written (no job
    listed, no file in the data directory)."""
    before = data_files(settings)
    r = client.post(path, json=body)
    assert r.status_code == 422, r.text
    errors = r.json()["detail"]
    assert any(e["loc"] == loc and words in e["msg"] for e in errors), errors
    assert client.get(path).json()["count"] == 0
    assert data_files(settings) == before


def job_getter(client: TestClient | httpx.Client, url: str) -> Callable[[], dict]:
    """A function that GETs the job at ``url`` (a study's or a calibration's) and returns its
    JSON, asserting a 200."""

    def get() -> dict:
        r = client.get(url)
        assert r.status_code == 200, r.text
        return r.json()

    return get


def record_schema(client: TestClient, model: str, record: type) -> dict:
    """The properties of the request model ``model`` in the app's OpenAPI document, checked
    against the engine record ``record`` it is derived from: the record's declared fields
    and its ``type`` tag, ``pair_law`` required, each field's unit as ``x-unit``."""
    from engine.core.records import describe

    schema = client.get("/openapi.json").json()["components"]["schemas"][model]
    declared = {info.name: info for info in describe(record)}
    assert set(schema["properties"]) == set(declared) | {"type"}
    assert "pair_law" in schema["required"]
    for name, info in declared.items():
        if info.unit:
            assert schema["properties"][name]["x-unit"] == info.unit, name
    return schema["properties"]


def study_getter(client: TestClient | httpx.Client, study_id: str) -> Callable[[], dict]:
    return job_getter(client, f"/studies/{study_id}")
