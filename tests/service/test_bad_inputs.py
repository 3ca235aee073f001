"""Every bad input issue 42 found, replayed against the API: each gets one clear 4xx that
names the field the client gave (a 422 with one error at that JSON path), or the 400 the
documentation promises for a body that is not UTF-8 JSON. No worker runs."""

from __future__ import annotations

import json

import pytest

from .conftest import TINIEST, TINY, changed

#: A calibration the service accepts (3 design runs and the check run of TINIEST's K1).
CALIBRATION = {
    "test": TINIEST["reference"],
    "targets": {"tester": "uniaxial", "loading_stiffness": 1e6, "loading_stiffness_sd": 2e5},
    "parameters": {"k1": [3e3, 2e4]},
    "runs": 3,
    "waves": 0,
}


#: The quick preset in a cell within the test settings' particle cap.
SMALL_QUICK = {"preset": "quick", "cell": [0.05, 0.05, 0.1]}


def law(**fields) -> dict:
    return {**TINY["reference"]["pair_law"], **fields}


#: (what, path, body, the loc of the one error, a word of its message)
UNPROCESSABLE = [
    # a study needs its reference: a preset named or the pair law given
    (
        "study without a reference",
        "/studies",
        changed(TINY, ("reference",), ...),
        ["reference"],
        "required",
    ),
    (
        "reference of defaults alone",
        "/studies",
        changed(TINY, ("reference",), {"radius": 2.5e-3}),
        ["reference"],
        "preset",
    ),
    # a coarse radius finer than the reference's
    (
        "coarse radius finer than the reference",
        "/studies",
        {"reference": {"preset": "quick"}, "coarse_radii": [0.001]},
        ["coarse_radii", 0],
        "reference radius",
    ),
    # a time step the laws cannot take is the time step's error, not output_interval's
    (
        "reference.dt = 1",
        "/studies",
        changed(TINY, ("reference", "dt"), 1.0),
        ["reference", "dt"],
        "stable limit",
    ),
    # K1 = 1e300 N/m is K1's error (beyond any time step), not K2's
    (
        "k1 = 1e300",
        "/studies",
        # at a fixed time step (with dt left to the laws, K1 = 1e300 N/m breaks only k2 >= k1)
        changed(changed(TINY, ("reference", "pair_law"), law(k1=1e300)), ("reference", "dt"), 1e-5),
        ["reference", "pair_law", "BilinearAdhesive", "k1"],
        "time step",
    ),
    # a rule broken by a field given and one left to the preset: the one given is named
    (
        "pre_stress above the preset's consolidation stress",
        "/studies",
        {"reference": {**SMALL_QUICK, "pre_stress": 3e4}, "coarse_radii": [5e-3]},
        ["reference", "pre_stress"],
        "consolidation_stress",
    ),
    (
        "a platen speed the preset's output_interval cannot sample",
        "/studies",
        {"reference": {**SMALL_QUICK, "platen_speed": 100.0}, "coarse_radii": [5e-3]},
        ["reference", "platen_speed"],
        "output_interval",
    ),
    # a NaN is one error at its field, inside a tagged union too
    (
        "NaN in the pair law",
        "/studies",
        b'{"reference": {"preset": "quick", "pair_law": {"k1": NaN, "k2": 2.5e4}}, '
        b'"coarse_radii": [5e-3]}',
        ["reference", "pair_law", "BilinearAdhesive", "k1"],
        "finite",
    ),
    (
        "NaN in an EEPA law",
        "/studies",
        b'{"reference": {"preset": "quick", "pair_law": {"type": "EEPA", "k1": NaN, '
        b'"k2": 2.5e6, "n": 1.5}}, "coarse_radii": [5e-3]}',
        ["reference", "pair_law", "EEPA", "k1"],
        "finite",
    ),
    (
        "Infinity in a radius",
        "/studies",
        b'{"reference": {"preset": "quick"}, "coarse_radii": [Infinity]}',
        ["coarse_radii", 0],
        "finite",
    ),
    # a calibration needs its test, and every target its uncertainty
    (
        "calibration without a test",
        "/calibrations",
        changed(CALIBRATION, ("test",), ...),
        ["test"],
        "required",
    ),
    (
        "a target without its sd",
        "/calibrations",
        changed(CALIBRATION, ("targets", "loading_stiffness_sd"), ...),
        ["targets", "loading_stiffness_sd"],
        "uncertainty",
    ),
    (
        "a porosity point without its sd",
        "/calibrations",
        changed(
            CALIBRATION,
            ("targets",),
            {"tester": "uniaxial", "compression": [{"stress": 1e4, "porosity": 0.42}]},
        ),
        ["targets", "compression", 0, "sd"],
        "required",
    ),
    # a calibration box beyond the law's own bounds, or the test's time step
    (
        "a box to K1 = 1e300",
        "/calibrations",
        changed(CALIBRATION, ("parameters",), {"k1": [3e3, 1e300]}),
        ["parameters", "k1"],
        "high end",
    ),
    (
        "a box beyond the time step",
        "/calibrations",
        {**CALIBRATION, "parameters": {"k1": [3e3, 2e4], "k2": [2.5e4, 1e12]}, "runs": 4},
        ["parameters", "k2"],
        "time step",
    ),
]


