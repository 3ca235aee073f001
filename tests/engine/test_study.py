"""Scaling rules, the study spec, the report, and tiny studies end to end (in process and
on a process pool)."""

from __future__ import annotations

import concurrent.futures as cf
import json
import math
import multiprocessing as mp

import numpy as np
import pytest

import engine
from engine.io.store import strict_json
from engine.study import metrics
from engine.study.adhesion import adhesion_advice
from engine.study.advice import rule_answers
from engine.study.judge import VERDICTS
from engine.study.report import Verdict
from tests.engine.test_uniaxial import COHESIVE, tiny


def test_rules_scale_the_parameters_they_promise():
    ref = engine.preset("quick", protocol="seed", pair_law=COHESIVE)  # a fixed dt of 1e-5 s
    coarse = engine.ScalingRule("p", 1.0, 2.0).apply(ref, 2 * ref.radius, 1e-5)
    assert coarse.radius == 2 * ref.radius
    assert coarse.pair_law.k1 == pytest.approx(2 * COHESIVE.k1)
    assert coarse.pair_law.k2 == pytest.approx(2 * COHESIVE.k2)
    assert coarse.pair_law.kt == pytest.approx(2 * COHESIVE.kt)
    assert coarse.pair_law.f0 == pytest.approx(4 * COHESIVE.f0)
    assert coarse.pair_law.mu_s == COHESIVE.mu_s and coarse.pair_law.restitution == 0.4
    assert coarse.dt == 1e-5 and coarse.wall_law == ref.wall_law
    cubic = engine.ScalingRule.named("cubic_adhesion", dt="scaled").apply(
        ref, 1.5 * ref.radius, 1e-5
    )
    assert cubic.pair_law.f0 == pytest.approx(1.5**3 * COHESIVE.f0)
    assert cubic.dt == pytest.approx(1.5e-5)
    uns = engine.ScalingRule.named("unscaled").apply(ref, 2 * ref.radius, 1e-5)
    assert uns.pair_law.k1 == COHESIVE.k1 and uns.pair_law.f0 == COHESIVE.f0
    # with the time step a fraction of the contact time (the default protocol), "fixed"
    # keeps that fraction: each coarse run steps at its own critical time's fraction, which
    # under the paper rule grows as s (sqrt(m / K), m ~ s^3, K ~ s) where the pair sets it
    frac = engine.preset("quick", pair_law=COHESIVE)
    assert frac.dt is None
    own = engine.ScalingRule("p", 1.0, 2.0).apply(frac, 2 * frac.radius, frac.resolved_dt())
    assert own.dt is None and own.dt_fraction == frac.dt_fraction
    assert own.resolved_dt() > 1.5 * frac.resolved_dt()


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


