"""Chaos: the API (``python -m service api``) and the worker (``python -m service.worker``)
are killed with SIGKILL at random moments while several small studies run, and restarted.
Every study must succeed, each results file must be whole, and no temporary file may be
left behind. Bounded: a few kills of each process over six one-second studies; a worker is
killed at a random moment of a running study (the engine running, the results being
written, a status being changed), the API at a random moment.

The first study runs undisturbed, so that the engine's kernels are compiled (and cached)
before the kills start: a worker killed every second or two would never finish compiling
on a cold cache.
"""

from __future__ import annotations

import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import httpx
import pytest
from sqlmodel import Session, select

from service.db import engine_for
from service.models import TERMINAL, Status, Study

from .conftest import AUTH, REPO, TINIEST, TOKEN, free_port, worker_env

N_STUDIES = 6
WORKER_KILLS = 6
API_KILLS = 2
#: The whole scenario must end within this many seconds (compilation on a cold cache
#: included).
BOUND_S = 400


class Api:
    """``python -m service api`` on a free local port, restartable."""

    def __init__(self, settings, log_dir: Path):
        self.env = worker_env(settings)
        self.port = free_port()
        self.env.update(
            DEMSCALE_HOST="127.0.0.1",
            DEMSCALE_PORT=str(self.port),
            DEMSCALE_API_TOKEN=TOKEN,
            DEMSCALE_EMBEDDED_WORKER="false",
        )
        self.url = f"http://127.0.0.1:{self.port}"
        self.log_dir = log_dir
        self.proc: subprocess.Popen | None = None
        self.starts = 0

    def start(self) -> None:
        with open(self.log_dir / f"api-{self.starts}.log", "wb") as log:
            self.proc = subprocess.Popen(
                [sys.executable, "-m", "service", "api"],
                cwd=REPO,
                env=self.env,
                stdout=log,
                stderr=subprocess.STDOUT,
            )
        self.starts += 1
        deadline = time.monotonic() + 60
        while True:
            try:
                if httpx.get(f"{self.url}/healthz", timeout=2).status_code == 200:
                    return
            except httpx.HTTPError:
                pass
            assert self.proc.poll() is None, "the API exited"
            assert time.monotonic() < deadline, "the API did not come up"
            time.sleep(0.1)

    def kill(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.send_signal(signal.SIGKILL)
            self.proc.wait()


def statuses(settings) -> dict[str, tuple[Status, int]]:
    with Session(engine_for(settings)) as s:
        return {str(x.id): (x.status, x.attempts) for x in s.exec(select(Study)).all()}


def running_on(settings, pid: int) -> bool:
    """Whether the worker process ``pid`` runs a study (its id is host:pid:suffix)."""
    with Session(engine_for(settings)) as s:
        owners = s.exec(select(Study.worker_id).where(Study.status == Status.running)).all()
    return any(w is not None and w.split(":")[1] == str(pid) for w in owners)


@pytest.mark.timeout(BOUND_S + 60)
def test_studies_survive_sigkills_of_worker_and_api(settings, workers, tmp_path):
    settings.max_attempts = 50  # every kill of a running study costs an attempt
    api = Api(settings, tmp_path)
    t0 = time.monotonic()
    try:
        api.start()
        with httpx.Client(base_url=api.url, headers=AUTH, timeout=30) as c:
            ids = []
            for i in range(N_STUDIES):
                r = c.post("/studies", json={**TINIEST, "name": f"chaos-{i}"})
                assert r.status_code == 202, r.text
                ids.append(r.json()["id"])
        worker = workers.start()
        while statuses(settings)[ids[0]][0] is not Status.succeeded:  # compile, undisturbed
            assert worker.poll() is None, workers.logs()
            assert time.monotonic() - t0 < BOUND_S, "the first study did not finish"
            time.sleep(0.2)

        seed = int(os.environ.get("DEMSCALE_CHAOS_SEED", time.time_ns() % 2**32))
        rng = random.Random(seed)
        plan = ["worker"] * WORKER_KILLS + ["api"] * API_KILLS
        rng.shuffle(plan)
        print(f"chaos seed {seed} (DEMSCALE_CHAOS_SEED), kills: {plan}")
        kills = 0
        for target in plan:
            if target == "worker":
                # a random moment while this worker runs a study (not while it starts)
                while not running_on(settings, worker.pid):
                    if all(s in TERMINAL for s, _ in statuses(settings).values()):
                        break
                    assert time.monotonic() - t0 < BOUND_S, "no study ran"
                    time.sleep(0.05)
                else:
                    time.sleep(rng.uniform(0.0, 1.5))
                    kills += 1
                worker.send_signal(signal.SIGKILL)
                worker.wait()
                worker = workers.start()
            else:
                time.sleep(rng.uniform(0.2, 2.0))
                api.kill()
                api.start()

        while not all(s in TERMINAL for s, _ in statuses(settings).values()):
            assert worker.poll() is None, workers.logs()
            assert time.monotonic() - t0 < BOUND_S, f"not done: {statuses(settings)}"
            time.sleep(0.2)
        final = statuses(settings)
        assert {s for s, _ in final.values()} == {Status.succeeded}, (final, workers.logs())
        print(
            f"{kills} worker kills during a run, {API_KILLS} API kills; attempts per "
            f"study: {sorted(a for _, a in final.values())}; {time.monotonic() - t0:.0f} s"
        )

        # the API (restarted) serves every result, and no temporary file is left anywhere
        with httpx.Client(base_url=api.url, headers=AUTH, timeout=30) as c:
            for sid in ids:
                assert c.get(f"/studies/{sid}/summary").status_code == 200
        for sid in ids:
            with h5py.File(settings.results_path(sid), "r") as f:
                assert f.attrs["study_id"] == sid and len(f["runs"]) == 2
        leftovers = [p for p in settings.data_dir.rglob("*") if p.is_file() and p.suffix == ".tmp"]
        assert leftovers == []
    finally:
        api.kill()
