"""Shear studies through the service (issue 41): ``POST /studies`` takes a reference of
``"type": "ShearTest"`` (engine.ShearTest's fields, from its records), the worker runs it
(stored in HDF5 like any study), the API gives its summary, yield loci and figures and the
page shows it; bad shear values get a 422 naming the field with nothing written; the
admission counts a shear run's worst case against the caps."""

from __future__ import annotations

import copy

import pytest
from fastapi.testclient import TestClient

import engine
from service.app import create_app
from service.routes.results import StageKind
from service.spec import SHEAR_EXAMPLE

from .conftest import AUTH, assert_refused, changed_part, record_schema

#: The service's documented shear example (service.spec.SHEAR_EXAMPLE: the tests' 120-grain
#: cell) with a short pre-shear (tests/engine/test_shear_study.py): two reference seeds (a
#: noise floor), one coarse run of the paper's rule: three runs, seconds.
SHEAR_STUDY = {
    **SHEAR_EXAMPLE,
    "name": "tiny shear",
    "reference": {**SHEAR_EXAMPLE["reference"], "preshear_min_strain": 0.3, "steady_window": 0.1},
    "rules": ["paper"],
    "seeds": [1],
    "reference_seeds": [1, 2],
    "controls": False,
    "protocol_check": False,
}


def test_a_shear_study_runs_in_the_worker_and_shows_its_loci(client, settings, tmp_path):
    from service.worker import Worker

    r = client.post("/studies", json=SHEAR_STUDY)
    assert r.status_code == 202, r.text
    sid = r.json()["id"]
    job = client.get(f"/studies/{sid}").json()
    assert job["spec"]["reference"]["type"] == "ShearTest"
    assert [run["key"] for run in job["runs"]] == ["ref-s1", "ref-s2", "r3.1mm-paper-s1"]
    Worker(settings, once=True).run()
    job = client.get(f"/studies/{sid}").json()
    assert job["status"] == "succeeded", job["error"]
    summary = client.get(f"/studies/{sid}/summary").json()
    # the shear metrics judged, the uniaxial ones absent
    assert set(summary["advisor"]["noise_floor"]) == set(engine.study.metrics.SHEAR_METRICS)
    assert summary["units"]["cohesion"] == "Pa" and "err_strength" not in summary["units"]
    (verdict,) = summary["advisor"]["verdicts"]
    assert verdict["verdict"] in ("equivalent", "differs", "undecided")
    rows = {row["run"]: row for row in summary["table"]}
    # the yield loci per run: the pre-shear point, then a failure point per normal stress,
    # each below the pre-shear stress; the stored locus is the table's
    curves = client.get(f"/studies/{sid}/curves").json()
    for key, run in curves["runs"].items():
        kinds = [p["kind"] for p in run["points"]]
        assert kinds == ["preshear", "failure", "failure"], key
        assert [p["target"] for p in run["points"][1:]] == [3e3, 7e3]
        assert run["locus"]["cohesion"] == pytest.approx(rows[key]["cohesion"])
        assert "preshear" in run["stages"] and "point1_shear" in run["stages"]
        # every stage the engine stored can be asked for by name (the service's list of the
        # shear stages is its own copy of engine.shear.driver's names)
        assert set(run["stages"]) <= {s.value for s in StageKind}, key
    assert curves["units"]["shear_stress"] == "Pa"
    one = client.get(f"/studies/{sid}/curves", params={"run": "ref-s1", "kind": "preshear"})
    assert one.status_code == 200 and set(one.json()["runs"]["ref-s1"]["stages"]) == {"preshear"}
    # the shear study's figures
    for kind in ("yield_locus", "preshear", "error_vs_runtime"):
        png = client.get(f"/studies/{sid}/plots/{kind}.png")
        assert png.status_code == 200 and png.content[:4] == b"\x89PNG", kind
    # the page: the shear columns and plots, no uniaxial-only ones
    page = client.get(f"/studies/{sid}/page")
    assert page.status_code == 200
    assert "A shear study" in page.text and "cohesion [kPa]" in page.text
    assert "plots/yield_locus.png" in page.text and "plots/stress_strain.png" not in page.text
    assert "self-weight" not in page.text
    # the HDF5 file reads back as the engine's shear results
    from engine.io.store import load_run

    ref = load_run(settings.runs_dir(sid) / "ref-s1.h5")
    assert isinstance(ref, engine.ShearResult) and ref.test.normal_stresses == (3e3, 7e3)
    assert ref.scalars["cohesion"] == pytest.approx(rows["ref-s1"]["cohesion"])
    # the yield-locus figure has the references' Mohr circles (sigma_c, sigma_1 judged);
    # a uniaxial plot of a shear study says what the study's plots are
    from engine.io.figures import figure
    from service.h5store import read_plot_data

    data = read_plot_data(settings.results_path(sid))
    labels = figure("yield_locus", *data).axes[0].get_legend_handles_labels()[1]
    assert any(lb.startswith("reference's Mohr circles: sigma_c") for lb in labels), labels
    texts = [x.get_text() for x in figure("stress_strain", *data).axes[0].texts]
    assert any("a shear study" in x and "yield_locus" in x for x in texts), texts
    _cohesionless_and_failed(client, settings, sid, tmp_path)