@pytest.mark.parametrize(
    "what,path,body,loc,word", UNPROCESSABLE, ids=[c[0] for c in UNPROCESSABLE]
)
def test_a_bad_body_gets_one_422_naming_the_field_given(client, what, path, body, loc, word):
    if isinstance(body, bytes):
        r = client.post(path, content=body, headers={"content-type": "application/json"})
    else:
        r = client.post(path, json=body)
    assert r.status_code == 422, r.text
    errors = r.json()["detail"]
    assert len(errors) == 1, errors  # once
    (e,) = errors
    assert e["loc"] == ["body", *loc], e
    assert word in e["msg"], e
    assert client.get(path).json()["count"] == 0  # nothing stored


#: Bodies that are not UTF-8 JSON: a 400 ``{"detail": ...}`` (docs/SERVICE.md).
NOT_JSON = [
    ("Latin-1", '{"name": "café"}'.encode("latin-1"), "application/json", "not UTF-8"),
    ("UTF-16", json.dumps(TINY).encode("utf-16"), "application/json", "not UTF-8"),
    ("a byte order mark", b"\xef\xbb\xbf" + json.dumps(TINY).encode(), "application/json", "byte"),
    ("a syntax error", b'{"name": ', "application/json", "not JSON"),
    ("Latin-1 without a media type", '{"name": "café"}'.encode("latin-1"), None, "not UTF-8"),
    ("a form", b"name=x", "application/x-www-form-urlencoded", "application/json"),
]


@pytest.mark.parametrize("path", ["/studies", "/calibrations"])
@pytest.mark.parametrize("what,body,media,word", NOT_JSON, ids=[c[0] for c in NOT_JSON])
def test_a_body_that_is_not_utf8_json_is_400(client, path, what, body, media, word):
    headers = {"content-type": media} if media else {}
    r = client.post(path, content=body, headers=headers)
    assert r.status_code == 400, r.text
    assert word in r.json()["detail"]


def test_results_of_a_study_not_run_yet(client):
    sid = client.post("/studies", json=TINY).json()["id"]
    # an unknown plot kind (or stage) is a 422 whatever the study's status, as documented
    r = client.get(f"/studies/{sid}/plots/bogus.png")
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["path", "kind"]
    r = client.get(f"/studies/{sid}/curves", params={"kind": "bogus"})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["query", "kind"]
    # a known one of a study that has not succeeded: 409
    for url in ("plots/stress_strain.png", "curves", "summary", "results.h5"):
        r = client.get(f"/studies/{sid}/{url}")
        assert r.status_code == 409 and "queued" in r.json()["detail"], url


def test_the_good_bodies_here_are_accepted(client):
    # the replays above differ from these in the one field they name
    assert client.post("/studies", json=TINY).status_code == 202
    assert client.post("/calibrations", json=CALIBRATION).status_code == 202
