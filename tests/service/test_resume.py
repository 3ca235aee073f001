"""A run in flight survives its worker: SIGKILLed mid-run more often than ``max_attempts``,
each time after its checkpoint moved on, the study succeeds, and its stored run is byte for
byte the run that was never interrupted (the poison rule that counts only attempts without
progress: tests/service/test_transitions.py)."""

from __future__ import annotations

import random
import signal
import time
from datetime import timedelta

import pytest

import engine
from engine.io.store import load_run
from service import checkpoints
from service.models import utcnow

from .conftest import TINY, study_getter, wait_for

#: One reference of several seconds (a small time step: about 290,000 steps, 4.5 s on a
#: core), so that it can be killed mid-run KILLS times: each attempt is killed within about
#: 0.6 s of its start (its first checkpoint comes after 0.3 s, or at the fill's end, the kill
#: up to 0.3 s later), about two fifths of the run in all. (dt = 1e-6 s before, then 4e-6 s:
#: a 30 s run, then 7 s, made twice, by the killed workers and uninterrupted to compare:
#: most of the test's time.)
LONG = {
    **TINY,
    "name": "long",
    "reference": {**TINY["reference"], "unconfined": False, "dt": 6e-6, "inertial_number": 5e-4},
}
KILLS = 3


@pytest.mark.timeout(300)
def test_a_run_killed_again_and_again_resumes_and_is_stored_bit_identically(
    client, workers, settings
):
    settings.checkpoint_interval = 0.3
    settings.max_attempts = 2  # fewer than the kills: each attempt moved its checkpoint on
    r = client.post("/studies", json=LONG)
    assert r.status_code == 202, r.text
    sid = r.json()["id"]
    ckpt = settings.checkpoints_dir(sid) / "ref-s1.ckpt"
    rng = random.Random(int(time.time()))
    for kill in range(KILLS):
        started = time.time()
        worker = workers.start()
        deadline = time.monotonic() + 120
        # this attempt has written a checkpoint of its own (not only resumed an older one)
        while not (ckpt.exists() and ckpt.stat().st_mtime > started + 0.05):
            assert worker.poll() is None, workers.logs()
            assert time.monotonic() < deadline, f"kill {kill}: no checkpoint\n{workers.logs()}"
            time.sleep(0.02)
        time.sleep(rng.uniform(0.0, 0.3))
        worker.send_signal(signal.SIGKILL)
        worker.wait()
        status = client.get(f"/studies/{sid}").json()
        assert status["status"] == "running", status  # killed mid-run, not after it
        assert status["runs"][0]["status"] == "running"
    workers.start()
    # the interrupted run is stored (the study's coarse run after it is any study's run, and
    # a whole study through kills is tests/service/test_chaos.py's)
    done = wait_for(
        study_getter(client, sid),
        lambda s: (
            s["status"] in ("succeeded", "failed")
            or any(
                r["key"] == "ref-s1" and r["status"] in ("succeeded", "failed", "cancelled")
                for r in s["runs"]
            )
        ),
        120,
        "the killed run to be stored after the kills",
        workers,
    )
    assert done["status"] != "failed", done["error"]
    assert next(r for r in done["runs"] if r["key"] == "ref-s1")["status"] == "succeeded", done
    logs = workers.logs(None)
    assert logs.count("resuming run ref-s1 from its checkpoint") >= KILLS, logs[-3000:]
    # the stored run is the uninterrupted one, byte for byte
    spec = engine.StudySpec.from_dict({k: v for k, v in LONG.items() if k != "name"})
    ref = next(p for p in engine.plan(spec).runs if p.key == "ref-s1")
    clean = engine.run_uniaxial(ref.test)
    stored = load_run(settings.runs_dir(sid) / "ref-s1.h5")
    assert list(stored.stages) == list(clean.stages)
    for name, st in clean.stages.items():
        for k, v in st.curves.items():
            assert stored.stages[name].curves[k].tobytes() == v.tobytes(), f"{name}.{k}"
    assert stored.scalars["steps"] == clean.scalars["steps"]
    # a run's checkpoint goes once the run is stored (just after its row says so)
    deadline = time.monotonic() + 10
    while ckpt.exists():
        assert time.monotonic() < deadline, "ref-s1's checkpoint outlived its stored run"
        time.sleep(0.05)


def test_advanced_since_reads_checkpoint_times(tmp_path):
    d = tmp_path / "checkpoints"
    assert not checkpoints.advanced_since(d, utcnow())  # no folder
    d.mkdir()
    before = utcnow() - timedelta(seconds=5)
    (d / "ref-s1.ckpt").write_bytes(b"x")
    (d / ".ref-s1.ckpt.1.tmp").write_bytes(b"x")
    assert checkpoints.advanced_since(d, before)
    assert checkpoints.advanced_since(d, before.replace(tzinfo=None))  # naive = UTC
    assert not checkpoints.advanced_since(d, utcnow() + timedelta(seconds=5))
    checkpoints.remove_all(d)
    assert not d.exists()