def _cohesionless_and_failed(client, settings, sid: str, tmp_path) -> None:
    """A locus without cohesion has sigma_c = 0 and an infinite ffc (a cohesionless
    material's coarse run did in a trial): stored as strict JSON and read back as infinity;
    a file with Python's ``Infinity`` (stored before) still gives finite JSON curves, not a
    500; the page shows ffc as infinite and lists a failed run with its reason. The study
    ``sid`` is the worker test's, its file edited here (no second worker run)."""
    import dataclasses
    import json
    import math

    import h5py

    from engine.io.store import load_run, read_run_group, write_run_group

    ref = load_run(settings.runs_dir(sid) / "ref-s1.h5")
    free = dataclasses.replace(ref, locus=dataclasses.replace(ref.locus, ffc=math.inf))

    def strict(text: str):
        return json.loads(text, parse_constant=lambda c: pytest.fail(f"{c} in stored JSON"))

    with h5py.File(tmp_path / "free.h5", "w") as f:
        write_run_group(f, free)
        assert strict(f.attrs["locus"])["ffc"] is None
        strict(f.attrs["shear_points"])
        assert read_run_group(f).locus.ffc == math.inf
    path = settings.results_path(sid)
    reason = "StageError: the yield locus: the yield locus's slope tan(phi) = -0.58 is not > 0"
    with h5py.File(path, "r+") as f:
        g = f["runs/ref-s1"]
        g.attrs["locus"] = json.dumps(free.locus.to_dict())  # Infinity, as stored before
        g["scalars"].attrs["ffc"] = math.inf
        summary = json.loads(f.attrs["summary"])
        summary["failed"] = {"ref-s9": reason}
        f.attrs["summary"] = json.dumps(summary)
    r = client.get(f"/studies/{sid}/curves")
    assert r.status_code == 200, r.text
    assert r.json()["runs"]["ref-s1"]["locus"]["ffc"] is None
    page = client.get(f"/studies/{sid}/page").text
    assert '<td class="num">∞</td>' in page
    assert "Failed runs" in page and "ref-s9" in page and "slope tan(phi) = -0.58" in page


@pytest.mark.parametrize(
    ("change", "loc", "words"),
    [
        # a normal stress above the pre-shear stress: the engine's cross-field rule
        (
            lambda t: t.__setitem__("normal_stresses", [3e3, 12e3]),
            ["body", "reference", "normal_stresses", 1],
            "< preshear_stress = 10000 Pa",
        ),
        # the pre-shear stress lowered below the normal stresses it left to the defaults:
        # the field the client set is named
        (
            lambda t: (t.pop("normal_stresses"), t.__setitem__("preshear_stress", 5e3)),
            ["body", "reference", "preshear_stress"],
            "< preshear_stress = 5000 Pa",
        ),
        (
            lambda t: t.__setitem__("normal_stresses", [-1e3, 3e3]),
            ["body", "reference", "normal_stresses", 0],
            "> 0",
        ),
        (
            lambda t: t.__setitem__("preshear_stress", -1e4),
            ["body", "reference", "preshear_stress"],
            "greater than 0",
        ),
        (
            lambda t: t.__setitem__("normal_stresses", [3e3]),
            ["body", "reference", "normal_stresses"],
            "2 to 8 stresses",
        ),
        (
            lambda t: t.__setitem__("inertial_number", 0.5),
            ["body", "reference", "inertial_number"],
            "less than or equal to 0.05",
        ),
        (
            lambda t: t.__setitem__("steady_window", 0.9),
            ["body", "reference", "steady_window"],
            "<= preshear_strain / 2",
        ),
        (lambda t: t.pop("pair_law"), ["body", "reference", "pair_law"], "Field required"),
        (
            lambda t: t.__setitem__("pair_law", {"type": "HertzMindlin"}),
            ["body", "reference", "pair_law"],
            "BilinearAdhesive",
        ),
        (lambda t: t.__setitem__("preset", "quick"), ["body", "reference", "preset"], "Extra"),
        (lambda t: t.__setitem__("type", "RingShear"), ["body", "reference"], "ShearTest"),
    ],
)
def test_bad_shear_values_get_a_422_naming_the_field(client, settings, change, loc, words):
    assert_refused(
        client, settings, "/studies", changed_part(SHEAR_STUDY, "reference", change), loc, words
    )