def test_spec_validation_names_fields():
    ref = tiny()
    with pytest.raises(engine.ParameterError, match=r"coarse_radii\[0\]"):
        engine.StudySpec(reference=ref, coarse_radii=(ref.radius,))
    # what spans records is checked when the study is planned (the spec is a plain record)
    too_big = engine.StudySpec(reference=ref, coarse_radii=(3e-3, 8e-3))  # cell too small
    with pytest.raises(engine.ParameterError, match=r"coarse_radii\[1\]"):
        engine.plan(too_big)
    # refused before running: a time step above the stable limit, adhesion pulling contacts
    # too deep at the coarse radius, a fill the packer cannot place
    with pytest.raises(engine.ParameterError, match=r"UniaxialTest.dt .*stable limit"):
        tiny(dt=1e-3)
    with pytest.raises(engine.ParameterError, match=r"coarse_radii\[0\].*pair_law.f0"):
        engine.plan(
            engine.StudySpec(
                reference=engine.preset(
                    "quick", pair_law=engine.BilinearAdhesive(k1=5e3, k2=2.5e4, f0=-4.0)
                ),
                coarse_radii=(1e-2,),
                rules=(engine.ScalingRule.named("cubic_adhesion"),),
            )
        )
    with pytest.raises(engine.ParameterError, match="pour_fraction"):
        engine.preset("quick", solid_fraction=0.3, pour_fraction=0.32)
    one = engine.StudySpec(reference=tiny(seed=7), coarse_radii=(3.1e-3,))
    assert one.seeds == (7,) and one.reference_seeds == (7,)
    two = engine.StudySpec(
        reference=tiny(), coarse_radii=(3.1e-3,), seeds=(1,), reference_seeds=(1, 2, 3)
    )
    runs = engine.plan(two).runs
    assert [p.key for p in runs][:3] == ["ref-s1", "ref-s2", "ref-s3"]
    # one interior window for the study: two diameters of its largest particle, every run
    # (a resolution control: scaled with its cell by R_ref / R_c)
    assert [p.test.interior_margin for p in runs] == pytest.approx(
        [4 * 3.1e-3 * (2.5 / 3.1 if p.control else 1.0) for p in runs]
    )
    assert two.reference.interior_margin is None  # the study's, not the reference's own
    assert two.tolerances == engine.DEFAULT_TOLERANCES
    with pytest.raises(engine.ParameterError, match="rules"):
        engine.StudySpec(reference=ref, rules=(engine.ScalingRule("x"), engine.ScalingRule("x")))
    with pytest.raises(engine.ParameterError, match="stiffness_exponent"):
        engine.ScalingRule("bad", stiffness_exponent=9)
    with pytest.raises(engine.ParameterError, match="ScalingRule.dt"):
        engine.ScalingRule("bad", dt="sometimes")
    with pytest.raises(engine.ParameterError, match="tolerances.density"):
        engine.StudySpec(reference=ref, coarse_radii=(3e-3,), tolerances={"density": 0})
    with pytest.raises(engine.ParameterError, match="tolerances"):
        engine.StudySpec(reference=ref, coarse_radii=(3e-3,), tolerances={"porosity": 0.1})
    loose = engine.StudySpec(reference=ref, coarse_radii=(3e-3,), tolerances={"strength": 0.3})
    assert loose.tolerances["strength"] == 0.3 and loose.tolerances["density"] == 0.03
    with pytest.raises(engine.ParameterError, match="interior_diameters"):
        engine.StudySpec(reference=ref, coarse_radii=(3e-3,), interior_diameters=1)
    with pytest.raises(engine.ParameterError, match="seeds"):
        engine.StudySpec(reference=ref, coarse_radii=(3e-3,), seeds=(1, 1))
    spec = engine.default_study()
    again = engine.StudySpec.from_dict(spec.to_dict())
    assert again == spec
    short = engine.StudySpec.from_dict(
        {
            "reference": {"preset": "quick", "radius": 2e-3},
            "coarse_radii": [4e-3],
            "rules": ["paper"],
        }
    )
    assert short.reference.radius == 2e-3 and short.rules[0].adhesion_exponent == 2.0
    assert engine.plan(spec).estimated_particle_steps() > 0
    assert engine.plan(spec).max_particles() == spec.reference.n_particles


def test_report_picks_coarsest_equivalent_and_fits_exponent():
    spec = engine.StudySpec(
        reference=engine.preset("quick"),
        coarse_radii=(3e-3, 3.5e-3),
        rules=(
            engine.ScalingRule("b1", 1, 1),
            engine.ScalingRule("b2", 1, 2),
            engine.ScalingRule("b3", 1, 3),
        ),
    )
    groups, verdicts = [], []
    for r in spec.coarse_radii:
        for rule in spec.rules:
            b = rule.adhesion_exponent
            strength = 1000.0 * (r / 2.5e-3) ** (b - 2.0)  # exact exponent b* = 2
            err = abs(strength - 1000.0) / 1000.0
            groups.append(
                {
                    "radius": r,
                    "rule": rule.name,
                    "stiffness_exponent": 1.0,
                    "adhesion_exponent": b,
                    "dt": "fixed",
                    "err_strength": err,
                    "unconfined_strength": strength,
                    "speedup": 2.0,
                    "thickness_diameters": 12.0,
                }
            )
            verdicts.append(Verdict(r, rule.name, "equivalent" if err < 0.2 else "differs"))
    rules = rule_answers(spec, groups, verdicts)
    assert rules["b2"].coarsest_radius == 3.5e-3
    assert rules["b1"].coarsest_radius == 3e-3  # 3.5 mm: 30 % off
    for v in adhesion_advice(spec, groups, reference_strength=1000.0).by_radius.values():
        assert v.best == 2.0
        assert v.fitted == pytest.approx(2.0, abs=1e-9)
    assert adhesion_advice(spec, groups, None).by_radius


