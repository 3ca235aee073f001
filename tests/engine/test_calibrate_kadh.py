"""Consolidation-dependent adhesion in the calibration (issue 41 item 3, docs/CALIBRATION.md
"Consolidation-dependent adhesion"): a kadh box is checked once, naming the field, against
the bound the law's branches give (at most 10 K2); the EEPA exponents are calibratable where
the law has them as fields; and a flow function whose cohesion grows with the pre-shear
stress moves kadh off 0, where a calibration with kadh held at 0 cannot meet it. The shear
test is a closed-form stand-in (seconds, not the DEM): its cohesion is 1e4 m^-2 x |f0| plus
half the pre-shear stress times the law's contact consolidation coefficient (:func:`cohesion`),
so it grows with sigma_pre only where kadh > 0."""

from __future__ import annotations

import json
from dataclasses import replace

import pytest

import engine
from engine.calibration import LabTargets, calibrate
from engine.calibration.calibrate import KADH_MAX_RATIO, check_request
from tests.engine.test_calibrate import BASE
from tests.engine.test_calibrate_shear import _pt, cal_module, quicker_posterior

#: The untold law: K1 = 5e3, K2 = 2.5e4 N/m, f0 = -0.2 N, kadh = 2e3 N/m (0.4 K1), mu_s 0.5.
TRUTH = engine.BilinearAdhesive(k1=5e3, k2=2.5e4, f0=-0.2, kadh=2e3, mu_s=0.5)
#: What the calibration is told: the truth's K1, K2 and f0; kadh 0 and mu_s 0.3 to start.
START = replace(TRUTH, kadh=0.0, mu_s=0.3)
TEST = replace(BASE, pair_law=START)
#: Pre-shear stress [Pa] -> its points' normal stresses [Pa].
LOCI = {5e3: (1.5e3, 3.5e3), 1e4: (3e3, 7e3), 2e4: (6e3, 1.4e4)}


def kappa(law) -> float:
    """The contact consolidation coefficient of the bilinear law [-]: the pull-off force a
    contact gains per newton of preload, kadh (K2 - K1) / (K1 (K2 + kadh)) (unloaded from
    dmax along K2 onto the adhesive branch)."""
    return law.kadh * (law.k2 - law.k1) / (law.k1 * (law.k2 + law.kadh))


def cohesion(law, sigma_pre: float) -> float:
    """The stand-in's cohesion [Pa]: 1e4 m^-2 x |f0| plus half the pre-shear stress's pull-off
    gain, c = 1e4 |f0| + 0.5 kappa sigma_pre (kadh = 0: the same c at every sigma_pre, the
    flow function's slope from friction alone)."""
    return 1e4 * abs(law.f0) + 0.5 * kappa(law) * sigma_pre


def stand_in(tests, progress=None):
    """A shear test in closed form: tau = c + 0.8 mu_s sigma at each point (its normal
    stress 1 % above its target), tau_pre = c + 0.96 mu_s sigma_pre."""
    out = {}
    for t in tests:
        law, s = t.pair_law, t.preshear_stress
        c, m = cohesion(law, s), 0.8 * law.mu_s
        sig = [1.01 * x for x in t.normal_stresses]
        out[s] = {
            "test": json.loads(json.dumps(t.to_dict())),
            "points": [{"kind": "preshear", "sigma": s, "tau": c + 1.2 * m * s}]
            + [
                {"kind": "failure", "target": x, "sigma": y, "tau": c + m * y}
                for x, y in zip(t.normal_stresses, sig)
            ],
            "locus": {"slope": m, "cohesion": c, "sigma_1": 2 * s, "sigma_c": 2 * c, "ffc": 1.0},
            "scalars": {"preshear_sigma": s, "preshear_tau": c + 1.2 * m * s, "bulk_density": 1e3},
        }
    return out


def lab() -> LabTargets:
    """The truth's loci, each tau with a 3 % sd, tau_pre with 3 %."""
    loci = []
    for s, sns in LOCI.items():
        c, m = cohesion(TRUTH, s), 0.8 * TRUTH.mu_s
        tp = c + 1.2 * m * s
        loci.append(
            {
                "sigma_pre": s,
                "points": [_pt(x, c + m * x, 0.0, 0.03 * (c + m * x)) for x in sns],
                "tau_pre": tp,
                "tau_pre_sd": 0.03 * tp,
            }
        )
    return LabTargets.from_dict({"tester": "ring_shear", "shear": loci})


@pytest.fixture
def shear_stand_in(monkeypatch):
    quicker_posterior(monkeypatch)
    monkeypatch.setattr(cal_module, "run_shear_tests", stand_in)


def test_a_cohesion_that_grows_with_consolidation_moves_kadh_off_zero(shear_stand_in):
    box = {"kadh": (0.0, 1e4), "mu_s": (0.2, 0.8)}
    cal = calibrate(TEST, lab(), box, runs=10, waves=0, seed=2)
    p = cal.parameters["kadh"]
    lo, hi = p["interval"]
    assert lo <= TRUTH.kadh <= hi, p
    # the interval leaves 0 well behind: the data moved kadh, not the prior
    assert lo > 0.5 * TRUTH.kadh and p["status"] == "determined", p
    assert cal.all_met, cal.not_met
    # the cohesion's growth is kadh's: each locus's tau_pre moves with it more than with mu_s
    # at 20 kPa, where the pull-off gain is largest
    assert cal.sensitivity["tau@6000Pa:20000Pa"]["kadh"] > 0.3


