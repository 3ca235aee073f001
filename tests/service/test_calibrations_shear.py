"""Shear-tester data through POST /calibrations (issue 41): the request takes yield loci the
way it takes uniaxial data, in the same ``targets``; bad shear data gets a 422 naming the
field, and a refused request leaves no job, row or file behind; the shear tests count in the
calibration's worst case."""

from __future__ import annotations

import pytest
from fastapi.testclient import TestClient

from service.app import create_app

from .conftest import AUTH, assert_refused, changed_part
from .test_calibrations import CALIBRATION


def _pt(sigma_n, tau):
    return {"sigma_n": sigma_n, "sigma_n_sd": 50.0, "tau": tau, "tau_sd": 150.0}


#: A ring-shear flow function of two loci (made-up numbers: a format example).
SHEAR = [
    {
        "sigma_pre": 5e3,
        "tau_pre": 3.2e3,
        "tau_pre_sd": 200.0,
        "points": [_pt(1e3, 1.3e3), _pt(2.5e3, 2.0e3), _pt(4e3, 2.7e3)],
        "bulk_density": 1150.0,
        "bulk_density_sd": 15.0,
    },
    {"sigma_pre": 1e4, "points": [_pt(2e3, 2.3e3), _pt(6e3, 4.2e3)]},
]
RING = {**CALIBRATION, "targets": {"tester": "ring_shear", "shear": SHEAR}}
#: The tests' 120-grain shear cell (tests/engine/test_shear.py), as a request gives it.
SMALL_CELL = {"cell": [0.03, 0.015, 0.03], "inertial_number": 2e-3, "max_stage_time": 2.0}
MIXED = {
    **CALIBRATION,
    "targets": {**CALIBRATION["targets"], "shear_tester": "jenike", "shear": SHEAR[:1]},
}


@pytest.mark.parametrize("body", [RING, MIXED], ids=["ring_shear", "mixed"])
def test_shear_data_is_taken_like_uniaxial_data(client, body):
    r = client.post("/calibrations", json=body)
    assert r.status_code == 202, r.text
    job = client.get(f"/calibrations/{r.json()['id']}").json()
    # the normalised request keeps the loci as given, with the engine's names and nulls
    shear = job["request"]["targets"]["shear"]
    assert [s["sigma_pre"] for s in shear] == [s["sigma_pre"] for s in body["targets"]["shear"]]
    assert shear[0]["points"][2] == SHEAR[0]["points"][2]
    assert job["status"] == "queued" and job["n_runs"] == 4


def test_the_shear_tests_count_in_the_worst_case(client, settings):
    # each parameter set runs a shear test per locus: two loci cost far more than TINIEST's
    # uniaxial runs alone
    ids = [client.post("/calibrations", json=b).json()["id"] for b in (CALIBRATION, RING)]
    steps = [client.get(f"/calibrations/{i}").json()["estimated_particle_steps"] for i in ids]
    assert steps[1] > 10 * steps[0], steps
    # a cap below that worst case refuses it: the shear tests are what exceeds it
    cap = {"max_calibration_particle_steps": 0.5 * steps[1]}
    with TestClient(create_app(settings.model_copy(update=cap)), headers=AUTH) as c:
        r = c.post("/calibrations", json=RING)
        assert r.status_code == 422 and "particle-steps" in r.text, r.text
        assert c.get("/calibrations").json()["count"] == 2  # the two above, nothing more


