"""The reproduction's storage and report on tiny runs: runs stored one file each and read
back unchanged, the report recomputed from them with every claim judged."""

from __future__ import annotations

import numpy as np
import pytest

import engine
from benchmarks.report import write_report
from engine.runstore import load_run, save_run
from tests.engine.test_uniaxial import COHESIVE, tiny

R = 2.5e-3


def test_stored_run_reads_back_unchanged_and_errors_are_kept(tmp_path):
    res = engine.run_uniaxial(tiny(pair_law=COHESIVE))
    back = load_run(save_run(tmp_path / "ref-s1.h5", res))
    assert back.test == res.test and back.scalars == res.scalars
    assert list(back.stages) == list(res.stages)
    for name, st in res.stages.items():
        for c, v in st.curves.items():
            assert np.array_equal(back.stages[name].curves[c], v)
        assert np.array_equal(back.stages[name].positions, st.positions)
        assert np.array_equal(back.stages[name].radii, st.radii)
    lean = load_run(save_run(tmp_path / "lean.h5", res, keep_particles=False))
    assert lean.stages["fill"].positions is None and lean.scalars == res.scalars
    assert load_run(save_run(tmp_path / "bad.h5", "StageError: no")) == "StageError: no"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.h5", "lean.h5", "ref-s1.h5"]


@pytest.mark.slow
def test_report_judges_the_claims_from_stored_runs(tmp_path):
    rule = engine.ScalingRule
    seeds = {"reference_seeds": (1, 2), "seeds": (1,)}
    specs = {
        "a_cohesionless": engine.StudySpec(
            reference=tiny(unconfined=False, cell=(0.025, 0.025, 0.02), pour_fraction=0.2),
            coarse_radii=(2 * R,),
            rules=(rule("unscaled", 0, 0), rule("linear", 1, 2)), **seeds),
        "b_cohesive": engine.StudySpec(
            reference=tiny(pair_law=COHESIVE, cell=(0.025, 0.025, 0.02), pour_fraction=0.2),
            coarse_radii=(1.5 * R, 2 * R),
            rules=(rule("b1", 1, 1), rule("b2", 1, 2), rule("b3", 1, 3)), **seeds),
        "c_eepa_cohesionless": engine.StudySpec(
            reference=tiny(unconfined=False, cell=(0.025, 0.025, 0.02), pour_fraction=0.2,
                           pair_law=engine.EEPA(k1=5e5, k2=2.5e6, n=1.5, restitution=0.4)),
            coarse_radii=(2 * R,),
            rules=(rule.named("similarity"), rule("linear", 1, 2)), **seeds),
    }
    data = {}
    for name, spec in specs.items():
        store = tmp_path / "runs" / name
        engine.run_study(spec, on_run=lambda k, r, d=store: save_run(d / f"{k}.h5", r))
        outcomes = {p.stem: load_run(p) for p in store.glob("*.h5")}
        data[name] = (spec, outcomes)
    path = write_report("tiny", data, tmp_path / "out")
    text = path.read_text()
    for claim in ("softens the bulk response", "Linear stiffness converges",
                  "Quadratic adhesion", "About 9x less compute"):
        line = next(li for li in text.splitlines() if claim in li)
        assert "runs missing" not in line
    eepa = next(li for li in text.splitlines() if li.startswith("- (c) R = 5 mm"))
    assert "(e) similarity **" in eepa and "(f) linear stiffness fails: **" in eepa
    assert "EEPA n = 1.5, chi = 1.5, K1 = 500000 N/m^1.5" in text
    assert text.count("**agrees**") + text.count("**differs**") + text.count(
        "**undecided**") >= 7
    assert (tmp_path / "out" / "figures" / "tiny_b_cohesive" / "error_vs_runtime.png").exists()
