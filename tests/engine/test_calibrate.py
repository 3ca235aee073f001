"""engine.calibrate on synthetic targets at a tiny scale: the engine makes the targets from a
law the calibration is not told, and the calibration recovers it within its posterior,
meets every target, says which target moves with which parameter, and resumes from its
stored runs."""

from __future__ import annotations

import functools
import importlib
import math
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

import engine
from engine.calibration import LabTargets, calibrate
from tests.engine.test_uniaxial import tiny

TRUTH = engine.BilinearAdhesive(k1=8e3, k2=4.5e4, mu_s=0.5, mu_r=0.001, restitution=0.4)
BASE = tiny(
    unconfined=False,
    pair_law=engine.BilinearAdhesive(k1=5e3, k2=8e4, mu_s=0.5, mu_r=0.001, restitution=0.4),
)
BOX = {"k1": (3e3, 2e4), "k2": (2.5e4, 8e4)}
#: the module (the package's ``calibrate`` is the function)
cal_module = importlib.import_module("engine.calibration.calibrate")


@pytest.fixture(scope="module")
def targets():
    r = engine.run_uniaxial(replace(BASE, pair_law=TRUTH))
    lo, un = r.scalars["loading_stiffness"], r.scalars["unloading_stiffness"]
    return LabTargets(
        tester="uniaxial",
        loading_stiffness=lo,
        loading_stiffness_sd=0.1 * lo,
        unloading_stiffness=un,
        unloading_stiffness_sd=0.1 * un,
    )


#: Packing seeds of the untold law's "laboratory" tests.
LAB_SEEDS = (1, 2, 3, 4, 5)


@pytest.fixture(scope="module")
def lab():
    """The targets as a laboratory reports a powder: the mean of repeated tests and their
    repeatability (the sd over five packings). In a cell of 31 particles one test is one
    draw from a wide spread (loading stiffness 2.9e5 to 1.09e6 Pa between laws 1 % apart,
    measured for issue 42): against one run's value with a 10 % sd the check run's "met"
    was a draw that any change of the engine's trajectories flipped."""
    runs = [engine.run_uniaxial(replace(BASE, pair_law=TRUTH, seed=s)) for s in LAB_SEEDS]
    lo = np.array([r.scalars["loading_stiffness"] for r in runs])
    un = np.array([r.scalars["unloading_stiffness"] for r in runs])
    return LabTargets(
        tester="uniaxial",
        loading_stiffness=float(lo.mean()),
        loading_stiffness_sd=float(lo.std(ddof=1)),
        unloading_stiffness=float(un.mean()),
        unloading_stiffness_sd=float(un.std(ddof=1)),
    )


def test_synthetic_targets_are_recovered(lab, tmp_path, monkeypatch):
    targets = lab
    seen = []
    cal = calibrate(
        BASE,
        targets,
        BOX,
        runs=12,
        waves=1,
        wave_runs=8,
        seed=1,
        store=tmp_path,
        on_run=lambda i, q: seen.append(i),
    )
    assert seen == list(range(20)) and len(cal.runs) == 20
    for name, p in cal.parameters.items():
        lo, hi = p["interval"]
        assert lo <= getattr(TRUTH, name) <= hi, (name, p)
        assert p["status"] in ("determined", "free") and p["box"] == list(BOX[name])
    assert all(q["met"] for q in cal.targets_met), cal.not_met
    assert cal.not_met == []
    # the posterior itself: samples in the law's units inside the box, and the parameters'
    # correlation (symmetric, unit diagonal)
    post = cal.posterior
    assert post["parameters"] == ["k1", "k2"] and len(post["samples"]) == 400
    assert all(3e3 <= k1 <= 2e4 and 2.5e4 <= k2 <= 8e4 for k1, k2 in post["samples"])
    c = post["correlation"]
    assert (
        c[0][0] == pytest.approx(1.0) and c[0][1] == pytest.approx(c[1][0]) and -1 <= c[0][1] <= 1
    )
    # which target moves with which parameter: loading with K1, unloading with K2
    s = cal.sensitivity
    assert max(s["loading_stiffness"], key=s["loading_stiffness"].get) == "k1"
    assert max(s["unloading_stiffness"], key=s["unloading_stiffness"].get) == "k2"
    assert isinstance(cal.law, engine.BilinearAdhesive) and cal.to_summary()["law"]["k1"] > 0
    # calibrate, then coarsen: the study of the calibrated test, the default's radii and rules
    assert cal.test == replace(BASE, pair_law=cal.law)
    study = cal.study()
    assert study.reference == cal.test
    assert study.coarse_radii == engine.default_study().coarse_radii
    from engine.io.figures import calibration_figure

    fig = calibration_figure(cal.to_summary())  # no curve target: the scalar panel alone
    assert len(fig.axes) == 1 and "targets met" in fig._suptitle.get_text()
    # run again on the same store: every design, wave and check run is found, none runs
    calls = []
    real = cal_module._run_point
    monkeypatch.setattr(
        cal_module, "_run_point", lambda t, s, *a: calls.append(t) or real(t, s, *a)
    )
    again = calibrate(BASE, targets, BOX, runs=12, waves=1, wave_runs=8, seed=1, store=tmp_path)
    assert calls == [] and again.parameters == cal.parameters  # the check run is stored too