@pytest.mark.parametrize(
    ("change", "loc", "words"),
    [
        # the three: sigma_n above sigma_pre, a locus with one point, negative tau
        (
            lambda t: t["shear"][0]["points"].__setitem__(1, _pt(6e3, 2e3)),
            ["body", "targets", "shear", 0, "points", 1, "sigma_n"],
            "below sigma_pre = 5000 Pa",
        ),
        (
            lambda t: t["shear"][1].__setitem__("points", [_pt(2e3, 2.3e3)]),
            ["body", "targets", "shear", 1, "points"],
            "a yield locus is a line",
        ),
        (
            lambda t: t["shear"][0]["points"].__setitem__(0, _pt(1e3, -1.3e3)),
            ["body", "targets", "shear", 0, "points", 0, "tau"],
            "greater than 0",
        ),
        (
            lambda t: t["shear"][0]["points"][0].pop("sigma_n_sd"),
            ["body", "targets", "shear", 0, "points", 0, "sigma_n_sd"],
            "Field required",
        ),
        (
            lambda t: t["shear"][0].pop("tau_pre_sd"),
            ["body", "targets", "shear", 0, "tau_pre_sd"],
            "uncertainty",
        ),
        (
            lambda t: t["shear"][1].__setitem__("sigma_pre", 5e3),
            ["body", "targets", "shear", 1, "points", 1, "sigma_n"],
            "below sigma_pre",
        ),
        (
            lambda t: t.__setitem__("tester", "lambda"),
            ["body", "targets", "shear_tester"],
            "not one",
        ),
        (
            lambda t: t.__setitem__("shear_tester", "shear box"),
            ["body", "targets", "shear_tester"],
            "ring_shear",
        ),
    ],
)
def test_bad_shear_data_gets_a_422_naming_the_field(client, settings, change, loc, words):
    assert_refused(
        client, settings, "/calibrations", changed_part(RING, "targets", change), loc, words
    )


def test_the_schema_states_the_shear_datas_units_and_rules(client):
    schema = client.get("/openapi.json").json()["components"]["schemas"]
    point = schema["LocusPointIn"]["properties"]
    assert point["tau"]["exclusiveMinimum"] == 0 and point["tau"]["x-unit"] == "Pa"
    assert set(schema["LocusPointIn"]["required"]) == {"sigma_n", "sigma_n_sd", "tau", "tau_sd"}
    locus = schema["ShearLocusIn"]
    assert locus["dependentRequired"] == {
        "tau_pre": ["tau_pre_sd"],
        "bulk_density": ["bulk_density_sd"],
    }
    assert "at least 2" in locus["properties"]["points"]["description"]
    assert locus["properties"]["bulk_density"]["x-unit"] == "kg/m^3"
    # the shear cell: engine.ShearTest's declared fields but those the calibration sets
    import engine
    from engine.calibration.forward import SET_BY_CALIBRATION
    from engine.core.records import describe

    cell = schema["ShearCellIn"]["properties"]
    declared = {i.name: i for i in describe(engine.ShearTest)}
    assert set(cell) == set(declared) - set(SET_BY_CALIBRATION)
    assert all(cell[n].get("x-unit") == declared[n].unit for n in cell if declared[n].unit)


