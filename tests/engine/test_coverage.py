"""The verdict rule keeps the rates it states and decides with the seeds a user pays for:
proven by simulation (docs/PHYSICS.md section 7).

Synthetic studies with known true errors and spreads are judged by the study's own
functions: :func:`engine.study.judge.judge_samples` (many studies of a scalar metric at
once, checked here to agree with :func:`~engine.study.judge.judge_metric`), and for the
adaptive rule :func:`engine.study.adaptive.next_runs` with
:func:`~engine.study.judge.judge_groups`, round by round.

- **Coverage**: a variant whose true error is at the tolerance is called ``equivalent`` in at
  most 5 % of studies, and ``differs`` in at most 5 %, for 2 to 12 seeds on either side,
  coarse spreads 1x to 5x the reference's, normal, lognormal and contaminated values (one
  seed in ten from a second mode 30 % below or above), with a Monte Carlo margin of three
  binomial standard errors. The plain two one-sided tests (alpha per end) fail the same
  test, which shows that it can fail.
- **Power**: 3 reference seeds with a 3 % spread against a coarse spread of 10 %: the rule
  calls a true error of 0 ``equivalent``, and one of twice the tolerance ``differs``, in 80 %
  of studies with at most 1.5x (+1) the coarse seeds that a z-test knowing both spreads
  needs at the same error rates per metric, end and look. The rule before issue 28 (Fieller's
  ratio with min(n) - 1 degrees of freedom) fails it.
- **Adaptive**: the same rates at the tolerance, and the mean number of coarse seeds it ends
  with within 1.5x (+1) of that oracle's.
"""

from __future__ import annotations

import functools
import math
from types import SimpleNamespace

import numpy as np
import pytest

from engine.study import judge
from engine.study.allocate import next_runs
from engine.study.intervals import hsu_df, t_quantile
from engine.study.noise import Space, StudyNoise

from .helpers import deciding_spec

CONS = 2e4
TOL = 0.15
LO, HI = math.log(1 - TOL), math.log(1 + TOL)
ALPHA = 1 - judge.CONFIDENCE


def _bound(n: int) -> float:
    return ALPHA + 3 * math.sqrt(ALPHA * (1 - ALPHA) / n)


@functools.cache
def _normal_log_mean(sd: float) -> float:
    """E[log X] of X normal with mean 1 and spread ``sd`` (Gauss-Hermite quadrature)."""
    z, w = np.polynomial.hermite_e.hermegauss(120)
    return float(np.sum(w * np.log(np.clip(1 + sd * z, 1e-12, None))) / np.sum(w))


def _draw(rng, shape, ratio: float, sd: float, kind: str) -> np.ndarray:
    """Values whose true geometric mean is ``ratio`` (the reference's is 1): ``normal``
    (normal with spread ``sd`` relative to its mean, scaled so that its geometric mean is
    ``ratio``), ``lognormal`` (log spread ``sd``), ``low``/``high``: the lognormal with one
    value in ten from a second mode 30 % below or above (scaled likewise)."""
    if kind == "normal":
        x = np.clip(rng.normal(1.0, sd, shape), 1e-12, None)
        return ratio * x / math.exp(_normal_log_mean(sd))
    x = ratio * np.exp(rng.normal(0.0, sd, shape))
    if kind in ("low", "high"):
        x = np.where(rng.random(shape) < 0.1, x * (0.7 if kind == "low" else 1.3), x)
        x = x / math.exp(0.1 * math.log(0.7 if kind == "low" else 1.3))
    return x


def _rates(n_ref, n_coarse, ratio, k, kind, n=4000, sd=0.05, seed=0, ae=None, ad=None):
    """Fractions of ``n`` studies called equivalent and differs (one scalar metric; the
    reference spread ``sd``, the coarse one ``k`` times it)."""
    rng = np.random.default_rng(seed)
    r = _draw(rng, (n, n_ref), 1.0, sd, kind)
    c = _draw(rng, (n, n_coarse), ratio, k * sd, kind)
    if ae is None:
        ae, ad = judge.error_rates(judge.CONFIDENCE, 1)
    v = judge.judge_samples(c, r, TOL, ae, ad)
    return float(np.mean(v == "equivalent")), float(np.mean(v == "differs"))


