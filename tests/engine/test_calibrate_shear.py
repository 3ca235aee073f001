"""Shear-tester targets in the calibration (issue 41 item 2, docs/CALIBRATION.md "Shear
data"): the records refuse bad yield loci naming the field, the forward model runs the shear
test at the data's stresses and reads each target from it (one real run on a cell of about
120 grains, seconds), and the calibration routes shear targets to the shear test and
uniaxial targets to the uniaxial test (with cheap closed-form stand-ins for both tests, so
that the routing and the fit are tested in about a second, not the DEM)."""

from __future__ import annotations

import copy
import importlib
import json
import math
from types import SimpleNamespace

import pytest

import engine
from engine.calibration import LabTargets, calibrate
from engine.calibration import forward as fw
from engine.calibration.targets import ShearLocus
from tests.engine.test_calibrate import BASE
from tests.engine.test_shear import tiny as tiny_shear

cal_module = importlib.import_module("engine.calibration.calibrate")


def _pt(sigma_n, tau, sigma_n_sd=0.0, tau_sd=100.0):
    return {"sigma_n": sigma_n, "sigma_n_sd": sigma_n_sd, "tau": tau, "tau_sd": tau_sd}


LOCUS = {
    "sigma_pre": 1e4,
    "tau_pre": 6e3,
    "tau_pre_sd": 300.0,
    "points": [_pt(2e3, 2.5e3), _pt(4e3, 3.5e3), _pt(6e3, 4.5e3)],
    "bulk_density": 1200.0,
    "bulk_density_sd": 12.0,
}
RING = {"tester": "ring_shear", "material": "synthetic", "shear": [LOCUS]}


def test_shear_data_round_trip_and_name_their_tester():
    t = LabTargets.from_dict(json.loads(json.dumps(RING)))
    assert t.names() == ["shear"] and t.uniaxial_names() == []
    assert t.resolved_shear_tester() == "ring_shear"
    assert LabTargets.from_dict(t.to_dict()) == t
    assert isinstance(t.shear[0], ShearLocus) and t.shear[0].slope() == pytest.approx(0.5)
    # sigma_n's sd carried along the lab's locus: hypot(tau_sd, tan(phi) sigma_n_sd)
    mixed = LabTargets.from_dict(
        {
            "tester": "lambda",
            "k0": 0.5,
            "k0_sd": 0.05,
            "shear_tester": "jenike",
            "shear": [{**LOCUS, "points": [_pt(2e3, 2.5e3, 400.0, 150.0), _pt(6e3, 4.5e3)]}],
        }
    )
    assert mixed.names() == ["k0", "shear"] and mixed.resolved_shear_tester() == "jenike"
    assert mixed.shear[0].tau_sd(0) == pytest.approx(math.hypot(150.0, 0.5 * 400.0))


def _with(change):
    data = copy.deepcopy(RING)
    change(data)
    return data


@pytest.mark.parametrize(
    "change, field, words",
    [
        # the three: sigma_n above sigma_pre, one point, negative tau
        (
            lambda d: d["shear"][0]["points"].__setitem__(2, _pt(12e3, 5e3)),
            "LabTargets.shear[0].points[2].sigma_n",
            "below sigma_pre = 10000 Pa",
        ),
        (
            lambda d: d["shear"][0].__setitem__("points", [_pt(2e3, 2.5e3)]),
            "LabTargets.shear[0].points",
            "one point gives no line",
        ),
        (
            lambda d: d["shear"][0]["points"].__setitem__(1, _pt(4e3, -3.5e3)),
            "LabTargets.shear[0].points[1].tau",
            "> 0",
        ),
        (
            lambda d: d["shear"][0]["points"][1].pop("tau_sd"),
            "LabTargets.shear[0].points[1].tau_sd",
            "required",
        ),
        (
            lambda d: d["shear"][0]["points"][0].__setitem__("sigma_n_sd", -1.0),
            "LabTargets.shear[0].points[0].sigma_n_sd",
            ">= 0",
        ),
        (
            lambda d: d["shear"][0].pop("bulk_density_sd"),
            "LabTargets.shear[0].bulk_density_sd",
            "repeatability",
        ),
        (
            lambda d: d["shear"][0]["points"].__setitem__(1, _pt(2e3, 3e3)),
            "LabTargets.shear[0].points[1].sigma_n",
            "points[0] has it",
        ),
        (
            lambda d: d["shear"][0]["points"].__setitem__(2, _pt(6e3, 1e3)),
            "LabTargets.shear[0].points",
            "tan(phi) > 0",
        ),
        (
            lambda d: d["shear"].append(copy.deepcopy(d["shear"][0])),
            "LabTargets.shear[1].sigma_pre",
            "shear[0] has it",
        ),
        (lambda d: d.update(tester="uniaxial"), "LabTargets.shear_tester", "not one"),
        (
            # a uniaxial flow function from a shear tester stays refused
            lambda d: d.update(strength=[{"consolidation_stress": 1e4, "strength": 1e3, "sd": 1}]),
            "LabTargets.strength",
            "ring-shear",
        ),
    ],
)
def test_bad_shear_data_is_refused_naming_the_field(change, field, words):
    with pytest.raises(engine.ParameterError) as e:
        LabTargets.from_dict(_with(change))
    assert e.value.field == field and words in str(e.value), str(e.value)


