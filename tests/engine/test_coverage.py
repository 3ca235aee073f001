"""The verdict rule keeps the rates it states: proven by simulation (docs/PHYSICS.md
section 7).

Synthetic studies with known true errors and spreads are judged by the advisor's own
functions. A variant whose true error is at (or beyond) the tolerance must be called
``equivalent`` in at most 5 % of studies, and one at (or inside) it ``differs`` in at most
5 %, for 2 to 12 seeds on either side and coarse spreads up to 3x the reference's. The bound
has a Monte Carlo margin of three binomial standard errors. The old rule (error ± 2u, the
factor of the normal distribution) fails the same test, which shows the test can fail.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from engine.study import advisor

N = 1200
BOUND = 0.05 + 3 * math.sqrt(0.05 * 0.95 / N)
TOL = 0.15
CONS = 2e4


def _old_rule(name, values, ref, tol):
    """The rule before issue 19: RMS error ± 2u, u from the two spreads."""
    a = np.array([v[name] for v in values])
    mean, rm = a.mean(0), ref["mean"]
    err = float(np.sqrt(np.mean(((mean - rm) / rm) ** 2)))
    sd_c = a.std(0, ddof=1) if len(a) > 1 else ref["sd"]
    u = float(np.sqrt(np.mean((ref["sd"] / rm) ** 2 / ref["seeds"] + (sd_c / rm) ** 2 / len(a))))
    return "equivalent" if err + 2 * u <= tol else "differs" if err - 2 * u > tol else "undecided"


def _new_rule(name, values, ref, tol):
    alpha_e, alpha_d = advisor.error_rates(advisor.CONFIDENCE, 1)
    return advisor.judge_metric(name, values, ref, tol, CONS, alpha_e, alpha_d)["verdict"]


def _rates(
    rule,
    n_ref,
    n_coarse,
    true_error,
    spread_ratio,
    sd=0.1,
    n=N,
    seed=0,
    name="loading_stiffness",
    tol=TOL,
):
    """Fractions of studies called equivalent and differs, for a scalar metric with
    reference mean 1, reference spread ``sd`` and coarse spread ``spread_ratio * sd``."""
    rng = np.random.default_rng(seed)
    eq = di = 0
    for _ in range(n):
        r = rng.normal(1.0, sd, n_ref)
        c = rng.normal(1.0 + true_error, spread_ratio * sd, n_coarse)
        ref = advisor.noise_floor([{name: np.array([x])} for x in r], [name], CONS)[name]
        v = rule(name, [{name: np.array([x])} for x in c], ref, tol)
        eq += v == "equivalent"
        di += v == "differs"
    return eq / n, di / n


CASES = [(2, 2, 1.0), (3, 2, 3.0), (2, 12, 1.0), (12, 2, 3.0), (5, 5, 3.0), (12, 12, 1.0)]


@pytest.mark.parametrize(("n_ref", "n_coarse", "k"), CASES)
@pytest.mark.parametrize("side", [1.0, -1.0])
def test_the_rule_keeps_its_rates_at_the_tolerance(n_ref, n_coarse, k, side):
    # at the tolerance a true error is both "not inside" (equivalent would be wrong) and
    # "not beyond" (differs would be wrong): the worst case of both rates
    eq, di = _rates(_new_rule, n_ref, n_coarse, side * TOL, k, seed=n_ref * 100 + n_coarse)
    assert eq <= BOUND, f"equivalent said of a variant at the tolerance in {eq:.1%}"
    assert di <= BOUND, f"differs said of a variant at the tolerance in {di:.1%}"


def test_differs_keeps_its_rate_when_the_tolerance_is_small_against_the_noise():
    # either end of the differs interval may clear its bound: with a tolerance far below
    # the noise both tails count, so each end is tested at alpha / 2 (found in review:
    # 7.4 % wrong differs at a nominal 5 % with alpha per end)
    _, di = _rates(_new_rule, 12, 12, 0.01, 30.0, sd=0.01, seed=5, tol=0.01)
    assert di <= BOUND


def test_the_old_factor_two_fails_the_same_test():
    worst = max(
        max(_rates(_old_rule, nr, nc, TOL, k, seed=nr * 100 + nc))
        for nr, nc, k in [(2, 12, 1.0), (12, 2, 3.0)]
    )
    assert worst > BOUND


def test_beyond_and_inside_the_tolerance():
    # clearly beyond: never equivalent; clearly inside: never differs
    eq, _ = _rates(_new_rule, 3, 3, 1.5 * TOL, 1.0, n=400, seed=7)
    _, di = _rates(_new_rule, 3, 3, 0.3 * TOL, 1.0, n=400, seed=8)
    assert eq <= BOUND and di <= BOUND


def test_the_rule_decides_with_enough_seeds():
    # not "always undecided": 12 seeds each decide a zero error and a doubled one
    eq, _ = _rates(_new_rule, 12, 12, 0.0, 1.0, sd=0.05, n=200, seed=9)
    _, di = _rates(_new_rule, 12, 12, 2 * TOL, 1.0, sd=0.05, n=200, seed=10)
    assert eq > 0.9 and di > 0.9


def _curve_rates(true_error, n_ref, n_coarse, n=300, seed=0):
    """A density curve of 32 levels: each seed's curve is the true one times (1 + a
    seed-wide offset + per-level noise); the true error is ``true_error`` at the worst
    level and half of it elsewhere (a curve that touches the tolerance at one level)."""
    rng = np.random.default_rng(seed)
    levels = 32
    base = np.linspace(0.55, 0.62, levels)
    shape = np.full(levels, 0.5 * true_error)
    shape[levels // 3] = true_error
    eq = di = 0
    for _ in range(n):

        def draw(k, rel):
            return [
                {
                    "density": base
                    * (1 + rel)
                    * (1 + rng.normal(0, 0.01) + rng.normal(0, 0.004, levels))
                }
                for _ in range(k)
            ]

        ref = advisor.noise_floor(draw(n_ref, 0.0), ["density"], CONS)["density"]
        ae, ad = advisor.error_rates(advisor.CONFIDENCE, 1)
        v = advisor.judge_metric("density", draw(n_coarse, shape), ref, 0.03, CONS, ae, ad)[
            "verdict"
        ]
        eq += v == "equivalent"
        di += v == "differs"
    return eq / n, di / n


def test_curve_metric_rates():
    bound = 0.05 + 3 * math.sqrt(0.05 * 0.95 / 300)
    eq, _ = _curve_rates(0.03, 3, 2, seed=1)
    assert eq <= bound
    # a curve at the tolerance at one level and half of it elsewhere is inside: not differs
    _, di = _curve_rates(0.03, 2, 3, seed=2)
    assert di <= bound
    # and the rule decides a clearly equivalent curve with a few seeds
    eq, _ = _curve_rates(0.0, 5, 5, n=100, seed=3)
    assert eq > 0.5


def _adaptive_rates(true_error, spread_ratio, n=N, seed=0, sd=0.1, peek_free=False):
    """Adaptive studies of one variant (engine.study.adaptive.next_runs picks the runs, the
    advisor judges each round): fractions finally called equivalent and differs.
    ``peek_free``: judge every look at the full rate (the rule without alpha spending)."""
    from types import SimpleNamespace

    from engine.study.adaptive import next_runs

    name = "loading_stiffness"
    spec = SimpleNamespace(
        reference=SimpleNamespace(consolidation_stress=CONS),
        tolerances={name: TOL},
        confidence=advisor.CONFIDENCE,
        decide=True,
        max_seeds=10,
        max_reference_seeds=5,
        rounds=3,
        budget=None,
    )
    spec.looks = 1 if peek_free else spec.rounds + 1
    rng = np.random.default_rng(seed)
    key = (5e-3, "rule")
    costs = {"reference": 8.0, key: 1.0}
    eq = di = 0
    for _ in range(n):
        refs = [{name: np.array([x])} for x in rng.normal(1.0, sd, 3)]
        coarse = [{name: np.array([x])} for x in rng.normal(1 + true_error, spread_ratio * sd, 2)]
        for round_no in range(1, spec.rounds + 2):
            _, verdicts = advisor.judge_groups(spec, refs, {key: coarse}, [name], looks=spec.looks)
            v = verdicts[0]["verdict"]
            if v != "undecided" or round_no > spec.rounds:
                break
            adds = next_runs(spec, refs, {key: coarse}, verdicts, costs, round_no, None)
            if not adds:
                break
            for a in adds:
                if a.kind == "reference":
                    refs.append({name: np.array([rng.normal(1.0, sd)])})
                else:
                    coarse.append({name: np.array([rng.normal(1 + true_error, spread_ratio * sd)])})
        eq += v == "equivalent"
        di += v == "differs"
    return eq / n, di / n


@pytest.mark.parametrize(("side", "k"), [(1.0, 1.0), (-1.0, 3.0)])
def test_the_adaptive_rule_keeps_its_rates(side, k):
    eq, di = _adaptive_rates(side * TOL, k, seed=int(10 * k))
    assert eq <= BOUND and di <= BOUND


def test_the_adaptive_rule_decides_what_a_fixed_study_leaves_open():
    # a true error of 3 % against 15 % with spreads of 4 %: 3 + 2 seeds leave it open
    # (t = 6.3 at 1 degree of freedom), the added seeds decide most studies
    fixed, _ = _rates(_new_rule, 3, 2, 0.03, 1.0, sd=0.04, n=300, seed=11)
    adaptive, _ = _adaptive_rates(0.03, 1.0, sd=0.04, n=300, seed=11)
    assert adaptive > fixed + 0.3
