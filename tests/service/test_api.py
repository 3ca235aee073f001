"""The REST API without a worker: admission (422 with field-level errors and size caps),
404 for unknown ids, 409 for results that do not exist yet, cancel and delete of queued
studies, listing, the OpenAPI docs."""

from __future__ import annotations

import uuid

import pytest

import engine
from service.cost import worst_case
from service.spec import StudyCreate

from .conftest import TINY, changed


def with_changes(path: tuple, value) -> dict:
    """TINY with the value at ``path`` replaced (or the key deleted when value is ...)."""
    return changed(TINY, path, value)


BAD = [
    # (what, path, value, expected loc, a word of the message)
    ("negative radius", ("reference", "radius"), -1e-3, ["reference", "radius"], "greater"),
    ("huge radius", ("reference", "radius"), 0.5, ["reference", "radius"], "less"),
    ("no coarse radii", ("coarse_radii",), [], ["coarse_radii"], "at least 1"),
    ("coarse radius too big", ("coarse_radii",), [1.0], ["coarse_radii", 0], "at most"),
    ("coarse radius = reference", ("coarse_radii",), [2.5e-3], ["coarse_radii", 0], "> the"),
    ("coarse radius finer", ("coarse_radii",), [1e-3], ["coarse_radii", 0], "reference radius"),
    ("cell too small for coarse", ("coarse_radii",), [9e-3], ["coarse_radii", 0], "cell"),
    (
        "exponent out of range",
        ("rules",),
        [{"name": "x", "adhesion_exponent": 9}],
        ["rules", 0, "adhesion_exponent"],
        "less",
    ),
    ("unknown named rule", ("rules",), ["quadratic"], ["rules", 0], "paper"),
    ("duplicate rules", ("rules",), ["paper", "paper"], ["rules"], "unique"),
    ("bad dt policy", ("rules",), [{"name": "x", "dt": "adaptive"}], ["rules", 0, "dt"], "fixed"),
    ("negative stress", ("reference", "pre_stress"), -5.0, ["reference", "pre_stress"], "greater"),
    (
        "consolidation below pre-stress",
        ("reference", "consolidation_stress"),
        1e3,
        ["reference", "consolidation_stress"],
        "pre_stress",
    ),
    ("platen backwards", ("reference", "platen_speed"), -1, ["reference", "platen_speed"], "great"),
    ("string number", ("reference", "density"), "2000", ["reference", "density"], "number"),
    ("null reference", ("reference",), None, ["reference"], "valid dictionary"),
    ("long rule name", ("rules",), [{"name": "r" * 41}], ["rules", 0, "name"], "pattern"),
    (
        "unknown metric",
        ("tolerances",),
        {"colour": 0.1},
        ["tolerances"],
        "metric",
    ),
    (
        "k2 below k1",
        ("reference", "pair_law", "k2"),
        1e3,
        ["reference", "pair_law", "BilinearAdhesive", "k2"],
        "k1",
    ),
    (
        "positive adhesion",
        ("reference", "pair_law", "f0"),
        0.5,
        ["reference", "pair_law", "BilinearAdhesive", "f0"],
        "less",
    ),
    ("negative seed", ("seeds",), [-1], ["seeds"], "[0, 2^31)"),
    ("too many seeds", ("seeds",), list(range(11)), ["seeds"], "at most 10"),
    ("duplicate seeds", ("seeds",), [1, 1], ["seeds"], "distinct"),
    ("zero tolerance", ("tolerances",), {"density": 0}, ["tolerances", "density"], "(0, 1]"),
    ("unknown field", ("colour",), "blue", ["colour"], "not permitted"),
    (
        "Hertz pair law",
        ("reference", "pair_law"),
        {"type": "HertzMindlin", "E": 1e8},
        ["reference", "pair_law"],
        "BilinearAdhesive",
    ),
    (
        "bad wall modulus",
        ("reference", "wall_law"),
        {"E": -1.0},
        ["reference", "wall_law", "E"],
        "greater",
    ),
    (
        "EEPA exponent below 1",
        ("reference", "pair_law"),
        {"type": "EEPA", "k1": 5e5, "k2": 2.5e6, "n": 0.5},
        ["reference", "pair_law", "EEPA", "n"],
        "greater than or equal to 1",
    ),
    (
        "EEPA k2 below k1",
        ("reference", "pair_law"),
        {"type": "EEPA", "k1": 5e5, "k2": 1e5},
        ["reference", "pair_law", "EEPA", "k2"],
        "k1",
    ),
    ("unknown preset", ("reference", "preset"), "huge", ["reference", "preset"], "quick"),
    ("string radius", ("reference", "radius"), "big", ["reference", "radius"], "number"),
]