def test_the_forward_model_runs_the_shear_test_at_the_datas_stresses():
    # one real shear test, about 120 grains (tests/engine/test_shear.py's cell), at the data's
    # sigma_pre and sigma_n with the parameter set's law; every target read from it
    targets = LabTargets.from_dict(
        {
            "tester": "ring_shear",
            "shear": [
                {
                    "sigma_pre": 8e3,
                    "tau_pre": 3e3,
                    "tau_pre_sd": 300.0,
                    "points": [_pt(3e3, 1.2e3, 100.0), _pt(6e3, 2.1e3)],
                    "bulk_density": 1200.0,
                    "bulk_density_sd": 12.0,
                }
            ],
        }
    )
    law = engine.BilinearAdhesive(k1=6e3, k2=3e4, mu_s=0.5, mu_r=0.001, restitution=0.4)
    cell = fw.check_shear_cell(BASE, tiny_shear())
    (test,) = fw.shear_tests(cell, targets, law)
    assert test.preshear_stress == 8e3 and test.normal_stresses == (3e3, 6e3)
    assert test.pair_law == law and test.cell == tiny_shear().cell
    seen = []
    out = cal_module._run_point(fw.Forward(None, (test,)), (), progress=seen.append)
    res = out[fw.SHEAR][8e3]
    assert list(out) == [fw.SHEAR] and res["test"] == json.loads(json.dumps(test.to_dict()))
    fractions = [p.fraction for p in seen]
    assert fractions == sorted(fractions) and seen[-1].stage.startswith("shear@8000Pa")
    q = {x["name"]: x for x in fw.measure_shear(out[fw.SHEAR], targets)}
    assert list(q) == [
        "tau@3000Pa:8000Pa",
        "tau@6000Pa:8000Pa",
        "tau_pre@8000Pa",
        "bulk_density@8000Pa",
    ]
    slope = res["locus"]["slope"]
    for k, target in enumerate((3e3, 6e3)):
        run = next(p for p in res["points"] if p["target"] == target)
        x = q[f"tau@{target:g}Pa:8000Pa"]
        # the run's point carried to the lab's sigma_n along the run's locus
        assert x["value"] == pytest.approx(run["tau"] + slope * (target - run["sigma"]))
        # the servo held the point within 5 % of its normal stress (docs/SHEAR.md), so the
        # carried value differs from the point's by at most tan(phi) x 5 % of sigma_n
        assert abs(x["value"] - run["tau"]) <= slope * 0.05 * target
        assert x["sd"] == pytest.approx(targets.shear[0].tau_sd(k)) and x["unit"] == "Pa"
    assert q["tau@3000Pa:8000Pa"]["sd"] == pytest.approx(math.hypot(100.0, 0.3 * 100.0))
    sc = res["scalars"]
    assert q["tau_pre@8000Pa"]["value"] == pytest.approx(
        sc["preshear_tau"] * 8e3 / sc["preshear_sigma"]
    )
    assert q["bulk_density@8000Pa"]["value"] == sc["bulk_density"] < law_density(BASE)
    curves = cal_module._curves(out)
    assert list(curves) == ["yield_loci"] and curves["yield_loci"][0]["sigma_pre"] == 8e3


def law_density(test) -> float:
    return test.density


# ------------------------------------------------------------- routing, closed-form stand-ins
#: The untold law of the routing tests: K1 sets the uniaxial stand-in's stiffness, mu_s the
#: shear stand-in's friction.
TRUTH = {"k1": 8e3, "mu_s": 0.5}
COHESION = 500.0  # the stand-in's cohesion [Pa]


