"""Scaling rules, error metrics, and a tiny study end to end."""

from __future__ import annotations

import math

import numpy as np
import pytest

import engine
from engine import metrics
from engine.study import advise
from tests.engine.test_uniaxial import COHESIVE, tiny


def test_rules_scale_the_parameters_they_promise():
    ref = engine.preset("quick", pair_law=COHESIVE)
    coarse = engine.ScalingRule("p", 1.0, 2.0).apply(ref, 2 * ref.radius, 1e-5)
    assert coarse.radius == 2 * ref.radius
    assert coarse.pair_law.k1 == pytest.approx(2 * COHESIVE.k1)
    assert coarse.pair_law.k2 == pytest.approx(2 * COHESIVE.k2)
    assert coarse.pair_law.kt == pytest.approx(2 * COHESIVE.kt)
    assert coarse.pair_law.f0 == pytest.approx(4 * COHESIVE.f0)
    assert coarse.pair_law.mu_s == COHESIVE.mu_s and coarse.pair_law.restitution == 0.4
    assert coarse.dt == 1e-5 and coarse.wall_law == ref.wall_law
    cubic = engine.ScalingRule.named("cubic_adhesion", dt="scaled").apply(ref, 1.5 * ref.radius,
                                                                         1e-5)
    assert cubic.pair_law.f0 == pytest.approx(1.5**3 * COHESIVE.f0)
    assert cubic.dt == pytest.approx(1.5e-5)
    uns = engine.ScalingRule.named("unscaled").apply(ref, 2 * ref.radius, 1e-5)
    assert uns.pair_law.k1 == COHESIVE.k1 and uns.pair_law.f0 == COHESIVE.f0


def test_nrmse_zero_for_identical_and_known_for_shifted():
    x = np.linspace(0.0, 2.0, 50)
    assert metrics.nrmse(x, x) == 0.0
    assert metrics.nrmse(x + 0.1, x) == pytest.approx(0.1 / 2.0)
    # normalised by the range, not the magnitude: 0.45..0.50 off by 0.005 is 10 %
    y = np.linspace(0.45, 0.50, 20)
    assert metrics.nrmse(y + 0.005, y) == pytest.approx(0.1)
    assert metrics.nrmse(np.full(5, 3.3), np.full(5, 3.0)) == pytest.approx(0.1)  # flat
    with pytest.raises(ValueError):
        metrics.nrmse(x, np.zeros_like(x))


def _fake_result(strain_shift=0.0, porosity_scale=1.0, strength=1000.0):
    """A UniaxialResult with analytic confined curves (for the metric, not the engine)."""
    s_load = np.linspace(5e3, 2e4, 30)
    s_unl = np.linspace(2e4, 100.0, 20)
    def curves(stress, strain):
        return {"stress_top": stress, "strain": strain + strain_shift,
                "porosity": porosity_scale * (0.5 - 0.1 * strain),
                "coordination": 4.0 + stress / 1e4}
    stages = {
        "consolidation": engine.StageResult("consolidation", curves(s_load, s_load / 1e6),
                                            None, None, 0),
        "unloading": engine.StageResult("unloading", curves(s_unl, 0.01 + s_unl / 4e6),
                                        None, None, 0),
    }
    return engine.UniaxialResult(tiny(), stages, {"unconfined_strength": strength})


def test_run_errors_on_analytic_curves():
    ref = _fake_result()
    same = metrics.run_errors(_fake_result(), ref)
    assert all(v == pytest.approx(0.0, abs=1e-12) for v in same.values())
    shifted = metrics.run_errors(_fake_result(strain_shift=0.002, strength=1500.0), ref)
    # reference strain range over both branches: 5e3/1e6 (start of loading) to 2e4/1e6
    strain_range = 2e4 / 1e6 - 5e3 / 1e6
    assert shifted["err_stress_strain"] == pytest.approx(0.002 / strain_range, rel=1e-6)
    assert shifted["err_coordination"] == pytest.approx(0.0, abs=1e-12)
    assert shifted["err_strength"] == pytest.approx(0.5)
    # cohesionless reference: relative to 5 % of the consolidation stress (20 kPa)
    assert metrics.strength_error(300.0, 0.0, 2e4) == pytest.approx(0.3)