def test_the_fast_path_is_the_rule():
    # judge_samples (many studies at once) gives judge_metric's verdict study by study
    rng = np.random.default_rng(1)
    ae, ad = judge.error_rates(judge.CONFIDENCE, 1)
    for n_ref, n_coarse in [(2, 2), (3, 7), (12, 3), (5, 5)]:
        r = np.exp(rng.normal(0, 0.05, (60, n_ref)))
        c = np.exp(rng.normal(rng.choice([0.0, 0.1, 0.2]), 0.1, (60, n_coarse)))
        fast = judge.judge_samples(c, r, TOL, ae, ad)
        for i in range(60):
            m = judge.judge_values(
                "k",
                [{"k": np.array([x])} for x in c[i]],
                [{"k": np.array([x])} for x in r[i]],
                TOL,
                CONS,
                ae,
                ad,
            )
            assert m["verdict"] == fast[i]
    assert set(fast) == {"equivalent", "differs", "undecided"}


SEEDS = (2, 3, 5, 12)
KINDS = ("normal", "lognormal", "low", "high")


@pytest.mark.parametrize("kind", KINDS)
def test_the_rule_keeps_its_rates_at_the_tolerance(kind):
    # at the tolerance a true error is both "not inside" (equivalent would be wrong) and
    # "not beyond" (differs would be wrong): the worst case of both rates
    n = 4000
    worst = []
    for n_ref in SEEDS:
        for n_coarse in SEEDS:
            for k in (1.0, 3.0, 5.0):
                for ratio in (1 + TOL, 1 - TOL):
                    seed = 1000 * n_ref + 10 * n_coarse + int(k) + (ratio > 1)
                    eq, di = _rates(n_ref, n_coarse, ratio, k, kind, n=n, seed=seed)
                    worst.append((max(eq, di), n_ref, n_coarse, k, ratio))
    top = max(worst)
    assert top[0] <= _bound(n), f"{kind}: wrong verdict in {top[0]:.1%} at {top[1:]}"


def test_plain_two_one_sided_tests_fail_the_same_test():
    # alpha per end (the two-sided 90 % interval) with Welch-Satterthwaite on logs: 3 seeds
    # against 12 with equal spreads and skewed values cover less than stated
    eq, _ = _rates(3, 12, 1 + TOL, 1.0, "normal", n=20_000, seed=5, ae=ALPHA, ad=ALPHA / 2)
    assert eq > _bound(20_000)


def test_differs_keeps_its_rate_when_the_tolerance_is_small_against_the_noise():
    # either end of the differs interval may clear its bound: with a tolerance far below
    # the noise both tails count, so each end is tested at alpha / 2
    rng = np.random.default_rng(5)
    r = np.exp(rng.normal(0, 0.01, (4000, 12)))
    c = np.exp(rng.normal(0.01, 0.3, (4000, 12)))
    ae, ad = judge.error_rates(judge.CONFIDENCE, 1)
    v = judge.judge_samples(c, r, 0.01, ae, ad)
    assert np.mean(v == "differs") <= _bound(4000)


def test_beyond_and_inside_the_tolerance():
    # clearly beyond: never equivalent; clearly inside: never differs
    eq, _ = _rates(3, 3, 1.5 * (1 + TOL), 1.0, "lognormal", seed=7)
    _, di = _rates(3, 3, 1.05, 1.0, "lognormal", seed=8)
    assert eq <= _bound(4000) and di <= _bound(4000)


# power: the issue-28 scenario
SD_REF, SD_COARSE, N_REF = 0.03, 0.10, 3


def _z(p: float) -> float:
    return t_quantile(p, math.inf)


def _oracle_equivalent(alpha_end: float, power=0.8) -> int:
    """Fewest coarse seeds with which a z-test knowing both spreads calls a true error of 0
    equivalent in ``power`` of studies, each end at ``alpha_end``."""
    z = _z(1 - alpha_end)
    for n in range(2, 200):
        u = math.sqrt(SD_COARSE**2 / n + SD_REF**2 / N_REF)
        p = 0.5 * math.erfc(-(HI - z * u) / u / math.sqrt(2)) - 0.5 * math.erfc(
            -(LO + z * u) / u / math.sqrt(2)
        )
        if p >= power:
            return n
    raise AssertionError