def test_with_kadh_held_at_zero_the_flow_function_is_not_met(shear_stand_in):
    # the same data, kadh left at the law's 0: f0 sets one cohesion for every sigma_pre, so
    # the loci at 5 and 20 kPa cannot both be met (their cohesions differ by 2.2 kPa, each
    # tau's sd is 3 %, about 100 to 250 Pa)
    box = {"f0": (-0.4, -0.05), "mu_s": (0.2, 0.8)}
    cal = calibrate(TEST, lab(), box, runs=10, waves=0, seed=2)
    assert not cal.all_met
    assert any(q.startswith("tau@1500Pa:5000Pa") or "20000Pa" in q for q in cal.not_met)


def test_a_kadh_box_is_bounded_by_ten_k2_naming_the_field():
    targets = lab()
    k2 = START.k2
    ok = {"kadh": (0.0, KADH_MAX_RATIO * k2)}
    check_request(TEST, targets, ok, 5)
    with pytest.raises(engine.ParameterError, match=r"calibrate\.parameters\.kadh") as e:
        check_request(TEST, targets, {"kadh": (0.0, 1.01 * KADH_MAX_RATIO * k2)}, 5)
    assert "10 K2" in str(e.value) and "pull" in str(e.value)
    # with K2 calibrated too, the box's highest K2 bounds it
    check_request(TEST, targets, {"k2": (2.5e4, 8e4), "kadh": (0.0, 8e5)}, 5)
    # a negative kadh is the law's own bound
    with pytest.raises(engine.ParameterError, match=r"calibrate\.parameters\.kadh"):
        check_request(TEST, targets, {"kadh": (-1.0, 1e3)}, 5)


def test_the_eepa_exponents_are_calibratable_where_the_law_has_them():
    targets = lab()
    eepa = engine.EEPA(k1=5e5, k2=2.5e6, f0=-0.2, n=1.5, chi=1.5, mu_s=0.5)
    test = replace(BASE, pair_law=eepa)
    check_request(test, targets, {"n": (1.2, 1.8), "chi": (1.0, 2.0)}, 5)
    # chi != n: kadh [N/m^chi] against K2 [N/m^n] at the consolidation's overlap, named
    chi1 = replace(test, pair_law=replace(eepa, chi=1.0))
    with pytest.raises(engine.ParameterError, match=r"calibrate\.parameters\.kadh") as e:
        check_request(chi1, targets, {"kadh": (0.0, 1e9)}, 5)
    assert "d_c" in str(e.value)
    # the bilinear law has n = chi = 1 by definition: no field to calibrate
    with pytest.raises(engine.ParameterError, match=r"calibrate\.parameters\.n"):
        check_request(TEST, targets, {"n": (1.0, 1.5)}, 5)


def test_vary_seed_packs_each_run_its_own_sample(monkeypatch, tmp_path):
    # each run's shear tests at the cell's seed plus the run's index, the check run the
    # next; a rerun on the store finds them all (the same seeds) and runs nothing
    quicker_posterior(monkeypatch)
    seeds = []

    def heard(tests, progress=None):
        seeds.append({t.seed for t in tests})
        return stand_in(tests, progress)

    monkeypatch.setattr(cal_module, "run_shear_tests", heard)
    box = {"kadh": (0.0, 1e4)}
    calibrate(TEST, lab(), box, runs=4, waves=0, seed=2, store=tmp_path, vary_seed=True)
    base = engine.calibration.forward.shear_cell(TEST)["seed"]
    assert seeds == [{base + i} for i in range(5)]
    calibrate(TEST, lab(), box, runs=4, waves=0, seed=2, store=tmp_path, vary_seed=True)
    assert len(seeds) == 5


def test_a_packing_seed_that_cannot_be_placed_is_left_out(monkeypatch):
    # with vary_seed a run's own seed may not place its fill (the engine refuses the
    # pour_fraction for it): that run is left out; any other refusal is raised
    quicker_posterior(monkeypatch)
    calls = []

    def shear(tests, progress=None, field="UniaxialTest.pour_fraction"):
        calls.append(tests)
        if len(calls) == 2:
            raise engine.ParameterError(field, 0.3, "low enough for the fill to be placed")
        return stand_in(tests, progress)

    monkeypatch.setattr(cal_module, "run_shear_tests", shear)
    box = {"kadh": (0.0, 1e4)}
    cal = calibrate(TEST, lab(), box, runs=4, waves=0, seed=2, vary_seed=True)
    errors = [r["error"] for r in cal.runs if "error" in r]
    assert len(errors) == 1 and "pour_fraction" in errors[0]
    calls.clear()
    monkeypatch.setattr(
        cal_module, "run_shear_tests", lambda t, p=None: shear(t, p, "ShearTest.cell")
    )
    with pytest.raises(engine.ParameterError, match=r"ShearTest\.cell"):
        calibrate(TEST, lab(), box, runs=4, waves=0, seed=2, vary_seed=True)