def _stand_in_shear(tests, progress=None):
    """A shear test in closed form: tau = c + 0.8 mu_s sigma, each point's normal stress 1 %
    above its target (as a servo leaves it), bulk density 1000 + 200 mu_s kg/m^3."""
    out = {}
    for t in tests:
        m = 0.8 * t.pair_law.mu_s
        sig = [1.01 * s for s in t.normal_stresses]
        out[t.preshear_stress] = {
            "test": json.loads(json.dumps(t.to_dict())),
            "points": [{"kind": "preshear", "sigma": t.preshear_stress, "tau": 0.0}]
            + [
                {"kind": "failure", "target": s, "sigma": x, "tau": COHESION + m * x}
                for s, x in zip(t.normal_stresses, sig)
            ],
            "locus": {
                "slope": m,
                "cohesion": COHESION,
                "sigma_1": 2 * t.preshear_stress,
                "sigma_c": 2 * COHESION,
                "ffc": t.preshear_stress / COHESION,
            },
            "scalars": {
                "preshear_sigma": 0.99 * t.preshear_stress,
                "preshear_tau": COHESION + 1.2 * m * 0.99 * t.preshear_stress,
                "bulk_density": 1000.0 + 200.0 * t.pair_law.mu_s,
            },
        }
    return out


def _stand_in_uniaxial(test, **_):
    return SimpleNamespace(scalars={"loading_stiffness": 100.0 * test.pair_law.k1}, stages={})


def _locus(sigma_pre, sigma_ns, tau_pre=False, bulk=False) -> dict:
    """A yield locus of the untold law's stand-in, each value with a 3 % sd."""
    m = 0.8 * TRUTH["mu_s"]
    out = {
        "sigma_pre": sigma_pre,
        "points": [_pt(s, COHESION + m * s, 0.0, 0.03 * (COHESION + m * s)) for s in sigma_ns],
    }
    if tau_pre:
        tau = COHESION + 1.2 * m * sigma_pre
        out.update(tau_pre=tau, tau_pre_sd=0.03 * tau)
    if bulk:
        out.update(bulk_density=1000.0 + 200.0 * TRUTH["mu_s"], bulk_density_sd=3.0)
    return out


def _lab(mixed: bool) -> LabTargets:
    """Mixed: the loading stiffness and two loci (one with tau_pre); else one locus with
    its bulk density (few targets: each is an emulator to fit)."""
    if not mixed:
        return LabTargets.from_dict(
            {"tester": "ring_shear", "shear": [_locus(1e4, (2e3, 7e3), bulk=True)]}
        )
    ks = 100.0 * TRUTH["k1"]
    return LabTargets.from_dict(
        {
            "tester": "uniaxial",
            "loading_stiffness": ks,
            "loading_stiffness_sd": 0.03 * ks,
            "shear_tester": "ring_shear",
            "shear": [_locus(5e3, (1e3, 3e3), tau_pre=True), _locus(1e4, (2e3, 7e3))],
        }
    )


def quicker_posterior(monkeypatch) -> None:
    """The posterior sampled with 1000 Metropolis steps a chain, not 4000: the stand-ins'
    posteriors have one or two parameters, and most of these tests' time went into
    sampling them."""
    real = cal_module._metropolis
    monkeypatch.setattr(cal_module, "_metropolis", lambda *a, **k: real(*a, **{**k, "steps": 1000}))


@pytest.fixture
def stand_ins(monkeypatch):
    """Both tests replaced by their closed forms; what each was asked to run recorded."""
    quicker_posterior(monkeypatch)
    ran = {"shear": [], "uniaxial": []}

    def shear(tests, progress=None):
        ran["shear"].append(tests)
        return _stand_in_shear(tests, progress)

    def uniaxial(test, **kw):
        ran["uniaxial"].append(test)
        return _stand_in_uniaxial(test, **kw)

    monkeypatch.setattr(cal_module, "run_shear_tests", shear)
    monkeypatch.setattr("engine.uniaxial.driver.run_uniaxial", uniaxial)
    return ran