@pytest.mark.timeout(60)
@pytest.mark.parametrize("what,path,value,loc,word", BAD, ids=[b[0] for b in BAD])
def test_bad_fields_are_refused_with_422_naming_the_field(client, what, path, value, loc, word):
    r = client.post("/studies", json=with_changes(path, value))
    assert r.status_code == 422, r.text
    errors = r.json()["detail"]
    assert any(e["loc"] == ["body", *loc] for e in errors), errors
    assert any(word in e["msg"] for e in errors), errors
    assert client.get("/studies").json()["count"] == 0


@pytest.mark.timeout(60)
def test_too_many_particles_is_refused(client, settings):
    body = with_changes(("reference",), {"preset": "quick", "radius": 1e-3})
    body["coarse_radii"] = [2e-3]
    r = client.post("/studies", json=body)
    assert r.status_code == 422, r.text
    (err,) = r.json()["detail"]
    assert err["loc"] == ["body", "reference", "radius"]  # the field given that makes them many
    assert "particles" in err["msg"] and str(settings.max_particles_per_run) in err["msg"]
    assert err["input"] > settings.max_particles_per_run


@pytest.mark.timeout(60)
def test_too_many_particle_steps_is_refused(client, settings):
    body = {  # the quick preset in its former 50 x 50 x 100 mm cell: within the test's cap
        "reference": {"preset": "quick", "cell": [0.05, 0.05, 0.1]},
        "coarse_radii": [5e-3],
        "rules": ["paper"],
        "seeds": [1, 2, 3, 4, 5],
    }
    spec = engine.StudySpec.from_dict(body)
    assert engine.plan(spec).max_particles() <= settings.max_particles_per_run
    # the cap is on the worst case the bounds allow (service.cost): between one seed's and
    # five seeds'
    one = sum(c.particle_steps for c in worst_case({**body, "seeds": [1]}))
    five = sum(c.particle_steps for c in worst_case(body))
    settings.max_particle_steps = (one + five) / 2
    r = client.post("/studies", json=body)
    assert r.status_code == 422, r.text
    (err,) = r.json()["detail"]
    assert err["loc"] == ["body"] and "particle-steps" in err["msg"]
    # the same study with one seed is within the caps
    assert client.post("/studies", json={**body, "seeds": [1]}).status_code == 202


@pytest.mark.timeout(60)
def test_default_study_is_a_valid_body():
    body = StudyCreate.model_validate(engine.default_study().to_dict())
    spec = engine.StudySpec.from_dict(body.engine_dict())
    assert spec.to_dict() == engine.default_study().to_dict()


@pytest.mark.timeout(60)
def test_submit_list_read_and_unknown_ids(client):
    ids = []
    for _ in range(2):
        r = client.post("/studies", json=TINY)
        assert r.status_code == 202, r.text
        assert r.json()["status"] == "queued" and r.headers["location"].endswith(r.json()["id"])
        ids.append(r.json()["id"])
    listing = client.get("/studies").json()
    assert listing["count"] == 2 and [s["id"] for s in listing["data"]] == ids[::-1]
    study = client.get(f"/studies/{ids[0]}").json()
    assert study["n_runs"] == 2 and [r["key"] for r in study["runs"]] == [
        "ref-s1",
        "r3.1mm-paper-s1",
    ]
    assert study["progress"] == 0.0 and study["attempts"] == 0 and study["name"] == "tiny"
    assert 0 < study["max_particles"] <= 100
    assert study["spec"]["reference"]["cell"] == [0.015, 0.015, 0.03]
    assert study["spec"]["rules"][0] == {
        "name": "paper",
        "stiffness_exponent": 1.0,
        "adhesion_exponent": 2.0,
        "dt": "fixed",
        "adhesive_exponent": None,
    }
    for bad, status in ((str(uuid.uuid4()), 404), ("not-a-uuid", 422)):
        for method, url in (
            ("get", ""),
            ("get", "/summary"),
            ("get", "/curves"),
            ("get", "/plots/stress_strain.png"),
            ("get", "/results.h5"),
            ("post", "/cancel"),
            ("delete", ""),
        ):
            r = client.request(method.upper(), f"/studies/{bad}{url}")
            assert r.status_code == status, (method, url, r.text)


