"""The reproduction's storage and report on tiny runs: runs stored one file each and read
back unchanged, the report recomputed from them with every claim judged."""

from __future__ import annotations

import numpy as np
import pytest

import engine
from benchmarks.report import write_report
from engine.io.store import load_run, save_run
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
    # no protocol check (half-step references), as in benchmarks.experiments: the report
    # judges the claims from the references, variants and controls; the check's four runs
    # were three quarters of this test's time
    seeds = {"reference_seeds": (1, 2), "seeds": (1,), "protocol_check": False}
    specs = {
        "a_cohesionless": engine.StudySpec(
            reference=tiny(unconfined=False, cell=(0.025, 0.025, 0.02), pour_fraction=0.2),
            coarse_radii=(2 * R,),
            rules=(rule("unscaled", 0, 0), rule("linear", 1, 2)),
            **seeds,
        ),
        "b_cohesive": engine.StudySpec(
            reference=tiny(pair_law=COHESIVE, cell=(0.025, 0.025, 0.02), pour_fraction=0.2),
            coarse_radii=(1.5 * R, 2 * R),
            rules=(rule("b1", 1, 1), rule("b2", 1, 2), rule("b3", 1, 3)),
            **seeds,
        ),
        "c_eepa_cohesionless": engine.StudySpec(
            reference=tiny(
                unconfined=False,
                cell=(0.025, 0.025, 0.02),
                pour_fraction=0.2,
                pair_law=engine.EEPA(k1=5e5, k2=2.5e6, n=1.5, restitution=0.4),
            ),
            coarse_radii=(2 * R,),
            rules=(rule.named("similarity"), rule("linear", 1, 2)),
            **seeds,
        ),
    }
    data = {}
    for name, spec in specs.items():
        store = tmp_path / "runs" / name
        engine.run_study(spec, on_run=lambda k, r, d=store: save_run(d / f"{k}.h5", r))
        outcomes = {p.stem: load_run(p) for p in store.glob("*.h5")}
        data[name] = (spec, outcomes)
    path = write_report("tiny", data, tmp_path / "out")
    text = path.read_text()
    for claim in (
        "softens the bulk response",
        "Linear stiffness converges",
        "Quadratic adhesion",
        "About 9x less compute",
    ):
        line = next(li for li in text.splitlines() if claim in li)
        assert "runs missing" not in line
    eepa = next(li for li in text.splitlines() if li.startswith("- (c) R = 5 mm"))
    assert "(e) similarity **" in eepa and "(f) linear stiffness fails: **" in eepa
    assert "EEPA n = 1.5, chi = 1.5, K1 = 500000 N/m^1.5" in text
    assert text.count("**agrees**") + text.count("**differs**") + text.count("**undecided**") >= 7
    assert (tmp_path / "out" / "figures" / "tiny_b_cohesive" / "error_vs_runtime.png").exists()


def test_stored_run_records_threads_and_machine(tmp_path):
    from engine.io.store import stored_machine, this_machine

    res = engine.run_uniaxial(tiny())  # 30 particles: one engine thread
    assert res.scalars["threads"] == 1.0
    path = save_run(tmp_path / "ref-s1.h5", res, keep_particles=False)
    assert stored_machine(path) == this_machine()
    assert this_machine()["logical_cpus"] >= 1 and this_machine()["cpu"]
    assert load_run(path).scalars["threads"] == 1.0
    # and the code that made it: the engine digest a checkpoint carries, the git commit
    from engine.io.store import stored_code
    from engine.uniaxial.checkpoint import code_digest

    code = stored_code(path)
    assert code["engine_digest"] == code_digest() and set(code) == {
        "engine_digest",
        "git_commit",
        "engine_modified",
    }
    assert code["git_commit"] is None or len(code["git_commit"]) == 40


def test_runs_selection_runs_only_the_named_runs_not_stored():
    from benchmarks.reproduce import SKIPPED, experiments, select

    spec = experiments("paper")["c_eepa_cohesionless"]
    keys = [p.key for p in engine.plan(spec).runs]
    # 3 references, 2 rules x 2 seeds, and the resolution control of each seed
    assert keys[:3] == ["ref-s1", "ref-s2", "ref-s3"] and len(keys) == 9
    assert [k for k in keys if k.startswith("ctl-")] == ["ctl-r5mm-s1", "ctl-r5mm-s2"]
    done, todo = select(spec, {"ref-s1": "stored"}, None)
    assert todo == keys[1:] and done == {"ref-s1": "stored"}
    done, todo = select(spec, {"ref-s1": "stored"}, ["ref-s1", "r5mm-linear-s2"])
    assert todo == ["r5mm-linear-s2"]
    assert done["ref-s1"] == "stored" and done["ref-s2"] == SKIPPED


