"""A study's plots are those of its kind of test (issue 53 item 4): its links, its
``plot_kinds`` and its page list no plot of the other test, and a request for one is a
404 that names the plots it has, whatever the study's status. Queued studies only (their
spec says which plots they will have): no run."""

from __future__ import annotations

from engine.io.figures import UNIAXIAL_KINDS
from service.spec import SHEAR_EXAMPLE

from .conftest import TINY

SHEAR_ONLY = {"yield_locus", "preshear"}
UNIAXIAL_ONLY = {"stress_strain", "stress_porosity", "coordination", "unconfined"}


def submit(client, body) -> dict:
    r = client.post("/studies", json=body)
    assert r.status_code == 202, r.text
    return r.json()


def plot_links(links: dict) -> set[str]:
    return {k.removeprefix("plot_") for k in links if k.startswith("plot_")}


def test_a_uniaxial_study_has_no_shear_plot(client):
    made = submit(client, {**TINY, "controls": True})
    sid = made["id"]
    kinds = list(UNIAXIAL_KINDS)  # all six: with the unconfined stage and controls
    assert plot_links(made["links"]) == set(kinds)
    detail = client.get(f"/studies/{sid}").json()
    assert detail["plot_kinds"] == kinds and plot_links(detail["links"]) == set(kinds)
    listed = next(s for s in client.get("/studies").json()["data"] if s["id"] == sid)
    assert plot_links(listed["links"]) == set(kinds)
    for kind in SHEAR_ONLY:
        r = client.get(f"/studies/{sid}/plots/{kind}.png")
        assert r.status_code == 404, r.text
        detail_text = r.json()["detail"]
        assert f"no {kind} plot" in detail_text and "uniaxial" in detail_text
        assert all(k in detail_text for k in kinds), detail_text
    # one of its own kinds: not yet (409), an unknown one: 422
    assert client.get(f"/studies/{sid}/plots/stress_strain.png").status_code == 409
    assert client.get(f"/studies/{sid}/plots/histogram.png").status_code == 422


def test_a_uniaxial_study_without_the_stage_or_controls_lacks_those_plots(client):
    body = {**TINY, "reference": {**TINY["reference"], "unconfined": False}}
    sid = submit(client, body)["id"]
    kinds = client.get(f"/studies/{sid}").json()["plot_kinds"]
    assert kinds == ["stress_strain", "stress_porosity", "coordination", "error_vs_runtime"]
    for kind in ("unconfined", "resolution"):
        r = client.get(f"/studies/{sid}/plots/{kind}.png")
        assert r.status_code == 404 and "its plots: stress_strain" in r.json()["detail"]


def test_a_shear_study_has_no_uniaxial_plot(client):
    made = submit(client, SHEAR_EXAMPLE)
    sid = made["id"]
    kinds = client.get(f"/studies/{sid}").json()["plot_kinds"]
    assert SHEAR_ONLY <= set(kinds) and not UNIAXIAL_ONLY & set(kinds)
    assert plot_links(made["links"]) == set(kinds)
    r = client.get(f"/studies/{sid}/plots/stress_strain.png")
    assert r.status_code == 404
    assert "this shear study has no stress_strain plot" in r.json()["detail"]
    assert "yield_locus" in r.json()["detail"]
    # the OpenAPI document says so
    doc = client.get("/openapi.json").json()
    plot = doc["paths"]["/studies/{study_id}/plots/{kind}.png"]["get"]
    assert "404" in plot["responses"] and "a 404 naming the kinds it has" in plot["description"]
