"""A real worker process runs studies end to end; cancel, SIGTERM and kill -9 mid-study."""

from __future__ import annotations

import contextlib
import io
import json
import signal
import time
from pathlib import Path

import h5py
import numpy as np
import pytest

import engine
from engine.io.store import read_run_group, stage_names

from .conftest import (
    RUN_TIMEOUT,
    SLOW,
    TINY,
    TINY_CONTROLLED,
    study_getter,
    wait_finished,
    wait_for,
    wait_stopped,
    wait_succeeded,
)

PNG = b"\x89PNG\r\n\x1a\n"


def submit(client, body=SLOW) -> str:
    r = client.post("/studies", json=body)
    assert r.status_code == 202, r.text
    return r.json()["id"]


@contextlib.contextmanager
def runs_elsewhere(settings, where: str):
    """The worker's runs on a 2-process pool, or on a 2-worker local Dask cluster."""
    if where != "dask":
        settings.run_workers = 2
        yield
        return
    distributed = pytest.importorskip("distributed")
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address=None)
    settings.dask_scheduler = cluster.scheduler_address
    try:
        yield
    finally:
        cluster.close()


def running_mid_study(client, sid, workers) -> dict:
    """Wait until the worker is inside the reference run (progress reported)."""
    return wait_for(
        study_getter(client, sid),
        lambda s: (
            s["status"] == "running" and s["progress"] > 0.02 and s["current_run"] == "ref-s1"
        ),
        RUN_TIMEOUT,
        "the study to run",
        workers,
    )