@pytest.mark.timeout(60)
def test_results_of_an_unfinished_study_are_409_and_cancel_of_queued(client):
    sid = client.post("/studies", json=TINY).json()["id"]
    for url in ("/summary", "/curves", "/plots/stress_strain.png", "/results.h5"):
        r = client.get(f"/studies/{sid}{url}")
        assert r.status_code == 409 and "queued" in r.json()["detail"], (url, r.text)
    assert client.delete(f"/studies/{sid}").status_code == 409
    r = client.post(f"/studies/{sid}/cancel")
    assert r.status_code == 202 and r.json()["status"] == "cancelled"
    assert {x["status"] for x in client.get(f"/studies/{sid}").json()["runs"]} == {"cancelled"}
    assert client.post(f"/studies/{sid}/cancel").status_code == 409
    assert client.get(f"/studies/{sid}/summary").status_code == 409
    assert client.delete(f"/studies/{sid}").status_code == 204
    assert client.get(f"/studies/{sid}").status_code == 404


@pytest.mark.timeout(60)
def test_health_and_openapi_docs(client):
    health = client.get("/healthz").json()
    assert health["status"] == "ok" and health["studies"]["queued"] == 0
    assert client.get("/docs").status_code == 200
    paths = client.get("/openapi.json").json()["paths"]
    for p in (
        "/studies",
        "/studies/{study_id}",
        "/studies/{study_id}/summary",
        "/studies/{study_id}/curves",
        "/studies/{study_id}/plots/{kind}.png",
        "/studies/{study_id}/results.h5",
        "/studies/{study_id}/cancel",
        "/healthz",
    ):
        assert p in paths, p


@pytest.mark.timeout(60)
def test_an_eepa_study_is_accepted_and_an_untagged_law_stays_bilinear(client):
    law = {"type": "EEPA", "k1": 5e5, "k2": 2.5e6, "f0": -0.05, "n": 1.5, "chi": 1.5}
    body = with_changes(("reference", "pair_law"), law)
    body["rules"] = ["similarity", "paper"]
    r = client.post("/studies", json=body)
    assert r.status_code == 202, r.text
    spec = client.get(f"/studies/{r.json()['id']}").json()["spec"]
    assert spec["reference"]["pair_law"]["type"] == "EEPA"
    assert spec["reference"]["pair_law"]["n"] == 1.5
    assert spec["rules"][0]["stiffness_exponent"] is None  # similarity: 2 - n for the law
    untagged = {k: v for k, v in TINY["reference"]["pair_law"].items() if k != "type"}
    r = client.post("/studies", json=with_changes(("reference", "pair_law"), untagged))
    assert r.status_code == 202, r.text
    spec = client.get(f"/studies/{r.json()['id']}").json()["spec"]
    assert spec["reference"]["pair_law"]["type"] == "BilinearAdhesive"


@pytest.mark.timeout(120)
def test_the_default_study_is_admitted_by_the_default_service(tmp_path):
    """The main job submits ``engine.default_study()`` to a service at its default limits:
    its worst case (every stage to its bound, the decide round's budget included) must be
    within them, costed at the time step each run takes."""
    from service.admission import admit_spec
    from service.cost import reference_dt
    from service.settings import Settings

    spec = engine.default_study()
    admitted = admit_spec(spec.to_dict(), Settings(data_dir=tmp_path))
    worst = sum(c.particle_steps for c in admitted.costs)
    assert worst <= Settings(data_dir=tmp_path).max_particle_steps
    assert reference_dt(spec.to_dict()["reference"]) == spec.reference.resolved_dt()