def _oracle_differs(alpha_end: float, power=0.8) -> int:
    """Fewest coarse seeds with which it calls a true error of twice the tolerance (above,
    the nearer of the two) differs in ``power`` of studies, each end at ``alpha_end``."""
    z = _z(1 - alpha_end)
    d = math.log(1 + 2 * TOL)
    for n in range(2, 200):
        u = math.sqrt(SD_COARSE**2 / n + SD_REF**2 / N_REF)
        if 0.5 * math.erfc(-((d - HI) / u - z) / math.sqrt(2)) >= power:
            return n
    raise AssertionError


def _power(rule, ratio: float, n_coarse: int, n=4000, seed=0) -> tuple[float, float]:
    rng = np.random.default_rng(seed)
    r = np.exp(rng.normal(0, SD_REF, (n, N_REF)))
    c = ratio * np.exp(rng.normal(0, SD_COARSE, (n, n_coarse)))
    v = rule(c, r)
    return float(np.mean(v == "equivalent")), float(np.mean(v == "differs"))


def _new_rule(c, r):
    ae, ad = judge.error_rates(judge.CONFIDENCE, 1)
    return judge.judge_samples(c, r, TOL, ae, ad)


def _old_rule(c, r):
    """The rule before issue 28: Fieller's interval of the ratio of means with
    min(n_c, n_r) - 1 degrees of freedom, alpha per end for equivalence and alpha / 2 for
    differs (one metric, one look)."""

    def fieller(mc, mr, vc, vr, t):
        a = mr * mr - t * t * vr
        if a <= 0:
            return -math.inf, math.inf
        b, cc = -2 * mc * mr, mc * mc - t * t * vc
        root = math.sqrt(max(b * b - 4 * a * cc, 0.0))
        return (-b - root) / (2 * a) - 1, (-b + root) / (2 * a) - 1

    df = hsu_df(c.shape[1], r.shape[1])
    te, td = t_quantile(1 - ALPHA, df), t_quantile(1 - ALPHA / 2, df)
    out = []
    for ci, ri in zip(c, r):
        st = (ci.mean(), ri.mean(), ci.var(ddof=1) / len(ci), ri.var(ddof=1) / len(ri))
        lo, hi = fieller(*st, te)
        dlo, dhi = fieller(*st, td)
        out.append(
            "differs"
            if dlo > TOL or dhi < -TOL
            else "equivalent"
            if lo >= -TOL and hi <= TOL
            else "undecided"
        )
    return np.array(out)


def _allowed(n_oracle: int) -> int:
    return int(1.5 * n_oracle + 1)


def test_power_equivalent_at_zero_error():
    ae, _ = judge.error_rates(judge.CONFIDENCE, 1)
    n = _allowed(_oracle_equivalent(ae))
    eq, _ = _power(_new_rule, 1.0, n, seed=11)
    assert eq >= 0.8, f"equivalent in {eq:.0%} with {n} coarse seeds"
    # the old rule, against its own oracle (alpha per end), fails with that allowance
    n_old = _allowed(_oracle_equivalent(ALPHA))
    eq_old, _ = _power(_old_rule, 1.0, n_old, n=1000, seed=11)
    assert eq_old < 0.8


def test_power_differs_at_twice_the_tolerance():
    _, ad = judge.error_rates(judge.CONFIDENCE, 1)
    n = _allowed(_oracle_differs(ad))
    _, di = _power(_new_rule, 1 + 2 * TOL, n, seed=12)
    _, di_low = _power(_new_rule, 1 - 2 * TOL, n, seed=13)
    assert di >= 0.8 and di_low >= 0.8, f"differs in {di:.0%} / {di_low:.0%} with {n} seeds"
    _, di_old = _power(_old_rule, 1 + 2 * TOL, n, n=1000, seed=12)
    assert di_old < 0.8


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
    ae, ad = judge.error_rates(judge.CONFIDENCE, 1)
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

        v = judge.judge_values(
            "density", draw(n_coarse, shape), draw(n_ref, 0.0), 0.03, CONS, ae, ad
        )
        eq += v["verdict"] == "equivalent"
        di += v["verdict"] == "differs"
    return eq / n, di / n


