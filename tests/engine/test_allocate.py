"""Seeds where they decide (engine.study.allocate), on made-up groups: the rule under test
first at an equal chance, no seed for a variant its headline metric already tells apart,
controls reserved in the budget with the coarse seeds they pair with, nothing for a
hopeless variant."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from engine.study import judge
from engine.study.allocate import headline, next_runs
from engine.study.noise import StudyNoise

from .helpers import deciding_spec

CONS = 2e4
R = 5e-3


def _spec(rules=("paper", "foil"), budget=None, max_seeds=10):
    names = ("loading_stiffness", "strength")
    rule_names = tuple(SimpleNamespace(name=r) for r in rules)
    tolerances = dict.fromkeys(names, 0.15)
    return deciding_spec(
        tolerances, rule_names, max_seeds, budget=budget, consolidation_stress=CONS
    ), names


def _values(rng, n, ratio, sd):
    """``n`` seeds whose log values have mean log(ratio) and sample spread ``sd`` exactly
    (standardised draws), so that a test's outcome does not hang on one draw."""
    out = []
    z = rng.normal(size=(2, n))
    z = (z - z.mean(axis=1, keepdims=True)) / z.std(axis=1, ddof=1, keepdims=True)
    for i in range(n):
        out.append(
            {
                "loading_stiffness": np.array([1e5 * ratio * np.exp(sd * z[0, i])]),
                "strength": np.array([1e4 * ratio * np.exp(sd * z[1, i])]),
                "failed": 1.0,
            }
        )
    return out


def _paper_alone(seed, ref_sd, ratio, sd, reference_cost, max_seeds):
    """The paper rule alone at radius R: 3 reference seeds of spread ``ref_sd`` and 3 coarse
    ones at ``ratio`` of spread ``sd`` (drawn from ``seed``), a coarse run costing 1 and a
    reference run ``reference_cost``: (spec, names, groups, refs, costs)."""
    spec, names = _spec(("paper",), max_seeds=max_seeds)
    rng = np.random.default_rng(seed)
    refs = _values(rng, 3, 1.0, ref_sd)
    groups = {(R, "paper"): _values(rng, 3, ratio, sd)}
    costs = {"reference": reference_cost, (R, "paper"): 1.0}
    return spec, names, groups, refs, costs


def _round(spec, names, groups, refs, costs, budget=None, control_costs=None):
    noise = StudyNoise(refs, groups, names, CONS)
    ae, ad = judge.error_rates(spec.confidence, len(names), 1, spec.looks)
    verdicts = [judge.judge_group(noise, k, spec.tolerances, ae, ad) for k in groups]
    return next_runs(spec, noise, verdicts, costs, 1, budget, None, control_costs), verdicts


def test_the_rule_under_test_comes_first_at_an_equal_chance():
    spec, names = _spec(("paper", "foil"))
    rng = np.random.default_rng(1)
    refs = _values(rng, 3, 1.0, 0.02)
    same = _values(rng, 3, 1.0, 0.06)
    groups = {(R, "foil"): same, (R, "paper"): [dict(v) for v in same]}
    costs = {"reference": 8.0, (R, "paper"): 1.0, (R, "foil"): 1.0}
    adds, _ = _round(spec, names, groups, refs, costs)
    coarse = [a for a in adds if a.kind == "coarse"]
    assert coarse and coarse[0].variant == (R, "paper")
    # and with the order of the rules turned round, the other one does
    spec2, _ = _spec(("foil", "paper"))
    adds2, _ = _round(spec2, names, groups, refs, costs)
    assert next(a for a in adds2 if a.kind == "coarse").variant == (R, "foil")


def test_no_seed_for_a_variant_its_headline_metric_tells_apart():
    spec, names = _spec(("paper", "unscaled"))
    assert headline(names) == "strength"
    rng = np.random.default_rng(2)
    refs = _values(rng, 3, 1.0, 0.02)
    groups = {
        (R, "paper"): _values(rng, 3, 1.02, 0.06),
        (R, "unscaled"): _values(rng, 3, 0.45, 0.05),  # -55 %: its strength tells it apart
    }
    costs = {"reference": 8.0, (R, "paper"): 1.0, (R, "unscaled"): 1.0}
    adds, _ = _round(spec, names, groups, refs, costs)
    assert all(a.variant != (R, "unscaled") for a in adds), adds
    assert any(a.variant == (R, "paper") for a in adds)