def test_a_calibration_refuses_what_it_cannot_set(targets):
    with pytest.raises(engine.ParameterError, match="parameters.E"):
        calibrate(BASE, targets, {"E": (1e6, 1e8)})
    with pytest.raises(engine.ParameterError, match="low < high"):
        calibrate(BASE, targets, {"k1": (2e4, 3e3)})
    with pytest.raises(engine.ParameterError, match="calibrate.runs"):
        calibrate(BASE, targets, BOX, runs=3)
    # a box end outside the range the law declares, a box with no law the law accepts
    with pytest.raises(engine.ParameterError, match=r"parameters.mu_s .* >= 0"):
        calibrate(BASE, targets, {"mu_s": (-1.0, 0.5)})
    with pytest.raises(engine.ParameterError, match=r"K2 >= K1"):
        calibrate(BASE, targets, {"k2": (1e3, 4e3)})
    # checked at once, before any run: an end no law in the box reaches (K1 = 1e300 N/m
    # with K2 = 8e4 N/m), an end the test's time step cannot integrate (K2 = 1e12 N/m at
    # dt = 1e-5 s: the stable limit is about 1.6e-8 s), each named
    ran = []
    with pytest.raises(engine.ParameterError, match=r"parameters\.k1 .* high end 1e\+300"):
        calibrate(BASE, targets, {"k1": (3e3, 1e300)}, on_run=lambda i, q: ran.append(i))
    with pytest.raises(engine.ParameterError, match=r"parameters\.k2 .* time step dt = 1e-05"):
        calibrate(BASE, targets, {"k1": (3e3, 2e4), "k2": (2.5e4, 1e12)})
    assert ran == []
    # with dt left to each law (null) the same box runs at each law's own step
    cal_module.check_request(replace(BASE, dt=None), targets, {"k2": (2.5e4, 1e12)}, 5)


def test_a_law_the_test_refuses_is_left_out_without_a_run(targets, monkeypatch):
    # the soft end of a K1 box (too soft to carry the consolidation stress within the
    # overlap limit): those parameter sets are listed with the reason and never run
    real = cal_module._run_point
    ran = []
    monkeypatch.setattr(cal_module, "_run_point", lambda t, s, *a: ran.append(t) or real(t, s, *a))
    # the design's points chosen, not drawn: K1 = 10, 21 and 46 N/m (refused: the limit is
    # about 500 N/m) and 4.4e3, 9.3e3 and 2e4 N/m, well above it (a law just above the
    # static limit may still blow up in the fill, which is another test's subject)
    u = np.array([[0.0], [0.1], [0.2], [0.8], [0.9], [1.0]])
    monkeypatch.setattr(cal_module, "_maximin", lambda rng, n, d, ok: u)
    cal = calibrate(BASE, targets, {"k1": (10.0, 2e4)}, runs=6, waves=0, seed=4)
    refused = [r for r in cal.runs if "error" in r]
    assert refused and all("stiff enough" in r["error"] for r in refused)
    assert all(r["parameters"]["k1"] < 500 for r in refused)
    assert len(ran) == 6 - len(refused) + 1  # the others and the check run


def test_a_run_that_fails_is_left_out_not_the_calibration(targets, monkeypatch):
    # a parameter set whose run stops (a stage that misses its criterion) is listed with its
    # error and left out of the emulators; the calibration goes on
    real = cal_module._run_point
    calls = []

    def flaky(test, stresses, *a):
        calls.append(test)
        return (
            "StageError: stage fill did not settle" if len(calls) == 3 else real(test, stresses, *a)
        )

    monkeypatch.setattr(cal_module, "_run_point", flaky)
    cal = calibrate(BASE, targets, BOX, runs=6, waves=1, wave_runs=3, seed=2)
    errors = [r for r in cal.runs if "error" in r]
    assert len(errors) == 1 and errors[0]["error"].startswith("StageError")
    assert len(cal.runs) == 9 and cal.parameters["k1"]["median"] > 0