def _tiny_spec(**kw):
    return engine.StudySpec(
        reference=tiny(pair_law=COHESIVE),
        coarse_radii=(3.1e-3,),
        rules=(
            engine.ScalingRule.named("paper"),
            engine.ScalingRule.named("unscaled", dt="scaled"),
        ),
        reference_seeds=(1, 2),
        seeds=(1,),
        **kw,
    )


@pytest.fixture(scope="module")
def tiny_study():
    spec = _tiny_spec()
    seen, stored = [], {}
    res = engine.run_study(spec, progress=seen.append, on_run=lambda k, r: stored.setdefault(k, r))
    return spec, res, seen, stored


def test_tiny_study_end_to_end(tiny_study, tmp_path):
    spec, res, seen, stored = tiny_study
    keys = [
        "ref-s1",
        "ref-s2",
        "half-s1",
        "half-s2",
        "r3.1mm-paper-s1",
        "r3.1mm-unscaled-s1",
        "ctl-r3.1mm-s1",
    ]
    assert list(res.runs) == keys and list(stored) == keys and not res.failed
    # the protocol check: the reference seeds at half the platen speed and half the step,
    # judged against the references, paired by seed
    half = stored["half-s1"]
    assert half.scalars["dt"] == pytest.approx(stored["ref-s1"].scalars["dt"] / 2)
    assert half.test.platen_speed == pytest.approx(stored["ref-s1"].test.platen_speed / 2)
    check = res.report.protocol
    assert check.rule == "protocol" and check.paired_seeds == 2
    assert {m.metric for m in check.metrics} == set(engine.METRICS)
    assert any(line.startswith("protocol check: ") for line in res.report.control_lines)
    assert res.runs["half-s1"].label == "protocol" and not res.runs["half-s1"].is_reference
    assert next(p.run_key for p in seen) == "ref-s1" and seen[-1].fraction == pytest.approx(1.0)
    for k in ("ref-s1", "ref-s2"):
        assert all(v == 0.0 for v in res.runs[k].errors.values())
    for row in res.table:
        for k, v in row.items():
            if isinstance(v, float):
                assert math.isfinite(v), (row["run"], k)
        assert row["thickness_diameters"] > 0 and row["height_diameters"] > 0
    ref = res.runs["ref-s1"]
    coarse = res.runs["r3.1mm-unscaled-s1"]
    assert coarse.result.scalars["dt"] == pytest.approx(ref.result.scalars["dt"] * 3.1 / 2.5)
    assert coarse.result.scalars["particles"] < ref.result.scalars["particles"]
    mean_ref_wall = np.median([res.runs[k].result.scalars["wall_time"] for k in keys[:2]])
    assert coarse.speedup == pytest.approx(mean_ref_wall / coarse.result.scalars["wall_time"])
    rep = res.report
    assert set(rep.rules) == {"paper", "unscaled"}
    assert {(v.radius, v.rule) for v in rep.verdicts} == {(3.1e-3, "paper"), (3.1e-3, "unscaled")}
    for v in rep.verdicts:
        assert v.verdict in VERDICTS and v.reason
        assert {m.metric for m in v.metrics} == set(engine.METRICS)
    assert set(rep.noise_floor) == set(engine.METRICS)
    assert all(x is not None and x >= 0 for x in rep.noise_floor.values())
    # 15 mm cell, 6.2 mm particles: 2.4 diameters, the finite-size warning
    assert any("R = 3.1 mm" in w for w in rep.warnings)
    # the report's JSON text reads back to the same report (the same JSON)
    text = strict_json(res.to_summary()["advisor"])
    assert strict_json(type(rep).from_dict(json.loads(text)).to_dict()) == text
    assert res.to_summary()["units"]["wall_time"] == "s"
    paths = res.save_plots(tmp_path)
    assert len(paths) == 6  # with the resolution curve: controls are on by default
    for p in paths:
        data = p.read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10_000
    # the verdicts recomputed from the stored runs are the same
    again = engine.study.results.assemble(spec, engine.plan(spec).runs, stored)
    assert again.report.verdicts == rep.verdicts


