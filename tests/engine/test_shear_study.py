"""Scaling judged in shear (issue 41 item 5; docs/PHYSICS.md section 11.1): a study whose
reference is a shear test plans its coarse runs with the rule's own scaling, its resolution
controls and protocol check; it runs (a tiny cell, seconds), judges the shear metrics with
the study's machinery and reports; its runs round-trip through storage; one rule's verdicts
on two tests are set side by side."""

from __future__ import annotations

import json
import math
from types import SimpleNamespace

import numpy as np
import pytest

import engine
from engine.shear.results import load_shear, save_shear
from engine.study.advice import side_by_side
from engine.study.metrics import SHEAR_METRICS, metric_values
from engine.study.plan import StudyPlan, plan
from engine.study.report import Verdict
from engine.study.results import assemble
from engine.study.spec import on_test
from tests.engine.test_shear import COHESIVE, tiny


def _spec(**kw) -> engine.StudySpec:
    base = {
        # a short pre-shear (0.3 strain at least, windows of 0.1): seconds per run
        "reference": tiny(
            pair_law=COHESIVE,
            normal_stresses=(3e3, 7e3),
            preshear_min_strain=0.3,
            steady_window=0.1,
        ),
        "coarse_radii": (3.1e-3,),
        "rules": (engine.ScalingRule.named("paper"), engine.ScalingRule.named("unscaled")),
        "reference_seeds": (1, 2),
        "seeds": (1, 2),
    }
    return engine.StudySpec(**{**base, **kw})


def test_a_shear_study_plans_the_rule_controls_and_protocol_check():
    spec = _spec()
    ref = spec.reference
    assert spec.tolerances == {k: m.tolerance for k, m in SHEAR_METRICS.items()}
    p = plan(spec)
    runs = {r.key: r for r in p.runs}
    assert list(runs)[:4] == ["ref-s1", "ref-s2", "half-s1", "half-s2"]
    s = 3.1 / 2.5
    paper = runs["r3.1mm-paper-s1"].test
    assert isinstance(paper, engine.ShearTest) and paper.radius == 3.1e-3
    # the rule's scaling, by the same code as the uniaxial test's: K ~ R, f0 ~ R^2
    assert paper.pair_law.k1 == pytest.approx(COHESIVE.k1 * s)
    assert paper.pair_law.k2 == pytest.approx(COHESIVE.k2 * s)
    assert paper.pair_law.f0 == pytest.approx(COHESIVE.f0 * s**2)
    assert paper.cell == ref.cell and paper.inertial_number == ref.inertial_number
    assert paper.max_stage_time == pytest.approx(ref.max_stage_time * s)
    unscaled = runs["r3.1mm-unscaled-s2"].test
    assert unscaled.pair_law == COHESIVE and unscaled.seed == 2
    # the control: the reference law in the cell scaled down, the fill's overburden kept
    ctl = runs["ctl-r3.1mm-s1"].test
    assert ctl.radius == ref.radius and ctl.pair_law == COHESIVE
    assert ctl.cell == pytest.approx(tuple(c / s for c in ref.cell))
    assert ctl.gravity == pytest.approx(ref.gravity * s)
    assert ctl.n_particles == pytest.approx(paper.n_particles, rel=0.05)
    # the protocol check: half the inertial number and half the step
    half = runs["half-s1"].test
    assert half.inertial_number == ref.inertial_number / 2
    assert half.dt_fraction == ref.dt_fraction / 2
    assert half.max_stage_time == 2 * ref.max_stage_time
    assert runs["half-s1"].particle_steps > 3 * runs["ref-s1"].particle_steps
    # the JSON forms name the shear test and read back; a uniaxial study's do not change
    d = json.loads(json.dumps(p.to_dict()))
    assert d["spec"]["reference"]["type"] == "ShearTest"
    assert StudyPlan.from_dict(d).to_dict() == d
    assert engine.StudySpec.from_dict(spec.to_dict()) == spec
    assert "type" not in engine.default_study().to_dict()["reference"]
    # a uniaxial metric's tolerance is not a shear study's
    with pytest.raises(engine.ParameterError, match=r"StudySpec\.tolerances"):
        _spec(tolerances={"strength": 0.1})
    with pytest.raises(engine.ParameterError, match=r"StudySpec\.reference\.type"):
        engine.StudySpec.from_dict({**spec.to_dict(), "reference": {"type": "Ring"}})


def test_the_shear_metrics_against_hand_numbers():
    test = tiny(normal_stresses=(2e3, 6e3))
    scalars = {
        "cohesion": 1000.0,
        "friction_angle": 45.0,
        "sigma_1": 12e3,
        "sigma_c": 4e3,
        "bulk_density": 1150.0,
    }
    v = metric_values(SimpleNamespace(test=test, scalars=scalars))
    assert set(v) == set(SHEAR_METRICS)
    assert v["yield_locus"] == pytest.approx([3000.0, 7000.0])  # c + sigma tan 45
    assert v["ffc"] == pytest.approx([3.0]) and v["bulk_density"] == pytest.approx([1150.0])
    # a cohesionless bed: sigma_c 0, ffc's denominator floored at 5 % of sigma_pre
    v = metric_values(SimpleNamespace(test=test, scalars={**scalars, "sigma_c": 0.0}))
    assert v["ffc"] == pytest.approx([12e3 / 500.0])