def test_curve_metric_rates():
    bound = ALPHA + 3 * math.sqrt(ALPHA * (1 - ALPHA) / 300)
    eq, _ = _curve_rates(0.03, 3, 3, seed=1)
    assert eq <= bound
    # a curve at the tolerance at one level and half of it elsewhere is inside: not differs
    _, di = _curve_rates(0.03, 3, 3, seed=2)
    assert di <= bound
    # and the rule decides a clearly equivalent curve with a few seeds
    eq, _ = _curve_rates(0.0, 5, 5, n=100, seed=3)
    assert eq > 0.5


def _adaptive(
    ratio, sd_ref=SD_REF, sd_coarse=SD_COARSE, kind="lognormal", n=1000, seed=0, rounds=1
):
    """Adaptive studies of one variant from a pilot of 3 + 3 seeds (engine.study.allocate.
    next_runs picks the runs of each round, engine.study.judge judges each look, as
    engine.study.plan.plan_runs does): the fractions finally called equivalent and differs,
    and the mean number of added coarse seeds."""
    name = "loading_stiffness"
    spec = deciding_spec(
        {name: TOL}, (SimpleNamespace(name="rule"),), 30, 10, rounds, consolidation_stress=CONS
    )
    rng = np.random.default_rng(seed)
    key = (5e-3, "rule")
    costs = {"reference": 8.0, key: 1.0}  # a reference run costs 8 coarse ones (2x radius)

    def one(r, sd):
        return {name: np.array([_draw(rng, 1, r, sd, kind)[0]])}

    eq = di = added = 0
    for _ in range(n):
        refs = [one(1.0, sd_ref) for _ in range(3)]
        coarse = [one(ratio, sd_coarse) for _ in range(3)]
        look = 1
        for round_no in range(1, rounds + 1):
            noise = StudyNoise(refs, {key: coarse}, [name], CONS)
            ae, ad = judge.error_rates(spec.confidence, 1, look, spec.looks)
            verdicts = [judge.judge_group(noise, key, spec.tolerances, ae, ad)]
            adds = next_runs(spec, noise, verdicts, costs, round_no, None)
            if not adds:
                break
            for a in adds:
                if a.kind == "reference":
                    refs.append(one(1.0, sd_ref))
                else:
                    coarse.append(one(ratio, sd_coarse))
            look += 1
        _, verdicts = judge.judge_groups(
            spec, refs, {key: coarse}, [name], look=look, looks=spec.looks
        )
        eq += verdicts[0]["verdict"] == "equivalent"
        di += verdicts[0]["verdict"] == "differs"
        added += len(coarse) - 3
    return eq / n, di / n, added / n


@pytest.mark.parametrize(
    ("ratio", "sd_ref", "sd_coarse", "kind"),
    [
        (1 + TOL, SD_REF, SD_COARSE, "lognormal"),
        (1 - TOL, SD_REF, SD_COARSE, "normal"),
        (1 + TOL, 0.1, 0.1, "low"),
        (1 - TOL, 0.03, 0.15, "high"),
    ],
)
def test_the_adaptive_rule_keeps_its_rates(ratio, sd_ref, sd_coarse, kind):
    n = 1500
    eq, di, _ = _adaptive(ratio, sd_ref, sd_coarse, kind, n=n, seed=int(100 * ratio))
    assert eq <= _bound(n) and di <= _bound(n), (eq, di)