def test_process_pool_gives_the_same_table_and_resumes(tiny_study):
    spec, res, _, stored = tiny_study
    ctx = mp.get_context("spawn")
    deciding = _tiny_spec(decide=True, rounds=1, max_seeds=2, max_reference_seeds=2)
    with cf.ProcessPoolExecutor(2, mp_context=ctx) as pool:
        done = {}
        pooled = engine.run_study(spec, executor=pool, on_run=done.__setitem__)
        # a study that decides: a round's added runs go to the pool side by side
        pooled_d = engine.run_study(deciding, executor=pool, completed=dict(stored))
    strip = ("wall_time", "speedup")

    def table(r):
        return [{k: v for k, v in row.items() if k not in strip} for row in r.table]

    assert table(pooled) == table(res)
    for k, r in pooled.runs.items():
        for stage, st in r.result.stages.items():
            for name, curve in st.curves.items():
                assert np.array_equal(curve, res.runs[k].result.stages[stage].curves[name])
    # resume: only the missing run executes
    partial = {k: v for k, v in stored.items() if k != "r3.1mm-paper-s1"}
    ran = []
    resumed = engine.run_study(spec, completed=partial, on_run=lambda k, r: ran.append(k))
    assert ran == ["r3.1mm-paper-s1"] and table(resumed) == table(res)
    # one seed per variant: its spread is unknown, so a second seed of each is added (with
    # the control of that seed), and the pool's added runs are those of the same study here
    added = [a["run"] for a in pooled_d.report.adaptive.added_runs]
    assert sorted(added) == ["ctl-r3.1mm-s3", "r3.1mm-paper-s3", "r3.1mm-unscaled-s3"]
    here = engine.run_study(deciding, completed=dict(stored))
    assert [a["run"] for a in here.report.adaptive.added_runs] == added
    assert table(here) == table(pooled_d)


def test_a_failed_coarse_run_leaves_the_rest():
    spec = _tiny_spec(protocol_check=False)
    outcomes = {}
    good = engine.run_study(spec, on_run=outcomes.__setitem__)
    outcomes["r3.1mm-paper-s1"] = "InstabilityError: blew up at step 12"
    res = engine.study.results.assemble(spec, engine.plan(spec).runs, outcomes)
    assert res.failed == {"r3.1mm-paper-s1": "InstabilityError: blew up at step 12"}
    v = next(v for v in res.report.verdicts if v.rule == "paper")
    assert v.verdict == "undecided" and "blew up" in v.reason
    assert "r3.1mm-unscaled-s1" in res.runs and len(good.runs) == 5
    outcomes["ref-s1"] = outcomes["ref-s2"] = "StageError: no"
    with pytest.raises(engine.RunFailed):
        engine.study.results.assemble(spec, engine.plan(spec).runs, outcomes)


def test_callback_can_stop_a_study():
    spec = engine.StudySpec(
        reference=tiny(),
        coarse_radii=(3.1e-3,),
        rules=(engine.ScalingRule.named("paper"),),
        protocol_check=False,
    )
    with pytest.raises(engine.StopRequested):
        engine.run_study(spec, progress=lambda p: p.run_index == 0)