def test_side_by_side_combines_one_rules_verdicts_on_two_tests():
    uni = [
        Verdict(3e-3, "paper", "equivalent"),
        Verdict(3e-3, "unscaled", "differs"),
        Verdict(4e-3, "paper", "equivalent"),
    ]
    shear = [
        Verdict(3e-3, "paper", "equivalent"),
        Verdict(3e-3, "unscaled", "undecided"),
        Verdict(4e-3, "paper", "undecided"),
    ]
    rows = {(r["radius"], r["rule"]): r for r in side_by_side({"uniaxial": uni, "shear": shear})}
    assert rows[3e-3, "paper"]["verdict"] == "equivalent"
    assert rows[3e-3, "unscaled"]["verdict"] == "differs"
    assert rows[4e-3, "paper"]["verdict"] == "undecided"
    assert rows[4e-3, "paper"]["tests"] == {"uniaxial": "equivalent", "shear": "undecided"}
    # the second study of a rule: the same design on the other test
    spec = _spec()
    uniaxial = engine.preset("quick", pair_law=COHESIVE)
    other = on_test(spec, uniaxial)
    assert other.reference == uniaxial and other.rules == spec.rules
    assert other.coarse_radii == spec.coarse_radii and other.seeds == spec.seeds
    assert set(other.tolerances) == set(engine.METRICS)
    with pytest.raises(engine.ParameterError, match="radius"):
        on_test(spec, engine.preset("quick", pair_law=COHESIVE, radius=2e-3))


def test_a_shear_study_refuses_run_options_the_shear_test_lacks():
    with pytest.raises(engine.ParameterError, match=r"RunOptions\.max_run_wall_time"):
        engine.run_study(_spec(), max_run_wall_time=10.0)


def test_a_tiny_shear_study_runs_judges_and_reports(tmp_path):
    spec = _spec(rules=(engine.ScalingRule.named("paper"),), protocol_check=False)
    stored = {}
    res = engine.run_study(spec, on_run=stored.__setitem__)
    planned = [r.key for r in plan(spec).runs]
    assert set(stored) == set(planned)
    # every run finished or is listed with its error; the references finished
    assert set(res.runs) | set(res.failed) == set(planned)
    assert {"ref-s1", "ref-s2"} <= set(res.runs)
    for k, text in res.failed.items():
        assert isinstance(stored[k], str) and text == stored[k]
    ref = res.runs["ref-s1"].result
    for run in res.runs.values():
        s = run.result.scalars
        assert isinstance(run.result, engine.ShearResult)
        assert s["particle_steps"] == s["particles"] * s["steps"]
        if run.rule is not None:  # the paper rule: the step at its fraction of t_c ~ R
            assert s["dt"] == pytest.approx(ref.scalars["dt"] * 3.1 / 2.5, rel=1e-9)
        elif run.control:  # the reference law: the reference's step
            assert s["dt"] == ref.scalars["dt"]
    rep = res.report
    (v,) = rep.verdicts
    assert v.rule == "paper" and v.verdict in ("equivalent", "differs", "undecided")
    if v.metrics:
        assert [m.metric for m in v.metrics] == list(SHEAR_METRICS)
    assert set(rep.noise_floor) == set(SHEAR_METRICS)
    assert all(x is not None and math.isfinite(x) for x in rep.noise_floor.values())
    assert [r.radius for r in rep.resolution] == [3.1e-3]
    # the paper rule is the law's exact similarity: against its control a check of units
    assert "a check of units, not evidence for the rule" in rep.message
    assert "output_interval" in rep.message
    # the shear study's figures (engine.io.figures.SHEAR_KINDS), not the uniaxial curves
    plots = res.save_plots(tmp_path / "plots")
    assert [p.stem for p in plots] == ["yield_locus", "preshear", "error_vs_runtime", "resolution"]
    summary = json.loads(json.dumps(res.to_summary(), default=float))
    assert summary["units"]["err_ffc"] == "1" and "err_strength" not in summary["units"]
    for row in res.table:
        assert row["err_yield_locus"] >= 0 and row["overburden_ratio"] == 0.0
    # the runs stored and read back give the same table and verdicts
    back = {}
    for k, r in stored.items():
        if isinstance(r, str):
            back[k] = r
            continue
        save_shear(tmp_path / f"{k}.json", r)
        back[k] = load_shear(tmp_path / f"{k}.json", curves=True)
        assert set(back[k].stages) == set(r.stages)
        assert np.array_equal(
            back[k].stages["preshear"].curves["shear_stress"],
            r.stages["preshear"].curves["shear_stress"],
        )
    again = assemble(spec, plan(spec).runs, back)
    assert again.report.verdicts == rep.verdicts
    assert again.table == res.table