def test_spec_validation_names_fields():
    ref = tiny()
    with pytest.raises(engine.ParameterError, match=r"coarse_radii\[0\]"):
        engine.StudySpec(reference=ref, coarse_radii=(ref.radius,))
    with pytest.raises(engine.ParameterError, match=r"coarse_radii\[1\]"):
        engine.StudySpec(reference=ref, coarse_radii=(3e-3, 8e-3))  # cell too small
    # refused before running: a time step above the stable limit, adhesion pulling contacts
    # too deep at the coarse radius, a fill the packer cannot place
    with pytest.raises(engine.ParameterError, match=r"UniaxialTest.dt .*stable limit"):
        tiny(dt=1e-3)
    with pytest.raises(engine.ParameterError, match=r"coarse_radii\[0\].*pair_law.f0"):
        engine.StudySpec(reference=engine.preset("quick", pair_law=engine.BilinearAdhesive(
            k1=5e3, k2=2.5e4, f0=-4.0)), coarse_radii=(1e-2,),
            rules=(engine.ScalingRule.named("cubic_adhesion"),))
    with pytest.raises(engine.ParameterError, match="fill_fraction"):
        engine.preset("quick", cell=(0.05, 0.05, 0.04), fill_fraction=0.32)
    assert engine.StudySpec(reference=tiny(seed=7), coarse_radii=(3.1e-3,)).seeds == (7,)
    with pytest.raises(engine.ParameterError, match="rules"):
        engine.StudySpec(reference=ref, rules=(engine.ScalingRule("x"), engine.ScalingRule("x")))
    with pytest.raises(engine.ParameterError, match="stiffness_exponent"):
        engine.ScalingRule("bad", stiffness_exponent=9)
    with pytest.raises(engine.ParameterError, match="ScalingRule.dt"):
        engine.ScalingRule("bad", dt="sometimes")
    with pytest.raises(engine.ParameterError, match="tolerance"):
        engine.StudySpec(reference=ref, tolerance=0)
    with pytest.raises(engine.ParameterError, match="seeds"):
        engine.StudySpec(reference=ref, seeds=(1, 1))
    spec = engine.default_study()
    again = engine.StudySpec.from_dict(spec.to_dict())
    assert again == spec
    short = engine.StudySpec.from_dict({"reference": {"preset": "quick", "radius": 2e-3},
                                        "coarse_radii": [4e-3], "rules": ["paper"]})
    assert short.reference.radius == 2e-3 and short.rules[0].adhesion_exponent == 2.0
    assert spec.estimated_particle_steps() > 0
    assert spec.max_particles() == spec.reference.n_particles


def test_advisor_picks_coarsest_within_tolerance_and_fits_exponent():
    spec = engine.StudySpec(reference=engine.preset("quick"), coarse_radii=(3e-3, 3.5e-3),
                            rules=(engine.ScalingRule("b1", 1, 1), engine.ScalingRule("b2", 1, 2),
                                   engine.ScalingRule("b3", 1, 3)), tolerance=0.2)
    groups = []
    for r in spec.coarse_radii:
        for rule in spec.rules:
            b = rule.adhesion_exponent
            strength = 1000.0 * (r / 2.5e-3) ** (b - 2.0)  # exact exponent b* = 2
            err = abs(strength - 1000.0) / 1000.0
            groups.append({"radius": r, "rule": rule.name, "stiffness_exponent": 1.0,
                           "adhesion_exponent": b, "dt": "fixed", "err_strength": err,
                           "unconfined_strength": strength, "speedup": 2.0,
                           "max_error": max(err, 0.05 * r / 3e-3)})
    adv = advise(spec, groups, reference_strength=1000.0)
    assert adv["rules"]["b2"]["coarsest_radius"] == 3.5e-3
    assert adv["rules"]["b1"]["coarsest_radius"] == 3e-3  # 3.5 mm: 30 % off
    for v in adv["adhesion_exponent"]["by_radius"].values():
        assert v["best"] == 2.0
        assert v["fitted"] == pytest.approx(2.0, abs=1e-9)


@pytest.fixture(scope="module")
def tiny_study():
    spec = engine.StudySpec(reference=tiny(pair_law=COHESIVE), coarse_radii=(3.1e-3,),
                            rules=(engine.ScalingRule.named("paper"),
                                   engine.ScalingRule.named("unscaled", dt="scaled")))
    seen = []
    return spec, engine.run_study(spec, progress=seen.append), seen


def test_tiny_study_end_to_end(tiny_study, tmp_path):
    _spec, res, seen = tiny_study
    assert list(res.runs) == ["ref-s1", "r3.1mm-paper-s1", "r3.1mm-unscaled-s1"]
    assert next(p.run_key for p in seen) == "ref-s1" and seen[-1].fraction == pytest.approx(1.0)
    ref = res.runs["ref-s1"]
    assert all(v == 0.0 for v in ref.errors.values())
    for row in res.table:
        for k, v in row.items():
            if isinstance(v, float):
                assert math.isfinite(v), (row["run"], k)
    coarse = res.runs["r3.1mm-unscaled-s1"]
    assert coarse.result.scalars["dt"] == pytest.approx(ref.result.scalars["dt"] * 3.1 / 2.5)
    assert coarse.result.scalars["particles"] < ref.result.scalars["particles"]
    assert coarse.speedup == pytest.approx(ref.result.scalars["wall_time"]
                                           / coarse.result.scalars["wall_time"])
    assert set(res.advisor["rules"]) == {"paper", "unscaled"}
    assert res.to_summary()["units"]["wall_time"] == "s"
    paths = res.save_plots(tmp_path)
    assert len(paths) == 5
    for p in paths:
        data = p.read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10_000


def test_callback_can_stop_a_study():
    spec = engine.StudySpec(reference=tiny(), coarse_radii=(3.1e-3,),
                            rules=(engine.ScalingRule.named("paper"),))
    with pytest.raises(engine.StopRequested):
        engine.run_study(spec, progress=lambda p: p.run_index == 0)