def _adding_study(seeds, reference_seeds):
    """The tiny study of one coarse radius under the paper's rule that decides in one round
    and may add seeds up to three of each kind."""
    return engine.StudySpec(
        reference=tiny(),
        coarse_radii=(3.1e-3,),
        seeds=seeds,
        reference_seeds=reference_seeds,
        rules=(engine.ScalingRule.named("paper"),),
        decide=True,
        rounds=1,
        max_seeds=3,
        max_reference_seeds=3,
    )


def test_a_deciding_study_resumes_with_the_runs_it_added():
    # a study that adds seeds, interrupted after its first added run: the resumed study
    # finds the same added runs (replayed from the stored ones) and runs only the rest
    spec = _adding_study(seeds=(1, 2), reference_seeds=(1,))
    stored: dict = {}
    full = engine.run_study(spec, on_run=stored.__setitem__)
    added = [a["run"] for a in full.report.adaptive.added_runs]
    assert added and added[0] == "ref-s2"  # one reference seed: its spread first
    planned = [p.key for p in engine.plan(spec).runs]
    partial = {k: v for k, v in stored.items() if k in planned + added[:1]}
    ran: list = []
    again = engine.run_study(spec, completed=partial, on_run=lambda k, o: ran.append(k))
    assert ran == added[1:]
    assert [a["run"] for a in again.report.adaptive.added_runs] == added
    assert [r["run"] for r in again.table] == [r["run"] for r in full.table]
    # the runs are deterministic: the resumed study's verdicts are the uninterrupted one's
    assert [v.verdict for v in again.report.verdicts] == [v.verdict for v in full.report.verdicts]


def test_a_control_follows_every_added_coarse_seed():
    # engine.study.plan._added_runs: one control per radius and seed, so that the rule's
    # own error keeps its pairs (judge.judge_rule_error); counted in the budget
    spec = _adding_study(seeds=(1,), reference_seeds=(1, 2, 3))
    stored: dict = {}
    res = engine.run_study(spec, on_run=stored.__setitem__)
    added = {a["run"]: a for a in res.report.adaptive.added_runs}
    # with a control still to run the study has not stopped, even when no round adds more
    from engine.study.plan import plan_runs

    assert plan_runs(spec, stored)[2] is not None
    assert plan_runs(spec, {k: v for k, v in stored.items() if k != "ctl-r3.1mm-s5"})[2] is None
    coarse = [k for k in added if k.startswith("r3.1mm-paper-")]
    assert coarse == ["r3.1mm-paper-s4", "r3.1mm-paper-s5"], list(added)
    for k in coarse:
        ctl = "ctl-r3.1mm-s" + k.rpartition("-s")[2]
        assert added[ctl]["kind"] == "control" and k in added[ctl]["reason"]
    (own,) = res.report.rule_errors
    assert own.paired_seeds == 3 and own.control_seeds == 3


def test_stored_runs_beyond_the_plan_are_judged_with_it():
    # a report judges every stored run of the study: a run of one of its variants (or its
    # reference) with another seed joins the plan; keys of no run of the study do not
    from engine.study.plan import stored_plan_runs

    spec = engine.default_study()
    plan = engine.plan(spec)
    runs = stored_plan_runs(
        spec, ["r3.125mm-paper-s7", "ref-s9", "r6mm-paper-s4", "r3.125mm-other-s4", "ref-sx"]
    )
    assert [p.key for p in runs[: len(plan.runs)]] == [p.key for p in plan.runs]
    extra = runs[len(plan.runs) :]
    assert [p.key for p in extra] == ["r3.125mm-paper-s7", "ref-s9"]
    assert extra[0].seed == 7 and extra[0].test.seed == 7 and extra[0].radius == 3.125e-3
    assert extra[1].is_reference and extra[1].test.radius == spec.reference.radius


