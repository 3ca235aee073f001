"""Calibrations through the service: POST /calibrations with the bounds, quotas, cancel and
resume of a study; a real worker runs one end to end and queues the study of the
calibrated law; bad requests get 422s naming the field."""

from __future__ import annotations

import signal

import pytest

from .conftest import (
    RUN_TIMEOUT,
    SLOW,
    TINIEST,
    job_getter,
    wait_finished,
    wait_for,
    wait_stopped,
    wait_succeeded,
)

PNG = b"\x89PNG\r\n\x1a\n"

#: A calibration of TINIEST's K1 to a loading stiffness: 3 design runs and the check run.
CALIBRATION = {
    "name": "tiny calibration",
    "test": TINIEST["reference"],
    "targets": {"tester": "uniaxial", "loading_stiffness": 1e6, "loading_stiffness_sd": 2e5},
    "parameters": {"k1": [3e3, 2e4]},
    "runs": 3,
    "waves": 0,
}


def getter(client, cid: str):
    return job_getter(client, f"/calibrations/{cid}")


def submit(client, body=CALIBRATION) -> str:
    r = client.post("/calibrations", json=body)
    assert r.status_code == 202, r.text
    assert r.headers["Location"] == f"/calibrations/{r.json()['id']}"
    return r.json()["id"]


@pytest.mark.timeout(2 * RUN_TIMEOUT)
def test_a_calibration_runs_end_to_end_then_its_study(client, workers, settings):
    then = {"coarse_radii": [3.1e-3], "rules": ["paper"], "controls": False}
    resolution = {"loading_stiffness": [1.5, 0.05]}  # the cell's loss, made up here
    cid = submit(client, {**CALIBRATION, "then_study": then, "resolution": resolution})
    assert client.get(f"/studies/{cid}").status_code == 404  # a calibration, not a study
    workers.start()
    seen = []
    done = wait_succeeded(getter(client, cid), "the calibration to finish", workers, seen=seen)
    assert any(0 < c["progress"] < 1 and c["current_run"] for c in seen)
    assert done["n_runs"] == 4 and done["progress"] == 1.0
    assert [(r["key"], r["status"]) for r in done["runs"]] == [
        ("cal-000", "succeeded"),
        ("cal-001", "succeeded"),
        ("cal-002", "succeeded"),
        ("check", "succeeded"),
    ]
    res = done["result"]
    k1 = res["parameters"]["k1"]
    assert 3e3 <= k1["median"] <= 2e4 and k1["status"] in ("determined", "free")
    (target,) = res["targets_met"]
    assert target["name"] == "loading_stiffness" and target["value"] > 0
    assert target["value"] == pytest.approx(1.5 * target["cell_value"])
    assert res["resolution"] == resolution
    assert isinstance(target["met"], bool)
    assert res["law"]["type"] == "BilinearAdhesive" and res["law"]["k1"] == k1["median"]
    curves = client.get(f"/calibrations/{cid}/curves").json()
    assert len(curves["check_run"]["loading"]["stress"]) > 3 and len(curves["runs"]) == 3
    png = client.get(f"/calibrations/{cid}/plot.png")
    assert png.status_code == 200 and png.content[:8] == PNG
    frag = client.get(f"/calibrations/{cid}/law", params={"format": "liggghts"})
    assert frag.status_code == 200 and "edinburgh" in frag.text
    table = client.get(f"/calibrations/{cid}/law").json()
    assert any(row["name"] == "k1" and row["unit"] == "N/m" for row in table), table
    assert client.get(f"/calibrations/{cid}/law", params={"format": "csv"}).text.count("\n") > 2
    # the study of the calibrated law, queued by the calibration, runs as any study
    sid = done["study_id"]
    assert sid is not None and res["then_study"] == {"id": sid}
    study = wait_succeeded(
        lambda: client.get(f"/studies/{sid}").json(), "the study of the calibrated law", workers
    )
    assert study["spec"]["reference"]["pair_law"]["k1"] == k1["median"]
    assert study["parent_id"] == cid
    assert f"/calibrations/{cid}/page" in client.get(f"/studies/{sid}/page").text
    listed = client.get("/calibrations").json()
    assert listed["count"] == 1 and listed["data"][0]["id"] == cid
    assert [s["id"] for s in client.get("/studies").json()["data"]] == [sid]
    page = client.get(f"/calibrations/{cid}/page")
    assert page.status_code == 200 and "k1" in page.text and "loading_stiffness" in page.text
    assert client.get("/").text.count(f"/calibrations/{cid}/page") == 1
    assert client.delete(f"/calibrations/{cid}").status_code == 204
    assert client.get(f"/calibrations/{cid}").status_code == 404
    assert client.get(f"/studies/{sid}").status_code == 200  # its study stays


