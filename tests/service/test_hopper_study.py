"""Hopper studies through the service (docs/HOPPER.md): ``POST /studies`` takes a reference of
``"type": "HopperTest"`` (engine.HopperTest's declared fields), the worker runs it and stores
its runs (an engine.HopperResult each), the API gives its summary, discharge curves and the
hopper kind's figures only, and the page shows its columns; bad values get a 422 naming the
field with nothing written; the admission counts a hopper run's worst case; the worker's
``on_run`` stores an added run's round."""

from __future__ import annotations

import threading
import uuid

import pytest
from fastapi.testclient import TestClient
from sqlmodel import Session

import engine
from engine.io.store import load_run, stored_additions
from service.app import create_app
from service.db import engine_for
from service.execute import StudyExecution
from service.models import Study
from tests.test_cli_hopper import HOPPER_STUDY

from .conftest import AUTH, assert_refused, record_schema


def test_a_hopper_study_runs_in_the_worker(client, settings):
    from service.worker import Worker

    r = client.post("/studies", json=HOPPER_STUDY)
    assert r.status_code == 202, r.text
    sid = r.json()["id"]
    job = client.get(f"/studies/{sid}").json()
    assert job["spec"]["reference"]["type"] == "HopperTest"
    assert [run["key"] for run in job["runs"]] == ["ref-s1", "r3.1mm-paper-s1"]
    Worker(settings, once=True).run()
    job = client.get(f"/studies/{sid}").json()
    assert job["status"] == "succeeded", job["error"]
    summary = client.get(f"/studies/{sid}/summary").json()
    assert set(summary["advisor"]["noise_floor"]) == {"discharge_number", "bulk_density"}
    assert summary["units"]["discharge_rate"] == "kg/s" and "err_strength" not in summary["units"]
    # the discharge curves, by their stage's name too
    curves = client.get(f"/studies/{sid}/curves", params={"kind": "discharge"}).json()
    assert set(curves["runs"]) == {"ref-s1", "r3.1mm-paper-s1"}
    assert curves["units"]["discharged_mass"] == "kg"
    mass = curves["runs"]["ref-s1"]["stages"]["discharge"]["discharged_mass"]
    assert mass[0] == 0.0 and mass[-1] > 0.0
    # the hopper kind's figures; a uniaxial one is a 404 naming the study's plots
    for kind in ("discharge", "error_vs_runtime"):
        png = client.get(f"/studies/{sid}/plots/{kind}.png")
        assert png.status_code == 200 and png.content.startswith(b"\x89PNG"), kind
    r = client.get(f"/studies/{sid}/plots/stress_strain.png")
    assert r.status_code == 404 and "hopper study" in r.text and "error_vs_runtime" in r.text
    page = client.get(f"/studies/{sid}/page")
    assert page.status_code == 200 and "discharge number err [%]" in page.text
    assert "A hopper study" in page.text and "A shear study" not in page.text
    assert "plots/discharge.png" in page.text
    assert "plots/error_vs_runtime.png" in page.text and "plots/stress_strain.png" not in page.text
    assert "self-weight" not in page.text
    ref = load_run(settings.runs_dir(sid) / "ref-s1.h5")
    assert isinstance(ref, engine.HopperResult) and ref.test.fill_height == 0.03
    row = next(r for r in summary["table"] if r["run"] == "ref-s1")
    assert ref.scalars["bulk_density"] == pytest.approx(row["bulk_density"])


def _changed(**fields) -> dict:
    return {**HOPPER_STUDY, "reference": {**HOPPER_STUDY["reference"], **fields}}


@pytest.mark.parametrize(
    "body, loc, words",
    [
        (_changed(half_angle=95.0), ["body", "reference", "half_angle"], "less than 90"),
        (_changed(shape="wedge"), ["body", "reference", "shape"], "'slot' or 'cone'"),
        (_changed(outlet_width=0.01), ["body", "reference", "outlet_width"], ">= 3 diameters"),
        (_changed(cell=[0.1, 0.1, 0.1]), ["body", "reference", "cell"], "Extra"),
        (
            {**HOPPER_STUDY, "reference": {"type": "HopperTest", "fill_height": 0.03}},
            ["body", "reference", "pair_law"],
            "Field required",
        ),
        (
            _changed(pair_law={"type": "HertzMindlin"}),
            ["body", "reference", "pair_law"],
            "BilinearAdhesive",
        ),
    ],
)
def test_bad_hopper_values_get_a_422_naming_the_field(client, settings, body, loc, words):
    assert_refused(client, settings, "/studies", body, loc, words)


def test_a_hopper_studys_worst_case_counts_against_the_caps(client, settings):
    r = client.post("/studies", json=HOPPER_STUDY)
    assert r.status_code == 202, r.text
    steps = client.get(f"/studies/{r.json()['id']}").json()["estimated_particle_steps"]
    # every run to max_settle_time and max_discharge_time: above the engine's estimate
    fields = {k: v for k, v in HOPPER_STUDY.items() if k != "name"}
    estimated = engine.plan(engine.StudySpec.from_dict(fields)).estimated_particle_steps()
    assert steps > estimated, (steps, estimated)
    cap = {"max_particle_steps": 0.5 * steps}
    with TestClient(create_app(settings.model_copy(update=cap)), headers=AUTH) as c:
        r = c.post("/studies", json=HOPPER_STUDY)
        assert r.status_code == 422 and "max_settle_time and max_discharge_time" in r.text
    few = {"max_particles_per_run": 300}  # the reference has 390
    with TestClient(create_app(settings.model_copy(update=few)), headers=AUTH) as c:
        r = c.post("/studies", json=HOPPER_STUDY)
        assert r.status_code == 422 and "DEMSCALE_MAX_PARTICLES_PER_RUN" in r.text, r.text
        assert r.json()["detail"][0]["loc"] == ["body", "reference", "fill_height"]
    gpu = {"backend": "cuda"}  # the hopper runs on either backend: a GPU service takes it
    with TestClient(create_app(settings.model_copy(update=gpu)), headers=AUTH) as c:
        r = c.post("/studies", json=HOPPER_STUDY)
        assert r.status_code == 202, r.text


def test_on_run_stores_an_added_runs_round(client, settings):
    """The worker's on_run takes the round of a run a decide study added (engine.run_study
    passes ``added=``) and stores it with the run, as engine.io.store.save_run does."""
    r = client.post("/studies", json=HOPPER_STUDY)
    sid = uuid.UUID(r.json()["id"])
    with Session(engine_for(settings)) as s:
        study = s.get(Study, sid)
        ex = StudyExecution(settings, "test-worker", study, threading.Event())
    key = "r3.1mm-paper-s1"
    ex.known_runs.update((key, "ref-s1"))
    added = [{"run": key, "round": 1, "kind": "coarse", "reason": "undecided"}]
    ex.on_run(key, "RuntimeError: a failed added run", added=added)
    assert stored_additions(settings.runs_dir(sid)) == added
    ex.on_run("ref-s1", "RuntimeError: a failed planned run")  # no round: none stored
    assert stored_additions(settings.runs_dir(sid)) == added
    runs = {run["key"]: run for run in client.get(f"/studies/{sid}").json()["runs"]}
    assert runs[key]["status"] == "failed" and "added run" in runs[key]["error"]


def test_the_schema_has_the_hopper_reference_from_the_record(client):
    hopper = record_schema(client, "HopperTestIn", engine.HopperTest)
    assert hopper["half_angle"]["exclusiveMaximum"] == 90.0