def test_a_control_is_the_reference_law_in_the_coarse_cell_scaled():
    # engine.study.plan.control_test: cell, interior margin and platen speed times
    # s = R_ref / R_c, gravity over s; the law, time step and stage times kept
    from engine.study.plan import control_test

    ref = engine.preset("quick", protocol="seed", interior_margin=0.02)
    ctl = control_test(ref, 5e-3, 1e-5)
    s = 0.5
    assert ctl.cell == pytest.approx(tuple(c * s for c in ref.cell))
    assert ctl.platen_speed == pytest.approx(ref.platen_speed * s)
    assert ctl.gravity == pytest.approx(ref.gravity / s)
    assert ctl.interior_margin == pytest.approx(0.02 * s)
    assert ctl.pair_law == ref.pair_law and ctl.radius == ref.radius and ctl.dt == 1e-5
    assert ctl.release_time == ref.release_time and ctl.max_stage_time == ref.max_stage_time
    # as many of its diameters across as the coarse run of its own, the same particle count
    coarse = engine.ScalingRule.named("paper").apply(ref, 5e-3, 1e-5)
    assert ctl.thickness_diameters == pytest.approx(coarse.thickness_diameters)
    assert ctl.n_particles == coarse.n_particles
    # the overburden rho g H and the strain rate are the coarse run's
    assert ctl.gravity * ctl.cell[2] == pytest.approx(coarse.gravity * coarse.cell[2])
    assert ctl.platen_speed / ctl.cell[2] == pytest.approx(coarse.platen_speed / coarse.cell[2])


def test_a_study_with_controls_gives_the_rule_error_and_the_resolution_error():
    spec = engine.StudySpec(
        reference=tiny(),
        coarse_radii=(3.1e-3,),
        rules=(engine.ScalingRule.named("paper"),),
        seeds=(1, 2, 3),
        reference_seeds=(1, 2, 3),
        protocol_check=False,
    )
    assert spec.controls  # on by default
    keys = [p.key for p in engine.plan(spec).runs]
    assert keys.count("ctl-r3.1mm-s1") == 1 and len(keys) == 9
    res = engine.run_study(spec)
    assert res.runs["ctl-r3.1mm-s2"].row()["rule"] == "control"
    # each run's self-weight at the base over the consolidation stress, rho g H / sigma:
    # the control's (g / s, H s) is the coarse run's and the reference's
    burden = {k: r.row()["overburden_ratio"] for k, r in res.runs.items()}
    assert 0 < burden["ref-s1"] < 1
    assert burden["ctl-r3.1mm-s2"] == pytest.approx(burden["r3.1mm-paper-s2"], rel=0.05)
    assert burden["ctl-r3.1mm-s2"] == pytest.approx(burden["ref-s2"], rel=0.05)
    assert res.runs["ctl-r3.1mm-s2"].result.test.gravity == pytest.approx(9.81 * 3.1 / 2.5)
    (resolution,) = res.report.resolution
    assert resolution.radius == 3.1e-3 and resolution.seeds == 3
    assert resolution.diameters_across == pytest.approx(12.1e-3 / 5e-3, rel=1e-2)
    (rule,) = res.report.rule_errors
    assert rule.rule == "paper" and rule.control_seeds == 3
    assert rule.verdict in ("equivalent", "differs", "undecided")
    lines = " ".join(res.report.control_lines)
    assert "against its resolution control" in lines and "diameters across" in lines
    # density paired by seed (its measured correlation), the stiffnesses not; coordination
    # not at three a side, where the unpaired interval's 4 degrees of freedom outweigh
    paired = {m.metric: m.paired for m in rule.metrics}
    assert paired["density"] and not paired["coordination"] and not paired["loading_stiffness"]
    assert rule.paired_seeds == 3
    # the resolution curve through the references and the controls, and its figure
    curve = res.report.resolution_curve.metrics
    assert set(curve) >= {"density", "loading_stiffness"}
    assert [s["reference"] for s in curve["density"]["sizes"]] == [True, False]
    assert "resolution curve, density" in lines and "bulk value" in lines
    assert res.figure("resolution").axes  # drawn from the report
    # the coarse variant's own verdict against the reference is judged as before
    assert [(v.radius, v.rule) for v in res.report.verdicts] == [(3.1e-3, "paper")]
    # a study may leave them out
    off = engine.StudySpec(reference=tiny(), coarse_radii=(3.1e-3,), controls=False)
    assert not any(p.control for p in engine.plan(off).runs)