def test_a_uniaxial_reference_is_unchanged_and_its_errors_untagged(client):
    # no "type": the uniaxial test, as before; its errors at reference.<field>
    r = client.post("/studies", json={"reference": {"preset": "quick", "radius": -1.0}})
    assert r.status_code == 422
    assert r.json()["detail"][0]["loc"] == ["body", "reference", "radius"]
    explicit = {"reference": {"type": "UniaxialTest", "preset": "quick", "unconfined": "no"}}
    r = client.post("/studies", json=explicit)
    assert r.json()["detail"][0]["loc"] == ["body", "reference", "unconfined"]


def test_a_shear_studys_worst_case_counts_against_the_caps(client, settings):
    r = client.post("/studies", json=SHEAR_STUDY)
    steps = client.get(f"/studies/{r.json()['id']}").json()["estimated_particle_steps"]
    # the worst case of three shear runs: each stage at its strain bound or max_stage_time,
    # far above what the runs are estimated to take
    fields = {k: v for k, v in SHEAR_STUDY.items() if k != "name"}
    study = engine.plan(engine.StudySpec.from_dict(copy.deepcopy(fields)))
    estimated = study.estimated_particle_steps()
    assert steps > 3 * estimated, (steps, estimated)
    # a cap below it refuses the study, naming the cap; nothing more is stored
    cap = {"max_particle_steps": 0.5 * steps}
    with TestClient(create_app(settings.model_copy(update=cap)), headers=AUTH) as c:
        r = c.post("/studies", json=SHEAR_STUDY)
        assert r.status_code == 422 and "DEMSCALE_MAX_PARTICLE_STEPS" in r.text, r.text
        # the bounds named are the shear test's, not the uniaxial test's
        assert "preshear_strain, failure_strain" in r.text and "release_time" not in r.text
        # decide adds seeds: its worst case grows with the caps on them
        more = {**SHEAR_STUDY, "decide": True, "max_seeds": 6, "max_reference_seeds": 6}
        r = c.post("/studies", json={**more, "name": "decide"})
        assert r.status_code == 422 and "runs added until decided" in r.text, r.text
        assert c.get("/studies").json()["count"] == 1  # the first one above
    # the particle cap applies to a shear study's runs too
    few = {"max_particles_per_run": 50}
    with TestClient(create_app(settings.model_copy(update=few)), headers=AUTH) as c:
        r = c.post("/studies", json=SHEAR_STUDY)
        assert r.status_code == 422 and "DEMSCALE_MAX_PARTICLES_PER_RUN" in r.text, r.text
    # a service that runs on the GPU refuses it: the shear test runs on the CPU only
    gpu = {"backend": "cuda"}
    with TestClient(create_app(settings.model_copy(update=gpu)), headers=AUTH) as c:
        r = c.post("/studies", json=SHEAR_STUDY)
        assert r.status_code == 422, r.text
        assert r.json()["detail"][0]["loc"] == ["body", "reference", "type"]


def test_the_schema_has_the_shear_reference_from_the_records(client):
    shear = record_schema(client, "ShearTestIn", engine.ShearTest)
    assert "< preshear_stress" in shear["normal_stresses"]["description"]
    assert shear["settle_ke"]["minimum"] == 1e-8
    schema = client.get("/openapi.json").json()["components"]["schemas"]
    ref = schema["StudyCreate"]["properties"]["reference"]
    refs = {o["$ref"].rsplit("/", 1)[1] for o in ref["oneOf"]}
    assert refs == {"ReferenceIn", "ShearTestIn", "HopperTestIn"}
    examples = schema["StudyCreate"]["examples"]
    assert SHEAR_EXAMPLE in examples