def test_progress_stop_and_resume(targets, tmp_path):
    # progress names each run and the check run; returning False stops the calibration
    # (engine.StopRequested); a rerun on the store resumes with what was stored
    seen = []

    def stop_at_third(p):
        seen.append(p)
        return p.run_key != "cal-002"

    # the same calibration, stopped and then resumed on its store
    run = functools.partial(
        calibrate, BASE, targets, {"k1": BOX["k1"]}, runs=4, waves=0, store=tmp_path
    )
    with pytest.raises(engine.StopRequested):
        run(progress=stop_at_third)
    assert {p.run_key for p in seen} == {"cal-000", "cal-001", "cal-002"}
    assert all(p.n_runs == 5 for p in seen)  # 4 design runs and the check run
    fractions = [p.fraction for p in seen]
    assert fractions == sorted(fractions) and fractions[-1] < 0.6
    stored = sorted(p.name for p in tmp_path.glob("cal-*.h5"))
    assert [n[:7] for n in stored] == ["cal-000", "cal-001"]
    heard, outcomes = [], []
    cal = run(progress=heard.append, on_run=lambda i, q: outcomes.append((i, q)))
    assert {p.run_key for p in heard} == {"cal-002", "cal-003", "check"}  # the rest only
    assert [i for i, _ in outcomes] == [0, 1, 2, 3] and heard[-1].fraction == pytest.approx(1.0)
    assert cal.curves["loading"]["stress"] and "flow_function" not in cal.curves


def test_tasks_on_an_executor_give_the_same_calibration(targets, tmp_path):
    # the runs as tasks (reporting through a FileChannel) give the calibration the runs in
    # this process give, bit for bit
    import concurrent.futures as cf

    box = {"k1": BOX["k1"]}
    here = calibrate(BASE, targets, box, runs=4, waves=0)
    heard = []
    with cf.ThreadPoolExecutor(2) as pool:
        options = engine.RunOptions(
            executor=pool, channel=engine.FileChannel(tmp_path / "ch"), poll_interval=0.05
        )
        there = calibrate(
            BASE, targets, box, runs=4, waves=0, options=options, progress=heard.append
        )
    assert there.parameters == here.parameters and there.targets_met == here.targets_met
    assert heard and heard[-1].fraction == pytest.approx(1.0)


def test_a_calibration_in_a_small_cell_corrected_to_the_bulk(targets):
    # laboratory data are bulk values; a cell whose resolution curve puts its loading
    # stiffness at half the bulk's is corrected by a factor 2 (with its uncertainty): the
    # calibration against targets twice the cell's recovers the untold law, and says what
    # the cell itself gave
    bulk = replace(
        targets,
        loading_stiffness=2 * targets.loading_stiffness,
        loading_stiffness_sd=2 * targets.loading_stiffness_sd,
        unloading_stiffness=None,
        unloading_stiffness_sd=None,
    )
    box = {"k1": BOX["k1"]}
    cal = calibrate(
        BASE,
        bulk,
        box,
        runs=5,
        waves=1,
        wave_runs=3,
        seed=3,
        resolution={"loading_stiffness": (2.0, 0.02), "strength": (1.2, 0.05)},
    )
    lo, hi = cal.parameters["k1"]["interval"]
    assert lo <= TRUTH.k1 <= hi, cal.parameters
    (q,) = cal.targets_met
    assert q["value"] == pytest.approx(2 * q["cell_value"]) and q["correction_sd"] == 0.02
    # met or not, said as it is: one check run in this cell is one draw of a wide spread
    # (the targets' fixture says how wide), so its z decides, not this test
    assert q["met"] == (abs(q["z"]) <= 2) and cal.all_met == q["met"]
    assert cal.to_summary()["resolution"]["loading_stiffness"] == [2.0, 0.02]
    # uncorrected, the calibration absorbs the cell's loss into the law: K1 comes out stiffer
    # than the untold law's, outside its interval
    plain = calibrate(BASE, bulk, box, runs=5, waves=1, wave_runs=3, seed=3)
    assert plain.parameters["k1"]["interval"][0] > TRUTH.k1, plain.parameters
    with pytest.raises(engine.ParameterError, match="resolution.k0"):
        calibrate(BASE, bulk, box, runs=5, resolution={"k0": (1.0, 0.0)})
    with pytest.raises(engine.ParameterError, match="resolution.strength"):
        calibrate(BASE, bulk, box, runs=5, resolution={"strength": (0.0, 0.1)})