def test_the_adaptive_rule_ends_with_about_the_seeds_an_oracle_needs():
    # the oracle knows both spreads: it runs what a z-test at the final look's rates needs
    # for 80 % power. The adaptive rule ends with at most 1.5x (+1) its coarse seeds, and
    # with no more added seeds than a fixed study that reaches the same power. (In added
    # seeds alone the oracle's 3 are out of reach: a t interval whose spread is estimated
    # needs 8 coarse seeds for 80 %, docs/PHYSICS.md section 7.2.)
    ae, _ = judge.error_rates(judge.CONFIDENCE, 1, look=2, looks=2)
    oracle = _oracle_equivalent(ae)
    eq, _, added = _adaptive(1.0, n=2000, seed=21)
    assert 3 + added <= 1.5 * oracle + 1, f"{3 + added:.2f} seeds, oracle {oracle}"
    fixed = next(n for n in range(3, 30) if _power(_new_rule, 1.0, n, seed=n)[0] >= eq)
    assert added <= fixed - 3 + 1, f"{added:.2f} added, a fixed study needs {fixed - 3}"
    assert eq >= 0.7  # sized for 80 % from a pilot's spread of three seeds


def test_the_adaptive_rule_decides_what_a_fixed_study_leaves_open():
    # a true error of 0 with a coarse spread of 10 %: the pilot of 3 + 3 seeds rarely
    # decides it, the added seeds decide most studies. 200 adaptive studies (600
    # before; 0.84 of those decided): 0.88 decided against the pilot's 0.18 of 4000, a
    # binomial standard error of sqrt(0.88 * 0.12 / 200) = 0.023 on the difference against
    # a margin of 0.30 over the 0.4 asserted
    fixed, _ = _power(_new_rule, 1.0, 3, seed=22)
    adaptive, _, _ = _adaptive(1.0, n=200, seed=22)
    assert adaptive > fixed + 0.4, (adaptive, fixed)


# ------------------------------------------------------------------ the rule's own error
# A coarse run and its resolution control of one seed start from the same scaled cloud
# (docs/PHYSICS.md section 7.4): their values are correlated. The paired interval (per-seed
# differences) must keep its rates whatever that correlation; the unpaired one, used for the
# metrics whose measured correlation is nil, must keep them at the measured values.


def _pairs(rng, n, n_pairs, ratio, k, rho, kind, sd=0.05):
    """Coarse and control values of ``n`` studies of ``n_pairs`` seeds each, correlated by
    seed: normal scores with correlation ``rho`` mapped to ``_draw``'s marginals (control
    spread ``sd``, coarse ``k`` times it, true ratio of geometric means ``ratio``)."""
    z1 = rng.normal(size=(n, n_pairs))
    z2 = rho * z1 + math.sqrt(1 - rho**2) * rng.normal(size=(n, n_pairs))

    def marginal(z, ratio, s):
        if kind == "normal":
            x = np.clip(1 + s * z, 1e-12, None)
            return ratio * x / math.exp(_normal_log_mean(s))
        x = ratio * np.exp(s * z)
        if kind in ("low", "high"):
            f = 0.7 if kind == "low" else 1.3
            x = np.where(rng.random(x.shape) < 0.1, x * f, x) / math.exp(0.1 * math.log(f))
        return x

    return marginal(z1, ratio, k * sd), marginal(z2, 1.0, sd)


def test_the_paired_fast_path_is_the_rule():
    rng = np.random.default_rng(11)
    ae, ad = judge.error_rates(judge.CONFIDENCE, 1)
    for n_pairs in (2, 3, 6):
        c, r = _pairs(rng, 60, n_pairs, 1.08, 2.0, 0.6, "lognormal")
        fast = judge.judge_samples(c, r, TOL, ae, ad, paired=True)
        for i in range(60):
            lc, lr = np.log(c[i])[:, None], np.log(r[i])[:, None]
            comp = judge.Comparison(Space("log"), lc, lr, None, None, TOL, paired=True)
            m = judge.judge_metric("k", comp, ae, ad)
            assert m["verdict"] == fast[i] and m["paired"]
            assert m["df"] == pytest.approx(n_pairs - 1)


