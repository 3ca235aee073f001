"""POST /plans: the planner through the API (issue 50 item 4), inputs validated like the
rest (422 naming the field), answered at once."""

from __future__ import annotations

BODY = {
    "pair_law": {"type": "BilinearAdhesive", "k1": 50.0, "k2": 250.0, "f0": -4e-5},
    "diameter": 5e-5,
    "feature_width": 0.2,
    "stress": 2e4,
}


def test_a_plan_answers_per_feature_kind(client):
    r = client.post("/plans", json=BODY)
    assert r.status_code == 200, r.text
    plan = r.json()
    assert plan["matched_series"] == "bond1"
    assert plan["features"][0]["kind"] == "bulk_shear"
    assert plan["features"][0]["s_max"] > 1


def test_bad_plans_are_422_naming_the_field(client):
    for change, where in (
        ({"feature_width": -1}, "feature_width"),
        ({"feature_kind": "hopper"}, "feature_kind"),
        ({"pair_law": {"type": "HertzMindlin", "E": 1e8}}, "pair_law"),
        ({"diameter": "big"}, "diameter"),
    ):
        r = client.post("/plans", json={**BODY, **change})
        assert r.status_code == 422, (change, r.text)
        assert where in str(r.json()["detail"][0]["loc"]), r.json()