@pytest.mark.timeout(2 * RUN_TIMEOUT)
def test_kill_9_mid_calibration_resumes_with_its_stored_runs(client, workers, settings):
    # CALIBRATION's own runs (TINIEST's test, seconds each with their snapshots): the kill
    # comes with two of the three design runs stored, a run and the check run before the end
    # (SLOW's test before: four times the runtime)
    cid = submit(client, CALIBRATION)
    first = workers.start()
    wait_for(
        getter(client, cid),
        lambda c: c["status"] == "running" and len(c["runs"]) >= 2,
        RUN_TIMEOUT,
        "the first run to be stored",
        workers,
    )
    first.send_signal(signal.SIGKILL)
    first.wait()
    stored = {p.name: p.stat().st_mtime_ns for p in settings.runs_dir(cid).glob("cal-*.h5")}
    assert stored
    workers.start()
    done = wait_finished(
        getter(client, cid),
        "the resumed calibration to finish",
        workers,
    )
    assert done["status"] == "succeeded" and done["attempts"] == 1, done["error"]
    # the runs stored before the kill were read back, not run again
    assert {n: (settings.runs_dir(cid) / n).stat().st_mtime_ns for n in stored} == stored
    assert len(done["result"]["runs"]) == 3


@pytest.mark.timeout(RUN_TIMEOUT + 60)
def test_cancel_a_queued_and_a_running_calibration(client, workers):
    queued = submit(client)
    r = client.post(f"/calibrations/{queued}/cancel")
    assert r.status_code == 202 and r.json()["status"] == "cancelled"
    assert client.post(f"/calibrations/{queued}/cancel").status_code == 409
    assert client.get(f"/calibrations/{queued}/curves").status_code == 409
    body = {**CALIBRATION, "test": SLOW["reference"] | {"unconfined": False}, "runs": 6}
    cid = submit(client, body)
    assert client.delete(f"/calibrations/{cid}").status_code == 409  # queued
    workers.start()
    wait_for(
        getter(client, cid),
        lambda c: c["status"] == "running" and c["progress"] > 0,
        RUN_TIMEOUT,
        "the calibration to run",
        workers,
    )
    assert client.post(f"/calibrations/{cid}/cancel").status_code == 202
    done = wait_stopped(getter(client, cid), 60, "the calibration to stop", workers)
    assert done["status"] == "cancelled" and done["result"] is None
    assert done["progress"] < 1


@pytest.mark.parametrize(
    ("change", "loc", "words"),
    [
        (
            {
                "targets": {
                    "tester": "uniaxial",
                    "compression": [{"stress": 1e4, "porosity": 0.7, "sd": 0.01}],
                }
            },
            ["body", "targets", "compression", 0, "porosity"],
            "spheres do not reach",
        ),
        (
            {
                "targets": {
                    "tester": "ring_shear",
                    "strength": [{"consolidation_stress": 2e4, "strength": 3e3, "sd": 300.0}],
                }
            },
            ["body", "targets", "strength"],
            "ring-shear",
        ),
        ({"parameters": {"n": [1.0, 2.0]}}, ["body", "parameters", "n"], "one of"),
        ({"parameters": {"k1": [2e4, 3e3]}}, ["body", "parameters", "k1"], "low < high"),
        ({"parameters": {"mu_s": [-1.0, 0.5]}}, ["body", "parameters", "mu_s"], ">= 0"),
        ({"parameters": {"k1": [3e3, 2e4], "k2": [3e4, 9e4]}}, ["body", "runs"], ">= 4"),
        ({"runs": 40, "waves": 2}, ["body", "runs"], "DEMSCALE_MAX_RUNS"),
        (
            {"then_study": {"coarse_radii": [0.5]}},
            ["body", "then_study", "coarse_radii", 0],
            "at most",
        ),
        (
            {"test": {**TINIEST["reference"], "cell": [1.0, 1.0, 2.0]}},
            ["body", "test"],
            "DEMSCALE_MAX_PARTICLES_PER_RUN",
        ),
        # what the user gives is explicit: the test, and each target's uncertainty
        ({"test": ...}, ["body", "test"], "Field required"),
        (
            {"targets": {"tester": "uniaxial", "loading_stiffness": 1e6}},
            ["body", "targets", "loading_stiffness_sd"],
            "uncertainty",
        ),
        # a box checked against the law's own bounds and the test's time step at once
        ({"parameters": {"k1": [3e3, 1e300]}}, ["body", "parameters", "k1"], "high end"),
        (
            {"parameters": {"k1": [3e3, 2e4], "k2": [2.5e4, 1e12]}, "runs": 4},
            ["body", "parameters", "k2"],
            "time step",
        ),
        ({"runs": 2.5}, ["body", "runs"], "integer"),
        (
            {"resolution": {"strength": [0.0, 0.1]}},
            ["body", "resolution", "strength"],
            "factor > 0",
        ),
    ],
)
def test_a_request_the_engine_refuses_gets_a_422_naming_the_field(client, change, loc, words):
    body = {k: v for k, v in {**CALIBRATION, **change}.items() if v is not ...}
    r = client.post("/calibrations", json=body)
    assert r.status_code == 422, r.text
    errors = r.json()["detail"]
    assert any(e["loc"] == loc and words in e["msg"] for e in errors), errors
    assert client.get("/calibrations").json()["count"] == 0  # nothing stored