@pytest.mark.parametrize("kind", KINDS)
def test_the_paired_rule_error_keeps_its_rates_at_the_tolerance(kind):
    n = 4000
    worst = []
    for n_pairs in SEEDS:
        for k in (1.0, 3.0):
            for rho in (-0.5, 0.0, 0.6, 0.95):
                for ratio in (1 + TOL, 1 - TOL):
                    seed = 100 * n_pairs + int(10 * k) + int(10 * (rho + 1)) + (ratio > 1)
                    rng = np.random.default_rng(seed)
                    c, r = _pairs(rng, n, n_pairs, ratio, k, rho, kind)
                    ae, ad = judge.error_rates(judge.CONFIDENCE, 1)
                    v = judge.judge_samples(c, r, TOL, ae, ad, paired=True)
                    rate = max(np.mean(v == "equivalent"), np.mean(v == "differs"))
                    worst.append((float(rate), n_pairs, k, rho, ratio))
    top = max(worst)
    assert top[0] <= _bound(n), f"{kind}: wrong verdict in {top[0]:.1%} at {top[1:]}"


def test_the_unpaired_rule_error_keeps_its_rates_at_the_measured_correlation():
    # stiffness and strength are judged unpaired: their measured correlation between a
    # coarse run and its control is -0.12 to -0.05 (judge.PAIRING_VARIANCE_RATIO); a
    # negative one makes the unpaired interval too narrow, so it is checked at -0.15
    n = 4000
    ae, ad = judge.error_rates(judge.CONFIDENCE, 1)
    worst = []
    for n_pairs in SEEDS:
        for ratio in (1 + TOL, 1 - TOL):
            rng = np.random.default_rng(7 * n_pairs + (ratio > 1))
            c, r = _pairs(rng, n, n_pairs, ratio, 1.0, -0.15, "lognormal")
            v = judge.judge_samples(c, r, TOL, ae, ad)
            worst.append(max(np.mean(v == "equivalent"), np.mean(v == "differs")))
    assert max(worst) <= _bound(n), worst


def test_pairing_is_chosen_by_counts_and_pays_where_correlated():
    ae, _ = judge.error_rates(judge.CONFIDENCE, 5)
    # the metrics that keep the cloud's imprint are paired; the others never
    for n in (2, 3, 6, 12):
        assert judge.pairing_pays("density", n, n, n, ae)
        assert not judge.pairing_pays("strength", n, n, n, ae)
        assert not judge.pairing_pays("loading_stiffness", n, n, n, ae)
    assert not judge.pairing_pays("density", 1, 3, 3, ae)
    # at the measured density correlation the paired rule calls a true error of 0
    # equivalent more often with the same seeds (3 coarse runs and their 3 controls)
    rng = np.random.default_rng(3)
    rho = 1 - judge.PAIRING_VARIANCE_RATIO["density"]
    c, r = _pairs(rng, 4000, 3, 1.0, 1.0, rho, "lognormal", sd=0.06)
    _, ad = judge.error_rates(judge.CONFIDENCE, 1)
    paired = np.mean(judge.judge_samples(c, r, TOL, ae, ad, paired=True) == "equivalent")
    unpaired = np.mean(judge.judge_samples(c, r, TOL, ae, ad) == "equivalent")
    assert paired > unpaired + 0.05, (paired, unpaired)


def test_the_pairing_ratios_are_those_the_stored_runs_show():
    # judge.PAIRING_VARIANCE_RATIO is measured by benchmarks.pairing on the stored runs;
    # runs stored since may move it a little, and not across 1 (paired or not) where the
    # stored runs decide the side: the ratio is 1 - rho, and the correlation rho of n pairs
    # has a standard error of about 1 / sqrt(n), so a ratio within two of them of 1
    # (strength's, +0.02 on 50 degrees of freedom) says nothing about the side
    from benchmarks.pairing import centred_pairs, pooled

    for name, rows in centred_pairs().items():
        if not rows:
            continue
        p = pooled(rows)
        measured = p["variance_ratio"]
        fixed = judge.PAIRING_VARIANCE_RATIO[name]
        assert abs(measured - fixed) < 0.15, (name, measured)
        if abs(measured - 1.0) > 2.0 / math.sqrt(p["dof"]):
            assert (measured < 1) == (fixed < 1), (name, measured)