def test_a_shear_calibration_runs_in_the_worker_and_shows_its_loci(client, settings, monkeypatch):
    # the worker (in this process, its runs in process: run_workers 1) runs a calibration
    # to shear data in a shear cell of the request's, with the shear test replaced by its
    # closed-form stand-in (tests/engine/test_calibrate_shear.py); the API, the page, the
    # curves and the figure show the result
    import importlib

    from service.worker import Worker
    from tests.engine.test_calibrate_shear import _locus, _stand_in_shear, quicker_posterior

    cal_module = importlib.import_module("engine.calibration.calibrate")
    ran = []
    monkeypatch.setattr(
        cal_module, "run_shear_tests", lambda t, p=None: ran.append(t) or _stand_in_shear(t, p)
    )
    quicker_posterior(monkeypatch)
    targets = {"tester": "ring_shear", "shear": [_locus(1e4, (2e3, 7e3), bulk=True)]}
    body = {
        **RING,
        "targets": targets,
        "parameters": {"mu_s": [0.2, 0.8]},
        "runs": 4,
        "shear_test": SMALL_CELL,
        "vary_seed": True,
    }
    assert client.post("/calibrations", json={**body, "vary_seed": "yes"}).status_code == 422
    r = client.post("/calibrations", json=body)
    assert r.status_code == 202, r.text
    cid = r.json()["id"]
    Worker(settings.model_copy(update={"run_workers": 1}), once=True).run()
    job = client.get(f"/calibrations/{cid}").json()
    assert job["status"] == "succeeded", job["error"]
    assert len(ran) == 5 and all(t[0].cell == tuple(SMALL_CELL["cell"]) for t in ran)
    assert len({t[0].seed for t in ran}) == 5  # vary_seed: a packing per run
    assert [r["key"] for r in job["runs"]] == ["cal-000", "cal-001", "cal-002", "cal-003", "check"]
    res = client.get(f"/calibrations/{cid}").json()["result"]
    assert [q["name"] for q in res["targets_met"]][-1] == "bulk_density@10000Pa"
    page = client.get(f"/calibrations/{cid}/page")
    assert page.status_code == 200
    assert "yield loci from a ring_shear tester" in page.text
    assert "The check run's yield loci" in page.text and "kg/m^3" in page.text
    curves = client.get(f"/calibrations/{cid}/curves").json()
    assert curves["laboratory"]["shear"][0]["sigma_pre"] == 1e4
    assert curves["check_run"]["yield_loci"][0]["sigma_pre"] == 1e4
    assert curves["units"]["bulk_density"] == "kg/m^3"
    png = client.get(f"/calibrations/{cid}/plot.png")
    assert png.status_code == 200 and png.content[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("name", ["LabTargets", "ShearLocus", "LocusPoint"])
def test_the_shear_records_fields_units_and_bounds_are_the_engines(client, name):
    # the request's schema is derived from the engine's declarations (engine.core.records
    # param): the agreement check of tests/service/test_spec_agreement.py on these records
    from engine.calibration import targets

    from .test_spec_agreement import test_fields_units_bounds_defaults_agree as agree

    agree(client.get("/openapi.json").json()["components"]["schemas"], getattr(targets, name))


def test_a_shear_cell_of_its_own_is_taken_and_stated(client):
    ids = [
        client.post("/calibrations", json={**RING, **extra}).json()["id"]
        for extra in ({}, {"shear_test": SMALL_CELL})
    ]
    jobs = [client.get(f"/calibrations/{i}").json() for i in ids]
    default, small = (j["request"]["shear_test"] for j in jobs)
    # the normalised request states the whole cell (defaults filled in), not the law or the
    # stresses, which the calibration sets
    assert default["cell"] == pytest.approx([0.05, 0.025, 0.075]) and default["dt"] == 3e-5
    assert small["cell"] == SMALL_CELL["cell"] and small["max_stage_time"] == 2.0
    assert not {"pair_law", "preshear_stress", "normal_stresses"} & set(small)
    # a smaller cell with shorter stages costs less
    steps = [j["estimated_particle_steps"] for j in jobs]
    assert steps[1] < steps[0] / 4, steps


@pytest.mark.parametrize(
    ("body", "loc", "words"),
    [
        ({**RING, "shear_test": {"radius": 2e-3}}, ["body", "shear_test", "radius"], "radius"),
        (
            {**RING, "shear_test": {**SMALL_CELL, "pair_law": {"k1": 5e3}}},
            ["body", "shear_test", "pair_law"],
            "Extra inputs",
        ),
        (
            {**RING, "shear_test": {"cell": [0.03, 0.015, 0.01]}},
            ["body", "shear_test", "cell"],
            "four glued layers",
        ),
        ({**CALIBRATION, "shear_test": SMALL_CELL}, ["body", "shear_test"], "shear targets only"),
    ],
)
def test_a_bad_shear_cell_gets_a_422_naming_the_field(client, settings, body, loc, words):
    assert_refused(client, settings, "/calibrations", body, loc, words)