@pytest.mark.timeout(RUN_TIMEOUT + 60)
def test_study_runs_end_to_end(client, workers, settings):
    sid = submit(client, TINY_CONTROLLED)
    workers.start()
    seen = []
    done = wait_succeeded(study_getter(client, sid), "the study to finish", workers, seen=seen)
    assert done["progress"] == 1.0 and done["attempts"] == 1 and done["run_time"] > 0
    assert done["started_at"] <= done["finished_at"]
    assert any(0 < s["progress"] < 1 and s["current_stage"] for s in seen)
    assert [(r["key"], r["status"]) for r in done["runs"]] == [
        ("ref-s1", "succeeded"),
        ("r3.1mm-paper-s1", "succeeded"),
        ("ctl-r3.1mm-s1", "succeeded"),
    ]
    assert all(r["steps"] > 0 and r["wall_time"] > 0 for r in done["runs"])
    assert [r["rule"] for r in done["runs"]] == ["reference", "paper", "control"]

    summary = client.get(f"/studies/{sid}/summary").json()
    table = {row["run"]: row for row in summary["table"]}
    assert set(table) == {"ref-s1", "r3.1mm-paper-s1", "ctl-r3.1mm-s1"}
    # the resolution control: the rule's own error and the resolution error, on the page too
    # (one seed each: their spreads are unknown, so both are undecided and say why)
    assert table["ctl-r3.1mm-s1"]["rule"] == "control"
    (res,) = summary["advisor"]["resolution"]
    (own,) = summary["advisor"]["rule_errors"]
    assert res["radius"] == own["radius"] == 3.1e-3 and own["rule"] == "paper"
    page = client.get(f"/studies/{sid}/page").text
    assert "Rule error and resolution error" in page and "against its resolution control" in page
    assert table["ref-s1"]["err_stress_strain"] == 0.0
    assert table["r3.1mm-paper-s1"]["particles"] < table["ref-s1"]["particles"]
    assert table["r3.1mm-paper-s1"]["speedup"] > 0 and summary["units"]["wall_time"] == "s"
    assert "paper" in summary["advisor"]["rules"]
    # snapshots of every run: ParaView files and a PNG section per stage, listed and served
    assert set(summary["snapshots"]) == {"ref-s1", "r3.1mm-paper-s1", "ctl-r3.1mm-s1"}
    urls = summary["snapshots"]["ref-s1"]
    assert any(u.endswith("/particles.vtkhdf") for u in urls)
    assert any(u.endswith("/unconfined.png") for u in urls)
    assert any(u.endswith("/particles.pvd") for u in urls)  # every ParaView: .pvd + .vtu
    assert any(u.endswith("/contacts-0000.vtu") for u in urls)
    for u in urls:
        r = client.get(u)
        assert r.status_code == 200 and len(r.content) > 200, u
        if u.endswith(".png"):
            assert r.content[:8] == b"\x89PNG\r\n\x1a\n"
        elif u.endswith((".pvd", ".vtu")):
            assert r.content.startswith(b'<?xml version="1.0"?>\n<VTKFile'), u
        else:
            assert r.content[:8] == b"\x89HDF\r\n\x1a\n"
    # the curves of a run as CSV, units in the headings
    r = client.get(f"/studies/{sid}/curves", params={"run": "ref-s1", "format": "csv"})
    assert r.status_code == 200 and r.headers["content-type"].startswith("text/csv")
    assert r.text.startswith("stage,time [s],strain [1],stress_top [Pa]")
    r = client.get(f"/studies/{sid}/curves", params={"format": "csv", "kind": "fill"})
    assert r.status_code == 200 and r.text.startswith("run,stage,time [s]")
    assert {line.split(",")[0] for line in r.text.splitlines()[1:]} == set(table)
    assert client.get(f"/studies/{sid}/runs/ref-s1/snapshots/other.png").status_code == 404
    assert client.get(f"/studies/{sid}/runs/ref-s1/snapshots/..%2Fresults.h5").status_code in (
        404,
        422,
    )

    curves = client.get(
        f"/studies/{sid}/curves", params={"run": "ref-s1", "kind": "consolidation"}
    ).json()
    cons = curves["runs"]["ref-s1"]["stages"]["consolidation"]
    assert list(curves["runs"]["ref-s1"]["stages"]) == ["consolidation"]
    assert len(cons["strain"]) == len(cons["stress_top"]) > 3
    assert max(cons["stress_top"]) >= 20e3 and curves["units"]["stress_top"] == "Pa"
    every = client.get(f"/studies/{sid}/curves").json()["runs"]
    assert set(every) == set(table) and "unconfined" in every["r3.1mm-paper-s1"]["stages"]
    for params in ({"run": "nope"}, {"run": ".."}, {"run": "."}):
        assert client.get(f"/studies/{sid}/curves", params=params).status_code == 404
    for params in ({"kind": "nope"}, {"run": "a/b"}, {"run": "x" * 101}):
        assert client.get(f"/studies/{sid}/curves", params=params).status_code == 422

    kinds = client.get(f"/studies/{sid}").json()["plot_kinds"]
    for kind in kinds:
        r = client.get(f"/studies/{sid}/plots/{kind}.png")
        assert r.status_code == 200 and r.headers["content-type"] == "image/png", kind
        assert r.content[:8] == PNG and len(r.content) > 10_000, kind
    # a uniaxial study has no shear plots: a 404 naming the kinds it has
    assert client.get(f"/studies/{sid}/plots/yield_locus.png").status_code == 404
    assert client.get(f"/studies/{sid}/plots/histogram.png").status_code == 422

    r = client.get(f"/studies/{sid}/results.h5")
    assert r.status_code == 200 and r.content[:8] == b"\x89HDF\r\n\x1a\n"
    with h5py.File(io.BytesIO(r.content), "r") as f:
        assert f.attrs["schema_version"] == 2 and f.attrs["study_id"] == sid
        assert '"coarse_radii": [0.0031]' in f.attrs["spec"]
        for pkg in ("demscale", "numpy", "numba", "h5py"):
            assert f.attrs[f"version_{pkg}"]
        assert list(f["runs"]) == ["ref-s1", "r3.1mm-paper-s1", "ctl-r3.1mm-s1"]
        ref = f["runs/ref-s1"]
        assert ref.attrs["reference"] and ref.attrs["radius_units"] == "m"
        ctl = f["runs/ctl-r3.1mm-s1"]
        assert ctl.attrs["control"] and not ctl.attrs["reference"]
        assert ctl.attrs["rule"] == "control"
        # the run in the one layout of a run (engine.io.store), as in its own file
        assert ref["scalars"].attrs["unconfined_strength_units"] == "Pa"
        assert engine.UniaxialTest.from_dict(json.loads(ref.attrs["test"])).seed == 1
        assert stage_names(ref) == [
            "fill",
            "pre_compression",
            "consolidation",
            "unloading",
            "release",
            "unconfined",
        ]
        stress = ref["stages/consolidation/stress_top"]
        assert stress.attrs["units"] == "Pa" and stress.shape == (len(cons["stress_top"]),)
        np.testing.assert_allclose(stress[()], cons["stress_top"])
        assert ref["stages/unconfined/particles/positions"].shape[1] == 3
        assert ref["stages/unconfined/particles/radii"].attrs["units"] == "m"
        stored = read_run_group(ref)  # reads back as a run
        assert stored.stages["consolidation"].curves["stress_top"].tobytes() == stress[()].tobytes()
        assert f["summary/wall_time"].attrs["units"] == "s"
        assert [x.decode() for x in f["summary/run"][()]] == list(f["runs"])
    assert not list(settings.study_dir(sid).glob("*.tmp"))

    assert client.delete(f"/studies/{sid}").status_code == 204
    assert not settings.study_dir(sid).exists()