def test_corrections_from_a_resolution_curve():
    from engine.calibration.calibrate import resolution_corrections

    curve = {
        "confidence": 0.95,
        "metrics": {
            "strength": {
                "reference_offset": -0.15,
                "reference_offset_interval": [-0.25, -0.04],
                "reference_offset_df": math.inf,
            },
            "coordination_interior": {
                "reference_offset": -0.02,
                "reference_offset_interval": [-0.03, -0.01],
                "reference_offset_df": 4.0,
            },
        },
    }
    out = resolution_corrections(curve)
    assert set(out) == {"strength"}  # coordination is no target
    factor, sd = out["strength"]
    assert factor == pytest.approx(1 / 0.85)
    assert sd == pytest.approx((math.log(0.96) - math.log(0.75)) / (2 * 1.959964), rel=1e-5)


def test_the_figure_draws_a_calibration_with_a_failed_run():
    # a run that stopped has an error and no quantities: the figure skips it (it raised
    # KeyError on the quick-scale benchmark's four fill failures)
    from engine.io.figures import calibration_figure

    def q(name, value):
        return {"name": name, "value": value, "lab": value, "sd": 0.01 * value, "met": True}

    checks = [q("porosity@8000Pa:loading", 0.45), q("strength@20000Pa", 1.3e4), q("k0", 0.4)]
    runs = [
        {"wave": 0, "parameters": {"k1": 5e3}, "quantities": checks},
        {"wave": 0, "parameters": {"k1": 2e3}, "error": "InstabilityError: overlap"},
    ]
    fig = calibration_figure({"targets_met": checks, "runs": runs})
    faint = [c for ax in fig.axes for c in ax.collections if len(c.get_offsets()) == 1]
    # compression, flow function and the scalar targets (K0), each with its units
    assert len(fig.axes) == 3 and "all 3 targets met" in fig._suptitle.get_text()
    assert all("[" in ax.get_title() and "[" in ax.get_ylabel() for ax in fig.axes)
    assert len(faint) >= 4  # per panel: the good run's point, the check run's square


def test_the_figure_has_no_empty_panel_and_says_a_target_is_missed():
    from engine.io.figures import calibration_figure

    def q(name, lab, value, sd):
        z = (value - lab) / sd
        return {"name": name, "value": value, "lab": lab, "sd": sd, "z": z, "met": abs(z) <= 2}

    checks = [
        q("porosity@5000Pa:loading", 0.45, 0.449, 0.004),
        q("loading_stiffness", 2e6, 1.5e6, 2e5),
    ]
    fig = calibration_figure({"targets_met": checks, "runs": []})
    # no strength target: no flow-function panel; compressibility on a log stress axis
    assert len(fig.axes) == 2 and not any("flow" in ax.get_title() for ax in fig.axes)
    assert fig.axes[0].get_xscale() == "log" and "kPa" in fig.axes[0].get_xlabel()
    assert "1 of 2 targets NOT met: loading_stiffness (z = -2.5)" in fig._suptitle.get_text()


def test_sobol_indices_of_a_known_function_far_from_zero():
    # y = 100 + u0 + 0.1 u1 (and nothing of u2): S = (1, 0.01, 0) / 1.01. The mean of 100
    # made the uncentred estimator's scatter larger than the indices themselves
    class Exact:
        noise = 0.0

        def predict(self, u):
            return 100.0 + u[:, 0] + 0.1 * u[:, 1], np.zeros(len(u))

    axes = [SimpleNamespace(name=n) for n in ("k1", "k2", "f0")]
    s = cal_module._sobol([Exact()], [{"name": "y"}], axes, np.random.default_rng(3))["y"]
    assert s["k1"] == pytest.approx(1 / 1.01, abs=0.05)
    assert s["k2"] < 0.05 and s["f0"] < 0.05


def test_the_figure_title_wraps_a_long_list_of_targets_not_met():
    # the calcium carbonate's four unmet loci ran off both edges of its figure; the title is
    # now wrapped to the figure's width, and a strength with no peak says so
    from engine.io.figures import calibration_figure

    checks = [
        {"name": f"tau@{s}Pa:2949Pa", "value": 600.0, "lab": 900.0, "sd": 100.0, "z": -3.0}
        for s in (1317, 1857, 2456, 2600)
    ] + [{"name": "strength@8000Pa", "value": math.nan, "lab": 2e3, "sd": 2e2, "no_peak": True}]
    for c in checks:
        c["met"] = False
    fig = calibration_figure({"targets_met": checks, "runs": []})
    title = fig._suptitle.get_text()
    assert "5 of 5 targets NOT met" in title and "strength@8000Pa (no peak)" in title
    assert "\n" in title
    assert max(len(line) for line in title.splitlines()) <= 12 * fig.get_figwidth()