# ------------------------------------------------------------------------ pooled spreads
# The groups at one radius (the rules' variants and the controls) pool their spreads
# (engine.study.pooling): the rates must hold when the spreads are equal, when the judged
# variant's spread is twice the others' (which a screen on two or three seeds mostly cannot
# see) and when another group's is; and pooling must decide with fewer seeds.


def _pooled_rates(n_groups, n_seeds, ratio, wide, kind, n=4000, n_ref=3, seed=0):
    """Fractions of ``n`` studies that call the judged variant (group 0, true ratio
    ``ratio``) equivalent and differs, its spread pooled with ``n_groups - 1`` others at its
    radius, all of ``n_seeds`` seeds; coarse spread 10 %, references 3 %; ``wide``: the
    index of the group whose spread is twice the others' (None: all equal)."""
    rng = np.random.default_rng(seed)
    sds = [SD_COARSE * (2.0 if g == wide else 1.0) for g in range(n_groups)]
    r = _draw(rng, (n, n_ref), 1.0, SD_REF, kind)
    c = _draw(rng, (n, n_seeds), ratio, sds[0], kind)
    others = [_draw(rng, (n, n_seeds), 1.0, s, kind) for s in sds[1:]]
    ae, ad = judge.error_rates(judge.CONFIDENCE, 1)
    v = judge.judge_samples(c, r, TOL, ae, ad, others=others)
    return float(np.mean(v == "equivalent")), float(np.mean(v == "differs"))


@pytest.mark.parametrize("kind", ("normal", "lognormal"))
@pytest.mark.parametrize("wide", (None, 0, 1), ids=("equal", "judged-2x", "other-2x"))
def test_pooled_spreads_keep_the_rates(kind, wide):
    n = 4000
    worst = []
    for n_groups in (2, 4):
        for n_seeds in (2, 3, 5, 8):
            for ratio in (1 + TOL, 1 - TOL):
                seed = 97 * n_groups + 13 * n_seeds + (ratio > 1) + 7 * (wide or 0)
                eq, di = _pooled_rates(n_groups, n_seeds, ratio, wide, kind, n=n, seed=seed)
                worst.append((max(eq, di), n_groups, n_seeds, ratio))
    top = max(worst)
    assert top[0] <= _bound(n), f"{kind}, wide {wide}: wrong verdict in {top[0]:.1%} at {top[1:]}"


def test_without_the_screen_a_wider_variant_breaks_the_rate():
    # the screen is what keeps the 2x case: pooling every group regardless, eight seeds
    # each, four groups, the wide variant at the tolerance is called equivalent too often
    rng = np.random.default_rng(17)
    n = 20_000
    r = _draw(rng, (n, 3), 1.0, SD_REF, "normal")
    c = _draw(rng, (n, 8), 1 + TOL, 2 * SD_COARSE, "normal")
    others = [_draw(rng, (n, 8), 1.0, SD_COARSE, "normal") for _ in range(3)]
    ae, ad = judge.error_rates(judge.CONFIDENCE, 1)
    unscreened = judge.judge_samples(c, r, TOL, ae, ad, others=others, level=None)
    screened = judge.judge_samples(c, r, TOL, ae, ad, others=others)
    assert np.mean(unscreened == "equivalent") > _bound(n)
    assert np.mean(screened == "equivalent") <= _bound(n)


def _pooled_power(n_seeds, pooled: bool, n=4000, seed=0) -> float:
    """Three rules at one radius, each at a true error of 0 with a 10 % spread, against
    three references at 3 %: the fraction of studies that call the first equivalent."""
    rng = np.random.default_rng(seed)
    r = np.exp(rng.normal(0, SD_REF, (n, N_REF)))
    c = [np.exp(rng.normal(0, SD_COARSE, (n, n_seeds))) for _ in range(3)]
    ae, ad = judge.error_rates(judge.CONFIDENCE, 1)
    v = judge.judge_samples(c[0], r, TOL, ae, ad, others=c[1:] if pooled else ())
    return float(np.mean(v == "equivalent"))