@pytest.mark.timeout(RUN_TIMEOUT + 60)
def test_cancel_a_running_study(client, workers):
    sid = submit(client)
    worker = workers.start()
    running_mid_study(client, sid, workers)
    r = client.post(f"/studies/{sid}/cancel")
    assert r.status_code == 202 and r.json()["cancel_requested"]
    done = wait_stopped(study_getter(client, sid), 30, "the cancel", workers)
    assert done["status"] == "cancelled" and done["progress"] < 1
    assert {x["status"] for x in done["runs"]} == {"cancelled"}
    assert client.get(f"/studies/{sid}/summary").status_code == 409
    assert worker.poll() is None  # the worker goes on serving the queue
    nxt = submit(client, TINY)
    wait_for(
        study_getter(client, nxt),
        lambda s: s["status"] == "running",
        60,
        "the next study to start",
        workers,
    )


@pytest.mark.timeout(RUN_TIMEOUT + 60)
def test_sigterm_puts_the_study_back_in_the_queue(client, workers):
    sid = submit(client)
    worker = workers.start()
    running_mid_study(client, sid, workers)
    worker.send_signal(signal.SIGTERM)
    assert worker.wait(30) == 0
    study = client.get(f"/studies/{sid}").json()
    assert study["status"] == "queued" and study["attempts"] == 0
    assert {x["status"] for x in study["runs"]} == {"queued"}


@pytest.mark.timeout(2 * RUN_TIMEOUT)
def test_kill_9_mid_study_then_a_new_worker_completes_it(client, workers, settings):
    # SLOW's step, so that the kill comes before the fill's end (a checkpoint: the attempt
    # would have moved the study on and not count), without the unconfined stages: the new
    # worker runs the whole study again, the test's longest part (two stages fewer per run)
    sid = submit(client, {**SLOW, "reference": {**SLOW["reference"], "unconfined": False}})
    first = workers.start()
    running_mid_study(client, sid, workers)
    first.send_signal(signal.SIGKILL)
    first.wait()
    orphan = client.get(f"/studies/{sid}").json()
    assert orphan["status"] == "running" and orphan["attempts"] == 1
    # the kill is meant to come mid-fill, before any checkpoint; on a loaded machine the
    # fill can end first, and its checkpoint means the attempt moved the study on: it does
    # not count (the poison rule), and the new worker resumes from that checkpoint
    moved_on = any(settings.checkpoints_dir(sid).glob("*.ckpt"))
    attempts = 1 if moved_on else 2
    t_kill = time.monotonic()
    workers.start()
    second = workers.log_dir / "worker-1.log"
    wait_for(
        study_getter(client, sid),
        lambda s: second.exists() and f"claimed study {sid}" in second.read_text(),
        60,
        "the new worker to take the study over",
        workers,
    )
    # read again: the state wait_for returns was fetched before the log was read, and the
    # claim can fall between the two (attempts 1 read, 2 logged)
    retaken = study_getter(client, sid)()
    # not before the heartbeat went stale
    assert time.monotonic() - t_kill >= settings.stale_after - 0.5
    assert retaken["status"] in ("running", "succeeded") and retaken["attempts"] == attempts
    done = wait_stopped(study_getter(client, sid), RUN_TIMEOUT, "the study to finish", workers)
    assert done["status"] == "succeeded" and done["attempts"] == attempts, done["error"]
    assert ("resuming run ref-s1 from its checkpoint" in second.read_text()) == moved_on
    assert [r["status"] for r in done["runs"]] == ["succeeded", "succeeded"]
    summary = client.get(f"/studies/{sid}/summary").json()
    assert [row["run"] for row in summary["table"]] == ["ref-s1", "r3.1mm-paper-s1"]