def test_a_control_is_reserved_with_each_coarse_seed():
    spec, names, groups, refs, costs = _paper_alone(3, 0.02, 1.0, 0.06, 100.0, max_seeds=10)
    # a budget of two coarse runs: two seeds alone, or one seed and its control
    free, _ = _round(spec, names, groups, refs, costs, budget=2.0)
    paired, _ = _round(spec, names, groups, refs, costs, budget=2.0, control_costs={R: 1.0})
    n_free = sum(a.kind == "coarse" for a in free)
    n_paired = sum(a.kind == "coarse" for a in paired)
    assert n_free == 2 and n_paired == 1, (free, paired)
    assert "with its resolution control" in paired[0].reason


def test_nothing_for_a_variant_at_its_tolerance():
    # an error sitting at the tolerance with a small spread: no seed count within the caps
    # decides it, so it takes none (futility: stopping never makes a wrong verdict)
    spec, names, groups, refs, costs = _paper_alone(4, 0.001, 1.15, 0.001, 8.0, max_seeds=6)
    adds, verdicts = _round(spec, names, groups, refs, costs)
    assert verdicts[0]["verdict"] == "undecided" and adds == []


def test_a_study_that_stops_is_judged_at_its_last_look():
    # while rounds may follow, the pilot's share of the rate (look 1), one more look per
    # round that added runs; once stopped, the last look: no look follows, and the rates of
    # the looks not taken add to alpha on the data the study has (a union bound)
    from engine.study.judge import look_alpha
    from engine.study.plan import final_look

    spec = SimpleNamespace(decide=True, looks=3)
    assert final_look(spec, [], None) == 1
    assert final_look(spec, [{"round": 1}], None) == 2
    assert final_look(spec, [], "no undecided verdict can be decided") == 3
    assert final_look(spec, [{"round": 1}], "every verdict decided") == 3
    assert final_look(SimpleNamespace(decide=False, looks=1), [], "x") == 1
    # every look's rate summed over the looks is alpha: judging once more at the last look
    # with the same data spends no more than the design allows
    assert sum(look_alpha(0.95, k, 3) for k in (1, 2, 3)) == pytest.approx(0.05)


def test_each_kind_s_headline_is_its_own():
    """The allocator reads the headline metric of the study's kind: a hopper study that adds
    seeds looked for a loading_stiffness it has not (KeyError) before the kind declared it."""
    assert headline(("discharge_number", "bulk_density")) == "discharge_number"
    assert headline(("bulk_density", "discharge_number")) == "discharge_number"
    assert headline(("density", "loading_stiffness", "strength")) == "strength"
    assert headline(("density", "loading_stiffness")) == "loading_stiffness"
    assert headline(("sigma_c", "ffc", "bulk_density")) == "ffc"


def test_the_one_level_chance_is_the_array_path(monkeypatch):
    """Comparison.chance's path for one level (numbers, its terms converted once) gives the
    same doubles as the array path every metric takes: unpaired, paired and pooled (shared)
    comparisons, projected seed counts, a given truth."""
    from engine.study.comparison import Comparison, Space
    from engine.study.pooling import Spread

    rng = np.random.default_rng(5)
    comps = []
    for i in range(300):
        nc, nr = int(rng.integers(2, 7)), int(rng.integers(2, 7))
        c = rng.normal(0.05 * rng.normal(), 0.1, (nc, 1))
        r = rng.normal(0.0, 0.05, (nr, 1))
        kind = i % 3
        if kind == 2:  # paired
            r = rng.normal(0.0, 0.05, (nc, 1))
            comps.append(Comparison(Space("log"), c, r, None, None, 0.15, paired=True))
            continue
        pool = ("a", "b") if kind == 1 else ("a",)
        vc, vr = float(rng.uniform(1e-4, 0.02)), float(rng.uniform(1e-4, 0.02))
        sc = Spread(np.array([vc]), vc, float(nc - 1 + 3 * kind), kind == 1, pool)
        sr = Spread(np.array([vr]), vr, float(nr - 1 + 3 * kind), kind == 1, pool)
        comps.append(Comparison(Space("log"), c, r, sc, sr, 0.15))
    cases = [
        (comp, int(comp.nc + rng.integers(0, 4)), int(comp.nr + rng.integers(0, 3)), truth)
        for comp in comps
        for truth in (None, 0.0, float(rng.normal(0, 0.1)))
    ]
    fast = [comp.chance(n, m, 0.025, 0.005, truth) for comp, n, m, truth in cases]
    assert all(comp._level_terms for comp in comps)  # the one-level path was taken
    monkeypatch.setattr(Comparison, "_one_level", lambda self, *a: None)
    slow = [comp.chance(n, m, 0.025, 0.005, truth) for comp, n, m, truth in cases]
    assert fast == slow
    assert len({p for p, _ in fast}) > 100  # chances of all sizes, not a few constants