def test_pooling_decides_with_fewer_seeds():
    # the issue-39 scenario: pooled, each rule is called equivalent more often with the same
    # seeds (simulated: 31 % against 19 % at 3 seeds a rule, 58 % against 45 % at 5); with
    # 8 or more the own spread has the degrees of freedom and the two meet (82 % and 80 %)
    pooled = {k: _pooled_power(k, True, seed=k) for k in (3, 5, 8)}
    own = {k: _pooled_power(k, False, seed=k) for k in (3, 5, 8)}
    assert pooled[3] > own[3] + 0.08 and pooled[5] > own[5] + 0.08, (pooled, own)
    assert pooled[8] >= 0.8 and pooled[8] > own[8] - 0.02, (pooled, own)
    # 80 % with at most 5 seeds a rule is out of reach at these rates for any rule that
    # estimates spreads: a z-test knowing both spreads needs more than 5 itself
    ae, _ = judge.error_rates(judge.CONFIDENCE, 1)
    assert _oracle_equivalent(ae) > 5


def _adaptive_pooled(ratios, sds, n=600, seed=0, kind="lognormal"):
    """Adaptive studies of several rules at one radius (their spreads pooled), one round:
    ``ratios`` and ``sds`` per rule (the first is judged); returns the first rule's
    fractions called equivalent and differs, and the mean seeds added to it."""
    name = "loading_stiffness"
    rules = tuple(SimpleNamespace(name=f"rule{i}") for i in range(len(ratios)))
    spec = deciding_spec({name: TOL}, rules, 10, 6, 1, consolidation_stress=CONS)
    rng = np.random.default_rng(seed)
    keys = [(5e-3, r.name) for r in rules]
    costs = {"reference": 8.0, **dict.fromkeys(keys, 1.0)}

    def one(r, sd):
        return {name: np.array([_draw(rng, 1, r, sd, kind)[0]])}

    eq = di = added = 0
    for _ in range(n):
        refs = [one(1.0, SD_REF) for _ in range(3)]
        groups = {k: [one(q, s) for _ in range(3)] for k, q, s in zip(keys, ratios, sds)}
        noise = StudyNoise(refs, groups, [name], CONS)
        ae, ad = judge.error_rates(spec.confidence, 1, 1, 2)
        verdicts = [judge.judge_group(noise, k, spec.tolerances, ae, ad) for k in keys]
        for a in next_runs(spec, noise, verdicts, costs, 1, None):
            if a.kind == "reference":
                refs.append(one(1.0, SD_REF))
            else:
                i = keys.index(a.variant)
                groups[a.variant].append(one(ratios[i], sds[i]))
        noise = StudyNoise(refs, groups, [name], CONS)
        ae, ad = judge.error_rates(spec.confidence, 1, 2, 2)
        v = judge.judge_group(noise, keys[0], spec.tolerances, ae, ad)
        eq += v["verdict"] == "equivalent"
        di += v["verdict"] == "differs"
        added += len(groups[keys[0]]) - 3
    return eq / n, di / n, added / n


@pytest.mark.parametrize(
    ("ratio", "sds"),
    [
        (1 + TOL, (0.10, 0.10, 0.10)),
        (1 - TOL, (0.20, 0.10, 0.10)),  # the judged rule twice the others' spread
        (1 + TOL, (0.10, 0.20, 0.10)),
    ],
)
def test_the_pooled_adaptive_rule_keeps_its_rates(ratio, sds):
    # three rules at one radius, a pilot of 3 seeds each, seeds allocated by the chance of a
    # verdict per particle-step (engine.study.allocate, which reads the observed means):
    # the judged rule at its tolerance is called equivalent, or differs, in at most 5 %
    n = 800
    eq, di, _ = _adaptive_pooled((ratio, 1.0, 1.0), sds, n=n, seed=int(1000 * ratio))
    assert eq <= _bound(n) and di <= _bound(n), (eq, di)


def test_the_pooled_adaptive_rule_decides_good_rules():
    # three good rules (error 0, 10 % spread) against references at 3 %: the allocation
    # decides most studies with at most 10 seeds a rule
    eq, _, added = _adaptive_pooled((1.0, 1.0, 1.0), (0.10, 0.10, 0.10), n=400, seed=5)
    assert eq >= 0.6 and added <= 7, (eq, added)