@pytest.mark.timeout(2 * RUN_TIMEOUT)
def test_a_study_resumes_with_only_its_unfinished_runs(client, workers, settings):
    body = {**TINY, "reference_seeds": [1, 2], "seeds": [1]}
    sid = submit(client, body)
    first = workers.start()
    # kill the worker once the first run is stored, while it works on the second
    wait_for(
        study_getter(client, sid),
        lambda s: s["status"] == "running" and s["runs"][0]["status"] == "succeeded",
        RUN_TIMEOUT,
        "the first run to be stored",
        workers,
    )
    first.send_signal(signal.SIGKILL)
    first.wait()
    stored_before = sorted(p.stem for p in settings.runs_dir(sid).glob("*.h5"))
    assert "ref-s1" in stored_before and len(stored_before) < 3
    workers.start()
    done = wait_finished(
        study_getter(client, sid),
        "the resumed study to finish",
        workers,
        timeout=2 * RUN_TIMEOUT - 30,
    )
    # the attempt that was killed had finished a run: an interruption, not a failure
    assert done["status"] == "succeeded" and done["attempts"] == 1, done["error"]
    second = (workers.log_dir / "worker-1.log").read_text()
    ran = sorted(k for k in ("ref-s1", "ref-s2", "r3.1mm-paper-s1") if f"run {k} stored" in second)
    assert ran == sorted({"ref-s1", "ref-s2", "r3.1mm-paper-s1"} - set(stored_before)), second
    assert f"resuming with {len(stored_before)} of 3 runs stored" in second
    summary = client.get(f"/studies/{sid}/summary").json()
    assert [row["run"] for row in summary["table"]] == ["ref-s1", "ref-s2", "r3.1mm-paper-s1"]
    assert {v["rule"] for v in summary["advisor"]["verdicts"]} == {"paper"}


@pytest.mark.timeout(RUN_TIMEOUT + 60)
def test_a_run_that_fails_fails_the_study_with_the_reason(client, workers):
    body = {**TINY, "reference": {**TINY["reference"], "max_stage_time": 0.02}}
    sid = submit(client, body)
    workers.start()
    done = wait_finished(
        study_getter(client, sid),
        "the study to fail",
        workers,
    )
    assert done["status"] == "failed" and done["attempts"] == 1
    assert "ref-s1" in done["error"] and "fill" in done["error"], done["error"]
    assert [(r["status"], bool(r["error"])) for r in done["runs"]] == [
        ("failed", True),
        ("cancelled", False),
    ]
    r = client.get(f"/studies/{sid}/summary")
    assert r.status_code == 409 and "failed" in r.json()["detail"]


@pytest.mark.timeout(RUN_TIMEOUT + 60)
def test_a_study_whose_worker_keeps_dying_is_failed_with_the_reason(client, workers, settings):
    settings.max_attempts = 1
    sid = submit(client)
    first = workers.start()
    running_mid_study(client, sid, workers)
    first.send_signal(signal.SIGKILL)
    first.wait()
    workers.start()
    done = wait_stopped(study_getter(client, sid), 60, "the orphaned study to be failed", workers)
    assert done["status"] == "failed" and done["attempts"] == 1
    assert "gave up after 1 attempts" in done["error"] and "heartbeat" in done["error"]
    assert {r["status"] for r in done["runs"]} == {"cancelled"}


@pytest.mark.timeout(2 * RUN_TIMEOUT)
@pytest.mark.parametrize("where", ["process pool", "dask"])
def test_runs_as_tasks_on_a_pool_or_a_dask_cluster(client, workers, settings, where):
    with runs_elsewhere(settings, where):
        sid = submit(client, {**TINY, "reference_seeds": [1, 2], "seeds": [1]})
        workers.start()
        done = wait_succeeded(
            study_getter(client, sid),
            f"the study on the {where} to finish",
            workers,
            timeout=2 * RUN_TIMEOUT - 30,
        )
    assert [r["status"] for r in done["runs"]] == ["succeeded"] * 3
    assert all(r["wall_time"] > 0 and r["steps"] > 0 for r in done["runs"])
    assert sorted(p.stem for p in settings.runs_dir(sid).glob("*.h5")) == [
        "r3.1mm-paper-s1",
        "ref-s1",
        "ref-s2",
    ]