def test_batch_starts_jobs_as_cores_free_and_kills_at_the_deadline(tmp_path):
    import sys

    from benchmarks.run_batch import parse_job, run_batch

    naps = {"a": 0.2, "b": 0.2, "c": 0.2, "d": 60.0}

    def argv(job, scale, store):
        return [sys.executable, "-c", f"import time; time.sleep({naps[job.key]})"]

    jobs = [parse_job(t) for t in ("x:a:2", "x:b:1", "x:c:1", "x:d:1")]
    run_batch(
        jobs,
        cores=3,
        deadline=5.0,
        scale="quick",
        store=tmp_path,
        logs=tmp_path,
        poll=0.05,
        argv_of=argv,
    )
    by = {j.key: j for j in jobs}
    assert [by[k].state for k in "abcd"] == ["done"] * 3 + ["killed at the deadline"]
    assert by["a"].start == by["b"].start < 0.01  # 2 + 1 threads fill the 3 cores at once
    assert by["c"].start >= 0.2  # waited for a core
    assert 5.0 <= by["d"].end < 10.0
    with pytest.raises(SystemExit, match="threads"):
        parse_job("x:a:0")


def test_the_benchmarks_import_no_circle():
    # the experiments are defined once (benchmarks/experiments.py); the report reads stored
    # runs; no benchmark module imports one that imports it back
    import ast
    from pathlib import Path

    bench = Path(__file__).resolve().parents[2] / "benchmarks"
    graph = {}
    for path in bench.glob("*.py"):
        deps = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module:
                if node.module.startswith("benchmarks."):
                    deps.add(node.module.split(".")[1])
                elif node.module == "benchmarks":
                    deps.update(a.name for a in node.names)
        graph[path.stem] = deps

    def reaches(a, b, seen=()):
        return any(
            d == b or (d not in seen and reaches(d, b, (*seen, d))) for d in graph.get(a, ())
        )

    circles = sorted(m for m in graph if reaches(m, m))
    assert circles == [], circles


def test_the_capped_study_is_experiment_b_with_only_the_pour_changed():
    """(b) with the capped pour plans the same runs as (b), every test filled at POUR_SPEED
    and nothing else changed: its stored runs are (b)'s runs with another fill."""
    from dataclasses import replace

    from benchmarks.experiments import POUR_SPEED, capped_study, experiments

    b, capped = experiments("paper")["b_cohesive"], capped_study()
    runs_b, runs_c = engine.plan(b).runs, engine.plan(capped).runs
    assert [p.key for p in runs_c] == [p.key for p in runs_b]
    for p, q in zip(runs_b, runs_c, strict=True):
        assert p.test.pour_speed is None and q.test.pour_speed == POUR_SPEED
        assert replace(q.test, pour_speed=None) == p.test


def test_the_experiments_at_the_default_protocol_adopt_the_protocol_benchmarks_runs(tmp_path):
    """--protocol default: the same experiments at the default protocol, stored apart; a run
    the protocol benchmark stored for the same test is taken under its run key, once."""
    import shutil

    from benchmarks.experiments import ROOT, experiments, label, store_dir
    from benchmarks.reproduce import adopt

    seed, new = experiments("paper"), experiments("paper", "default")
    assert seed["b_cohesive"].reference.dt == 1e-5 and new["b_cohesive"].reference.dt is None
    assert new["b_cohesive"].coarse_radii == seed["b_cohesive"].coarse_radii
    assert label("paper", "default") == "paper_default" and label("paper") == "paper"
    assert store_dir("paper", "b_cohesive", "default").parent.name == "paper_default"
    with pytest.raises(ValueError, match="protocol"):
        experiments("paper", "fast")
    src = tmp_path / "src"
    src.mkdir()
    stored = ROOT / "benchmarks" / "results" / "paper" / "protocol"
    for name in ("ref-I5e-4-f0.4-s2.h5", "ref-I2.5e-4-f0.4-s1.h5"):  # default; I* halved
        shutil.copyfile(stored / name, src / name)
    dest = tmp_path / "dest"
    assert adopt(new["b_cohesive"], dest, [src]) == [f"ref-s2 <- {src / 'ref-I5e-4-f0.4-s2.h5'}"]
    assert sorted(p.name for p in dest.iterdir()) == ["ref-s2.h5"]
    assert adopt(new["b_cohesive"], dest, [src]) == []  # once
    assert adopt(seed["b_cohesive"], tmp_path / "seed", [src]) == []  # another protocol