def test_shear_targets_are_routed_to_the_shear_test_and_recovered(stand_ins):
    targets = _lab(mixed=True)
    box = {"k1": (3e3, 2e4), "mu_s": (0.2, 0.8)}
    cal = calibrate(BASE, targets, box, runs=8, waves=0, seed=3)
    # every parameter set ran the uniaxial test (its one branch) and a shear test per locus
    # at the data's stresses, each with the parameter set's law
    assert len(stand_ins["uniaxial"]) == len(stand_ins["shear"]) == 9  # 8 and the check
    for tests, ut in zip(stand_ins["shear"], stand_ins["uniaxial"]):
        assert [t.preshear_stress for t in tests] == [5e3, 1e4]
        assert [t.normal_stresses for t in tests] == [(1e3, 3e3), (2e3, 7e3)]
        assert all(t.pair_law == ut.pair_law for t in tests)
        # the default cell, 10 x 5 x 15 diameters, with the test's time step
        assert tests[0].cell == tuple(fw.shear_cell(BASE)["cell"]) and tests[0].dt == BASE.dt
    names = [q["name"] for q in cal.targets_met]
    assert names[0] == "loading_stiffness" and "tau@7000Pa:10000Pa" in names
    assert "tau_pre@5000Pa" in names and len(names) == 1 + 2 + 1 + 2
    for name, p in cal.parameters.items():
        lo, hi = p["interval"]
        assert lo <= TRUTH[name] <= hi, (name, p)
    assert cal.all_met, cal.not_met
    # each target moves with its own test's parameter
    s = cal.sensitivity
    assert max(s["loading_stiffness"], key=s["loading_stiffness"].get) == "k1"
    assert max(s["tau@7000Pa:10000Pa"], key=s["tau@7000Pa:10000Pa"].get) == "mu_s"
    summary = cal.to_summary()
    assert summary["shear_test"]["cell"] == fw.shear_cell(BASE)["cell"]
    assert "pair_law" not in summary["shear_test"]
    assert [c["sigma_pre"] for c in summary["curves"]["yield_loci"]] == [5e3, 1e4]


def test_shear_data_alone_never_runs_the_uniaxial_test(stand_ins, tmp_path):
    targets, box = _lab(mixed=False), {"mu_s": (0.2, 0.8)}
    cal = calibrate(BASE, targets, box, runs=5, waves=0, seed=1, store=tmp_path)
    assert stand_ins["uniaxial"] == [] and len(stand_ins["shear"]) == 6
    lo, hi = cal.parameters["mu_s"]["interval"]
    assert lo <= TRUTH["mu_s"] <= hi and cal.all_met, cal.not_met
    # a rerun on the store finds every run's stored shear results: nothing runs
    assert len(list(tmp_path.glob("*-shear-*Pa.json"))) == 5 + 1  # and the check run
    again = calibrate(BASE, targets, box, runs=5, waves=0, seed=1, store=tmp_path)
    assert len(stand_ins["shear"]) == 6 and again.parameters == cal.parameters


def test_a_failed_shear_run_is_left_out(monkeypatch):
    calls = []

    def shear(tests, progress=None):
        calls.append(tests)
        if len(calls) == 2:
            raise engine.StageError("the pre-shear did not reach steady flow", "preshear", 10)
        return _stand_in_shear(tests, progress)

    monkeypatch.setattr(cal_module, "run_shear_tests", shear)
    quicker_posterior(monkeypatch)
    cal = calibrate(BASE, _lab(mixed=False), {"mu_s": (0.2, 0.8)}, runs=5, waves=0, seed=1)
    errors = [r for r in cal.runs if "error" in r]
    assert len(errors) == 1 and errors[0]["error"].startswith("StageError")


def test_a_shear_run_is_stopped_at_its_wall_time_limit():
    heard = cal_module._wall_limited(None, (0.0, "max_run_wall_time"))
    with pytest.raises(engine.WallTimeExceeded, match="max_run_wall_time"):
        heard(SimpleNamespace(fraction=0.1))
    assert cal_module._wall_limited(None, None) is None


def test_a_shear_request_is_checked_before_anything_runs(stand_ins):
    targets = _lab(mixed=False)
    with pytest.raises(engine.ParameterError, match=r"calibrate.shear_test.radius"):
        calibrate(BASE, targets, {"mu_s": (0.2, 0.8)}, shear_test=tiny_shear(radius=2e-3))
    uniaxial_only = LabTargets.from_dict(
        {"tester": "uniaxial", "loading_stiffness": 1e6, "loading_stiffness_sd": 1e5}
    )
    with pytest.raises(engine.ParameterError, match=r"calibrate.shear_test .* shear targets only"):
        cal_module.check_request(BASE, uniaxial_only, {"k1": (3e3, 2e4)}, 5, tiny_shear())
    # a locus the shear test cannot be set up for, named where the data holds it: a sigma_pre
    # the base law cannot carry within the overlap limit (K1 = 5e3 N/m at 5 MPa)
    hard = {"sigma_pre": 5e6, "points": [_pt(1e6, 1e6), _pt(2e6, 1.5e6)]}
    with pytest.raises(engine.ParameterError) as e:
        cal_module.check_request(
            BASE,
            LabTargets.from_dict({"tester": "jenike", "shear": [LOCUS, hard]}),
            {"mu_s": (0.2, 0.8)},
            5,
        )
    assert e.value.field.startswith("LabTargets.shear[1]"), str(e.value)
    assert stand_ins["shear"] == []