@pytest.mark.timeout(RUN_TIMEOUT + 90)
@pytest.mark.parametrize("where", ["process pool", "dask"])
def test_progress_within_runs_and_cancel_on_a_pool_or_a_dask_cluster(
    client, workers, settings, where
):
    """Runs on other processes report progress while they run (engine.FileChannel in the
    study's folder), and a cancel stops the running tasks, not only the pending ones."""
    with runs_elsewhere(settings, where):
        # half SLOW's step: a run lasts several progress intervals (engine's
        # REPORT_INTERVAL, 0.5 s), so the first report the study shows cannot come from a
        # run that finished within one interval (CI-like run, session 35: SLOW's 1 s run did)
        slower = {**SLOW["reference"], "dt": 2e-6}
        sid = submit(client, {**SLOW, "reference": slower, "reference_seeds": [1, 2], "seeds": [1]})
        workers.start()
        mid = wait_for(
            study_getter(client, sid),
            lambda s: s["status"] == "running" and s["progress"] > 0.02,
            RUN_TIMEOUT,
            "progress from inside the running tasks",
            workers,
        )
        # progress came from inside the runs: none had finished when it was reported
        assert "succeeded" not in {r["status"] for r in mid["runs"]}
        assert (settings.study_dir(sid) / "channel").is_dir()
        t0 = time.monotonic()
        assert client.post(f"/studies/{sid}/cancel").status_code == 202
        done = wait_stopped(study_getter(client, sid), 30, "the cancel", workers)
        assert done["status"] == "cancelled"
        assert time.monotonic() - t0 < 20
        # the running tasks were asked to stop (tests/engine/test_channel.py: they do)
        assert (settings.study_dir(sid) / "channel" / "STOP").exists()


def _children(pid: int) -> set[int]:
    """Direct child processes of ``pid`` (Linux /proc)."""
    out: set[int] = set()
    for task in (Path("/proc") / str(pid) / "task").glob("*"):
        try:
            out |= {int(c) for c in (task / "children").read_text().split()}
        except OSError:
            continue
    return out


def _alive(pid: int) -> bool:
    try:
        state = (Path("/proc") / str(pid) / "stat").read_text().split(")")[-1].split()[0]
    except OSError:
        return False
    return state != "Z"


@pytest.mark.timeout(RUN_TIMEOUT + 60)
@pytest.mark.skipif(not Path("/proc/self/task").exists(), reason="needs Linux /proc")
def test_pool_processes_exit_when_their_worker_is_killed(client, workers, settings):
    """A service worker killed outright cannot shut its pool down: the pool's processes
    notice that their parent is gone and exit (service.pools.exit_with_parent) instead of
    living on, idle, with their memory."""
    settings.run_workers = 2
    sid = submit(client, {**SLOW, "reference_seeds": [1, 2], "seeds": [1]})
    worker = workers.start()
    wait_for(
        study_getter(client, sid),
        lambda s: s["status"] == "running" and s["progress"] > 0.02,
        RUN_TIMEOUT,
        "the pool to run",
        workers,
    )
    pool = _children(worker.pid)
    assert len(pool) >= 2
    worker.send_signal(signal.SIGKILL)
    worker.wait()
    deadline = time.monotonic() + 15
    while time.monotonic() < deadline and any(_alive(p) for p in pool):
        time.sleep(0.2)
    assert not [p for p in pool if _alive(p)]


@pytest.mark.timeout(RUN_TIMEOUT + 60)
def test_a_study_that_decides_adds_runs_with_rows_and_shows_them(client, workers, settings):
    from .conftest import TINIEST

    body = {
        **TINIEST,
        "name": "decide",
        "decide": True,
        "rounds": 1,
        "max_seeds": 3,
        "max_reference_seeds": 3,
    }
    sid = submit(client, body)
    workers.start()
    done = wait_succeeded(study_getter(client, sid), "the study to finish", workers)
    summary = client.get(f"/studies/{sid}/summary").json()
    adaptive = summary["advisor"]["adaptive"]
    added = [a["run"] for a in adaptive["added_runs"]]
    assert adaptive["planned_runs"] == 2 and added  # one reference seed: a second is added
    keys = [r["key"] for r in done["runs"]]
    assert keys[:2] == ["ref-s1", "r3.1mm-paper-s1"] and set(added) <= set(keys)
    assert done["n_runs"] == len(keys)
    assert all(r["status"] in ("succeeded", "failed") for r in done["runs"])
