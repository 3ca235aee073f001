r"""From metric values to verdicts (docs/PHYSICS.md section 7).

For every verdict metric (:data:`engine.study.metrics.METRICS`), with the reference seeds' values
:math:`r_i` and a coarse variant's seeds' values :math:`c_j` (per stress level for density
and coordination):

- the **reference** is the mean of the reference seeds' values; its **noise floor** is their
  seed-to-seed spread (sample standard deviation) relative to the mean;
- the variant's relative error at a level is :math:`\rho - 1` with the ratio of geometric
  means :math:`\rho = \exp(\overline{\log c} - \overline{\log r})` (for the strength of a
  reference weaker than 5 % of the consolidation stress: the difference over that floor);
  its interval is the t interval of the difference of mean logarithms (Schuirmann 1987),
  with :func:`engine.study.intervals.interval_df` degrees of freedom (a lower bound of
  Welch-Satterthwaite's with three or more seeds a side, Hsu's min(n_c, n_r) - 1 with two):
  it holds for the seeds actually run, spreads not assumed equal, and is bounded for any
  positive values;
- the verdict reads two one-sided tests at error rate :math:`\alpha = 1 -` confidence
  (default 95 %): ``equivalent`` when, at every level, the interval at one-sided rate
  :math:`\alpha / 2` lies inside the tolerance (:data:`EQUIVALENCE_LEVEL`: the two-sided
  :math:`1 - \alpha` interval, which keeps its rate for skewed values and an adaptive second
  stage where the plain :math:`\alpha` per end does not; an intersection-union test needs no
  split over levels or metrics); ``differs`` when the interval of the per-seed mean over
  levels (for a curve; the value itself for a scalar metric) lies wholly outside the
  tolerance at rate :math:`\alpha_k / 2M` per end over the :math:`M` metrics judged
  (Bonferroni over the metrics, the two ends, either of which may clear its bound, and the
  looks :math:`k`; the level mean is outside the tolerance only if some level is); else
  ``undecided``;
- a study that adds seeds until decided (engine.study.adaptive) claims ``equivalent`` at its
  final look only, on seeds sized from the pilot's spreads, and ``differs`` at any look, the
  looks sharing :math:`\alpha` (:func:`look_alpha`); its rates are shown by simulation
  (tests/engine/test_coverage.py);
- with fewer than two reference seeds, or fewer than two seeds of the variant, a spread is
  unknown and the metric is ``undecided``.

A (radius, rule) ``differs`` when any metric differs, is ``equivalent`` when all are, and is
``undecided`` otherwise; its reason says which metrics decided, with their intervals, and
an undecided metric says how many more seeds would decide it if the means and spreads
stayed as observed. The coarsest equivalent radius of a rule is found by testing its radii
from fine to coarse in a fixed sequence (:func:`advise`), so that the stated confidence
holds for the radius a user acts on. docs/PHYSICS.md section 7 states why;
tests/engine/test_coverage.py checks the rates and the power by simulation.
"""

from __future__ import annotations

import math

import numpy as np

from ..uniaxial.spec import MIN_THICKNESS_DIAMETERS
from .intervals import interval_df, t_quantile, t_upper_quantiles
from .metrics import METRICS, STRENGTH_FLOOR, reference_scale, relative_error, signed_error

#: Default confidence of a verdict: 1 - the largest rate of a wrong ``equivalent`` or of a
#: wrong ``differs`` [-].
CONFIDENCE = 0.95

#: Most seeds a "would need" estimate looks for (beyond it: "more than" this).
MAX_SEEDS_NEEDED = 100

VERDICTS = ("equivalent", "differs", "undecided")


#: Share of the ``differs`` error rate an adaptive study spends at its pilot look (the
#: planned runs); the later looks share the rest equally. The pilot is there to stop early on
#: gross differences (a variant 40 % off is told apart at 1 % as surely as at 5 %); most of
#: the rate goes to the look that has the seeds sized for it (docs/PHYSICS.md section 7.2).
PILOT_SHARE = 0.2

#: Power the second stage of an adaptive study is sized for: the chance that a variant whose
#: true error is 0 is called ``equivalent`` at the final look, with the pilot's spreads [-].
PLANNED_POWER = 0.8

#: The nominal one-sided rate of each end of an equivalence interval, as a fraction of
#: alpha = 1 - confidence: one half, so that ``equivalent`` means the two-sided
#: 1 - alpha interval lies inside the tolerance (the conservative form of the two one-sided
#: tests; the plain form, alpha per end, is the two-sided 1 - 2 alpha interval). Two things
#: make the plain form cover less than it states here (docs/PHYSICS.md section 7.1,
#: ``python -m benchmarks.verdict_rates``): skewed values with three seeds on one side and
#: many on the other (simulated, alpha = 5 %: up to 7.3 % wrong ``equivalent`` for normal
#: values and 8.5 % with one seed in ten from a second mode 30 % away), and an adaptive
#: second stage sized from the pilot's spreads (up to 7.8 %). At alpha / 2 per end the
#: simulated rates stay under 5 % (tests/engine/test_coverage.py).
EQUIVALENCE_LEVEL = 0.5

#: Variance of the per-seed difference of a coarse run and its resolution control (both
#: started from the same scaled cloud), relative to the sum of their variances, per metric:
#: var(log c - log k) / (var log c + var log k) = 1 - rho for equal spreads, rho their
#: correlation. Measured by ``python -m benchmarks.pairing`` on the stored runs of the four
#: experiments (2026-12-03, quick and paper scale, pooled within variants: 44 degrees of
#: freedom, 30 for strength): density and coordination keep the cloud's imprint
#: (rho = 0.64 and 0.51); the stiffnesses and the strength forget it (rho -0.12, -0.06,
#: -0.05, none distinguishable from 0 at 1 / sqrt(44) = 0.15): a packing is chaotic and
#: bit-level differences in the clock grow. Fixed here, so that whether a metric is paired
#: depends on seed counts only, never on the values judged (:func:`pairing_pays`).
PAIRING_VARIANCE_RATIO = {
    "density": 0.37,
    "loading_stiffness": 1.12,
    "unloading_stiffness": 1.06,
    "coordination": 0.51,
    "strength": 1.05,
}


def pairing_pays(name: str, pairs: int, nc: int, nr: int, alpha: float) -> bool:
    """Whether the rule's own error of metric ``name`` is judged paired by seed (the t
    interval of the ``pairs`` per-seed differences, pairs - 1 degrees of freedom) rather
    than unpaired (all ``nc`` coarse and ``nr`` control seeds, :func:`two_sample_intervals`):
    paired when its expected half-width at one-sided rate ``alpha``, with equal spreads and
    the measured :data:`PAIRING_VARIANCE_RATIO`, is the smaller. Depends on the counts and
    the fixed ratio alone, so either interval keeps its own coverage."""
    ratio = PAIRING_VARIANCE_RATIO.get(name, 1.0)
    if pairs < 2 or ratio >= 1.0:
        return False
    df_unpaired = float(interval_df(nc, nr, 1.0 / nc, 1.0 / nr))
    unpaired = t_quantile(1.0 - alpha, df_unpaired) * math.sqrt(1.0 / nc + 1.0 / nr)
    paired = t_quantile(1.0 - alpha, pairs - 1) * math.sqrt(2.0 * ratio / pairs)
    return paired < unpaired


def look_alpha(confidence: float, look: int = 1, looks: int = 1) -> float:
    """The ``differs`` error rate spent at look ``look`` of ``looks`` (1 for a study judged
    once): all of alpha = 1 - confidence when judged once; else :data:`PILOT_SHARE` of it at
    the pilot (look 1) and the rest split equally over the later looks. The rates over all
    looks add up to alpha, so a ``differs`` reported from any look is wrong in at most alpha
    of studies (Bonferroni over the looks)."""
    if not 0.5 < confidence < 1.0:
        raise ValueError(f"confidence {confidence} outside (0.5, 1)")
    if not 1 <= look <= looks:
        raise ValueError(f"look {look} outside 1 to {looks}")
    alpha = 1.0 - confidence
    if looks == 1:
        return alpha
    if look == 1:
        return PILOT_SHARE * alpha
    return (1.0 - PILOT_SHARE) * alpha / (looks - 1)


def error_rates(
    confidence: float, metrics_judged: int, look: int = 1, looks: int = 1
) -> tuple[float, float]:
    """Nominal one-sided rates per end of the intervals of one metric's two tests, for a
    variant judged on ``metrics_judged`` metrics at look ``look`` of ``looks`` (module
    docstring): equivalence :data:`EQUIVALENCE_LEVEL` x alpha at any look (an intersection-
    union test needs no split over metrics or levels, and an adaptive study never stops on
    an ``equivalent`` before its final look, so equivalence is claimed once); differs
    :func:`look_alpha` / (2 metrics), since any metric and either end of its interval may
    clear its tolerance bound, at any look."""
    a = look_alpha(confidence, look, looks)
    return EQUIVALENCE_LEVEL * (1.0 - confidence), a / (2 * max(metrics_judged, 1))


def _stack(values: list[dict], name: str) -> np.ndarray:
    return np.array([np.atleast_1d(v[name]) for v in values], dtype=float)


def noise_floor(ref_values: list[dict], names, consolidation_stress: float) -> dict:
    """Per metric, the reference seeds' ``values`` (seeds x levels), mean values, spread
    (per level) and the relative noise floor [-] (RMS over levels of spread / scale); the
    floor is None with one seed."""
    out = {}
    for n in names:
        a = _stack(ref_values, n)
        mean = a.mean(axis=0)
        sd = a.std(axis=0, ddof=1) if len(a) > 1 else None
        scale = reference_scale(n, mean, consolidation_stress)
        floor = None if sd is None else float(np.sqrt(np.mean((sd / scale) ** 2)))
        out[n] = {"values": a, "mean": mean, "sd": sd, "noise": floor, "seeds": len(a)}
    return out


def _floored(name: str, ref_mean: float, consolidation_stress: float) -> float | None:
    """The constant scale of a strength compared against the 5 % floor, else None."""
    if name == "strength" and abs(ref_mean) < STRENGTH_FLOOR * consolidation_stress:
        return STRENGTH_FLOOR * consolidation_stress
    return None


def two_sample_intervals(mc, mr, sc2, sr2, nc: int, nr: int, alpha: float):
    """Element-wise difference of two sample means ``mc`` - ``mr`` (numbers or arrays) with
    its interval at one-sided rate ``alpha`` per end, from the sample variances ``sc2``,
    ``sr2`` of ``nc`` and ``nr`` values: :func:`engine.study.intervals.interval_df` degrees
    of freedom and a Student-t quantile. Returns arrays (difference, low, high, dof, standard
    error). The one computation behind every interval of a verdict."""
    mc, mr = np.asarray(mc, dtype=float), np.asarray(mr, dtype=float)
    vc = np.asarray(sc2, dtype=float) / nc
    vr = np.asarray(sr2, dtype=float) / nr
    df = np.asarray(interval_df(nc, nr, vc, vr), dtype=float)
    u = np.sqrt(vc + vr)
    h = np.where(u > 0, t_upper_quantiles(alpha, df) * u, 0.0)
    d = mc - mr
    return d, d - h, d + h, df, u


def _bounds(tolerance: float) -> tuple[float, float]:
    """The tolerance ± ``tolerance`` on a ratio as bounds on a difference of logarithms."""
    return (math.log(1.0 - tolerance) if tolerance < 1 else -math.inf), math.log1p(tolerance)


def judge_samples(
    c, r, tolerance: float, alpha_e: float, alpha_d: float, paired: bool = False
) -> np.ndarray:
    """The verdicts of many studies of one positive scalar metric at once: ``c`` (studies x
    coarse seeds) and ``r`` (studies x reference seeds; ``paired``: as many, matched column
    by column), the same tests as :func:`judge_metric` (which judges one study, and curves).
    Returns an array of ``"equivalent"``, ``"differs"`` or ``"undecided"``;
    tests/engine/test_coverage.py simulates the rule's rates with it and checks that it
    agrees with :func:`judge_metric`."""
    lc, lr = np.log(np.asarray(c, dtype=float)), np.log(np.asarray(r, dtype=float))
    nc, nr = lc.shape[1], lr.shape[1]
    lo_b, hi_b = _bounds(tolerance)
    if paired:
        dd = lc - lr
        zero = np.zeros(len(dd))
        stats = (dd.mean(1), zero, dd.var(1, ddof=1), zero)
    else:
        stats = (lc.mean(1), lr.mean(1), lc.var(1, ddof=1), lr.var(1, ddof=1))
    _, lo, hi, _, _ = two_sample_intervals(*stats, nc, nr, alpha_e)
    equivalent = (lo >= lo_b) & (hi <= hi_b)
    _, lo, hi, _, _ = two_sample_intervals(*stats, nc, nr, alpha_d)
    differs = (lo > hi_b) | (hi < lo_b)
    return np.where(differs, "differs", np.where(equivalent, "equivalent", "undecided"))


class _Space:
    """Where a metric's two samples are compared (docs/PHYSICS.md section 7.1): ``log``, the
    logarithms of positive values (a difference d of mean logs is the ratio exp(d) of
    geometric means, relative error exp(d) - 1, tolerance bounds log(1 -/+ tol)), or
    ``difference``, the values over a constant scale (a strength under 5 % of the
    consolidation stress, over that floor; any non-positive value, over the reference mean),
    relative error d and bounds -/+ tol. Holds the per-level means and sample variances of
    the transformed values (seeds x levels), ``stats``, and those of each seed's mean over
    levels (of logs: a geometric mean over levels), ``summed``, whose difference is the mean
    of the level differences, so that it lies beyond a tolerance bound only if some level
    does. ``paired``: the rows of the two samples are matched by seed (a coarse run and its
    resolution control), and the intervals are those of the per-seed differences."""

    def __init__(
        self,
        name: str,
        a: np.ndarray,
        r: np.ndarray,
        tolerance: float,
        cons: float,
        paired: bool = False,
    ):
        floor = _floored(name, float(r.mean(axis=0)[0]), cons) if a.shape[1] == 1 else None
        if floor is None and np.all(a > 0) and np.all(r > 0):
            self.kind = "log"
            c, r = np.log(a), np.log(r)
            self.lo, self.hi = _bounds(tolerance)
        else:
            self.kind = "difference"
            scale = floor if floor is not None else reference_scale(name, r.mean(axis=0), cons)
            c, r = a / scale, r / scale
            self.lo, self.hi = -tolerance, tolerance
        self.nc, self.nr = len(c), len(r)
        self.paired = paired
        if paired:  # rows matched by seed: the one-sample t of the per-seed differences
            # (two_sample_intervals with a second sample of zero spread and as many values:
            # interval_df gives n - 1 and the standard error is s_D / sqrt(n))
            dd = c - r
            z = np.zeros(dd.shape[1])
            self.stats = (dd.mean(0), z, dd.var(0, ddof=1), z)
            ds = dd.mean(axis=1)
            self.summed = (ds.mean(), 0.0, ds.var(ddof=1), 0.0)
            return
        self.stats = (c.mean(0), r.mean(0), c.var(0, ddof=1), r.var(0, ddof=1))
        cs, rs = c.mean(axis=1), r.mean(axis=1)
        self.summed = (cs.mean(), rs.mean(), cs.var(ddof=1), rs.var(ddof=1))

    def rel(self, d):
        """A difference in this space as a relative error [-]."""
        return math.expm1(d) if self.kind == "log" else float(d)

    def interval(self, stats, alpha: float, nc=None, nr=None):
        """:func:`two_sample_intervals` of ``stats`` (:attr:`stats`, per level, or
        :attr:`summed`) with the observed counts or, projected, ``nc`` and ``nr`` seeds."""
        return two_sample_intervals(
            *stats, self.nc if nc is None else nc, self.nr if nr is None else nr, alpha
        )

    def equivalent(self, alpha: float, nc=None, nr=None) -> bool:
        """Every level's interval inside the bounds."""
        _, lo, hi, _, _ = self.interval(self.stats, alpha, nc, nr)
        return bool(np.all(lo >= self.lo) and np.all(hi <= self.hi))

    def differs(self, alpha: float, nc=None, nr=None) -> bool:
        """The interval of the level-summed values wholly beyond a bound."""
        _, lo, hi, _, _ = self.interval(self.summed, alpha, nc, nr)
        return bool(lo > self.hi or hi < self.lo)


def judge_metric(
    name: str,
    values: list[dict],
    ref: dict,
    tolerance: float,
    consolidation_stress: float,
    alpha_equivalent: float = EQUIVALENCE_LEVEL * (1 - CONFIDENCE),
    alpha_differs: float = (1 - CONFIDENCE) / 2,
    paired: bool = False,
    against: str = "reference",
) -> dict:
    """Error, interval and verdict of one metric of one (radius, rule) (module docstring).
    ``values``: the variant's metric values per seed; ``ref``: this metric's entry of
    :func:`noise_floor`; the two one-sided error rates as from :func:`error_rates`.
    ``paired``: ``values`` and the values in ``ref`` are matched by seed, row by row (a rule
    against its resolution controls, :func:`judge_rule_error`); ``against`` names the other
    side in the reason ("reference" or "control")."""
    a = _stack(values, name)
    mean = a.mean(axis=0)
    err = relative_error(name, mean, ref["mean"], consolidation_stress)
    signed = signed_error(name, mean, ref["mean"], consolidation_stress)
    out = {
        "metric": name,
        "error": err,
        "signed_error": signed,
        "tolerance": tolerance,
        "noise": ref["noise"],
        "seeds": len(a),
        "reference_seeds": ref["seeds"],
        "alpha_equivalent": alpha_equivalent,
        "alpha_differs": alpha_differs,
        "interval": None,
        "differs_interval": None,
        "level": None,
        "df": None,
        "uncertainty": None,
        "needs": None,
        "paired": paired,
        "against": against,
    }
    if ref["seeds"] < 2 or len(a) < 2:
        out.update(verdict="undecided")
        return out
    r = ref["values"]
    levels = a.shape[1]
    sp = _Space(name, a, r, tolerance, consolidation_stress, paired)
    d, lo, hi, df, u = sp.interval(sp.stats, alpha_equivalent)
    excess = np.maximum(hi - sp.hi, sp.lo - lo)
    k = int(np.argmax(excess))
    equivalent = bool(excess[k] <= 0)
    dd = sp.interval(sp.summed, alpha_differs)
    differs = bool(dd[1] > sp.hi or dd[2] < sp.lo)
    if paired:  # the per-seed differences' standard error, relative (logs) or scaled
        u2 = np.asarray(u) ** 2
    else:
        sc = reference_scale(name, ref["mean"], consolidation_stress)
        u2 = (a.var(axis=0, ddof=1) / len(a) + r.var(axis=0, ddof=1) / len(r)) / sc**2
    out.update(
        interval=[sp.rel(lo[k]), sp.rel(hi[k])],
        level=None if levels == 1 else k,
        level_error=sp.rel(d[k]),
        df=float(df[k]),
        differs_interval=[sp.rel(dd[1]), sp.rel(dd[2])],
        differs_error=sp.rel(dd[0]),
        uncertainty=float(np.sqrt(np.mean(u2))),
        scale=sp.kind,
        verdict="differs" if differs else "equivalent" if equivalent else "undecided",
    )
    if out["verdict"] == "undecided":
        out["needs"] = seeds_needed(
            name, a, r, tolerance, consolidation_stress, alpha_equivalent, alpha_differs, paired
        )
    return out


def _projected(sp: _Space, n: int, m: int, alpha_e: float, alpha_d: float) -> str | None:
    """The verdict a metric (in its comparison space ``sp``) would get with ``n`` coarse and
    ``m`` reference seeds if its means and spreads stayed as observed: the verdict's own
    intervals at the projected counts and their degrees of freedom; None: undecided."""
    if sp.differs(alpha_d, n, m):
        return "differs"
    return "equivalent" if sp.equivalent(alpha_e, n, m) else None


def _decides(
    sp: _Space, n: int, m: int, alpha_e: float, alpha_d: float, planned: bool = False
) -> bool:
    """Whether a metric would be decided with ``n`` coarse and ``m`` reference seeds if its
    spreads stayed as observed and

    - (``planned`` False) its means too (:func:`_projected`);
    - (``planned`` True) its true error were 0: the chance of ``equivalent`` would be at
      least :data:`PLANNED_POWER` at every level, computed for a normal difference of
      standard error u with the nearer tolerance bound m on both sides (half-width h at the
      projected counts, h + z u <= m with z the normal quantile of (1 + power) / 2): a second
      stage sized from the pilot's spreads alone (Stein 1945)."""
    if planned:
        _, lo, hi, _, u = sp.interval(sp.stats, alpha_e, n, m)
        z = t_quantile(0.5 + 0.5 * PLANNED_POWER, math.inf)
        return bool(np.all(0.5 * (hi - lo) + z * u <= min(sp.hi, -sp.lo)))
    return _projected(sp, n, m, alpha_e, alpha_d) is not None


def variant_decided(projections) -> bool:
    """A (radius, rule) is decided when any metric differs or every metric is equivalent:
    ``projections`` holds each metric's verdict (None: undecided)."""
    projections = list(projections)
    return any(p == "differs" for p in projections) or all(p == "equivalent" for p in projections)


def seeds_needed(
    name: str,
    c: np.ndarray,
    r: np.ndarray,
    tolerance: float,
    consolidation_stress: float,
    alpha_e: float,
    alpha_d: float,
    paired: bool = False,
) -> dict:
    """How many more seeds would decide an undecided metric if its means and spreads stayed
    as observed: ``coarse`` (more coarse seeds, reference seeds as they are), or
    ``coarse_and_reference`` (the same number more of each) where coarse seeds alone cannot
    (``paired``: more pairs, always both), each None when more than
    :data:`MAX_SEEDS_NEEDED` would be needed (an error that sits at the tolerance is decided
    by no seed count); ``verdict``: the one those seeds would give."""
    sp = _Space(name, c, r, tolerance, consolidation_stress, paired)
    n0, m0 = len(c), len(r)

    def first(pred):
        lo, hi = 1, MAX_SEEDS_NEEDED  # undecided now: at least one more seed
        if not pred(hi):
            return None
        while lo < hi:  # smallest k with pred(k): decidedness grows with seeds
            mid = (lo + hi) // 2
            if pred(mid):
                hi = mid
            else:
                lo = mid + 1
        return lo

    coarse = None if paired else first(lambda k: _decides(sp, n0 + k, m0, alpha_e, alpha_d))
    both = (
        None
        if coarse is not None
        else first(lambda k: _decides(sp, n0 + k, m0 + k, alpha_e, alpha_d))
    )
    verdict = None
    if coarse is not None:
        verdict = _projected(sp, n0 + coarse, m0, alpha_e, alpha_d)
    elif both is not None:
        verdict = _projected(sp, n0 + both, m0 + both, alpha_e, alpha_d)
    return {"coarse": coarse, "coarse_and_reference": both, "verdict": verdict}


def _pct(x: float) -> str:
    return f"{100 * x:+.1f} %"


def _describe(m: dict) -> str:
    tol = f"± {m['tolerance']:.0%}"
    if m["interval"] is None:
        return f"{m['metric']} {_pct(m['signed_error'])} (spread unknown) against {tol}"
    conf = 1 - m["alpha_equivalent"]
    if m["verdict"] == "differs":
        lo, hi = m["differs_interval"]
        what = "summed over levels " if m["level"] is not None else ""
        return (
            f"{m['metric']} {what}{_pct(m['differs_error'])} in [{_pct(lo)}, {_pct(hi)}] "
            f"({1 - m['alpha_differs']:.1%} one-sided) against {tol}"
        )
    lo, hi = m["interval"]
    at = "" if m["level"] is None else f" at its worst level {m['level'] + 1}"
    pairs = ", paired by seed" if m.get("paired") else ""
    text = (
        f"{m['metric']} {_pct(m['level_error'])}{at} in [{_pct(lo)}, {_pct(hi)}] "
        f"({conf:.1%} one-sided per end, {m['df']:.1f} dof{pairs}) against {tol}"
    )
    need = m.get("needs")
    if need is not None:
        if need["coarse"] is not None:
            text += f"; about {need['coarse']} more coarse seeds would decide it"
        elif need["coarse_and_reference"] is not None:
            text += (
                f"; about {need['coarse_and_reference']} more coarse and "
                f"{m.get('against', 'reference')} seeds each would decide it"
            )
        else:
            text += f"; more than {MAX_SEEDS_NEEDED} more seeds would be needed"
    return text


def what_decides(metrics: list[dict]) -> str | None:
    """One line on what would decide an undecided (radius, rule), from its metrics'
    ``needs`` (as if their means and spreads stayed as observed): the fewest seeds with
    which some metric would differ, or with which every metric would be equivalent; None
    when it is decided."""
    if any(m["verdict"] == "differs" for m in metrics):
        return None
    open_ = [m for m in metrics if m["verdict"] == "undecided"]
    if not open_:
        return None
    if open_[0]["reference_seeds"] < 2 or open_[0]["seeds"] < 2:
        return "two or more seeds on each side (three give the intervals more degrees of freedom)"
    other = open_[0].get("against", "reference")

    def cost(n: dict) -> tuple[int, str] | None:
        if n.get("coarse") is not None:
            return n["coarse"], "coarse"
        if n.get("coarse_and_reference") is not None:
            return n["coarse_and_reference"], f"coarse and {other}"
        return None

    def words(k: int, kind: str) -> str:
        return f"about {k} more {kind} seeds" + (" each" if kind != "coarse" else "")

    needs = {m["metric"]: m.get("needs") or {} for m in open_}
    to_differ = [
        (cost(n), name) for name, n in needs.items() if n.get("verdict") == "differs" and cost(n)
    ]
    if to_differ:
        (k, kind), name = min(to_differ, key=lambda x: (x[0][1] != "coarse", x[0][0]))
        return (
            f"{words(k, kind)} would show it differs in {name}, if the means and spreads "
            "stayed as observed"
        )
    costs = {name: cost(n) for name, n in needs.items()}
    hopeless = [name for name, c in costs.items() if c is None]
    if hopeless:
        return (
            f"no seed count within {MAX_SEEDS_NEEDED} more: {', '.join(hopeless)} sits at "
            "its tolerance (as observed); a looser tolerance, or a finer radius"
        )
    kind = "coarse" if all(c[1] == "coarse" for c in costs.values()) else f"coarse and {other}"
    k = max(c[0] for c in costs.values())
    return f"{words(k, kind)} would decide it, if the means and spreads stayed as observed"


def verdict(metrics: list[dict]) -> tuple[str, str]:
    """Overall verdict and its reason from the per-metric judgements."""
    if metrics and metrics[0]["reference_seeds"] < 2:
        return "undecided", (
            "one reference seed: the reference's own spread is unknown, so "
            "no error can be told apart from noise; run two or more "
            "reference seeds"
        )
    if metrics and metrics[0]["seeds"] < 2:
        return "undecided", (
            "one seed of this variant: its own spread is unknown (a coarse "
            "bed of fewer particles scatters more than the reference), so "
            "no interval holds; run two or more seeds: " + "; ".join(_describe(m) for m in metrics)
        )
    differs = [m for m in metrics if m["verdict"] == "differs"]
    undecided = [m for m in metrics if m["verdict"] == "undecided"]
    if differs:
        return "differs", "differs beyond noise in " + "; ".join(_describe(m) for m in differs)
    if undecided:
        ok = [m["metric"] for m in metrics if m["verdict"] == "equivalent"]
        reason = "noise too large to tell for " + "; ".join(_describe(m) for m in undecided)
        if ok:
            reason += "; within tolerance: " + ", ".join(ok)
        return "undecided", reason
    return "equivalent", "within tolerance beyond noise: " + "; ".join(
        _describe(m) for m in metrics
    )


def finite_size_warnings(groups: list[dict], controlled: bool = False) -> list[str]:
    """Warnings for radii whose cell is under :data:`MIN_THICKNESS_DIAMETERS` diameters
    thick and, in a study without resolution controls (``controlled`` False), for radii
    under 10: there part of the error may be the sample's size in diameters, which only a
    control tells apart from the rule's."""
    out, seen = [], set()
    for g in groups:
        if g["radius"] in seen:
            continue
        seen.add(g["radius"])
        t = g["thickness_diameters"]
        if t < MIN_THICKNESS_DIAMETERS:
            out.append(
                f"R = {g['radius'] * 1e3:g} mm: the cell is {t:.1f} particle "
                f"diameters thick, under the {MIN_THICKNESS_DIAMETERS:g} a bulk sample "
                "needs (Thakur et al. 2013): wall and periodic-image effects may dominate"
            )
        elif t < 10 and not controlled:
            out.append(
                f"R = {g['radius'] * 1e3:g} mm: the cell is {t:.1f} particle diameters "
                "thick and no resolution control of it has run (StudySpec.controls): part "
                "of this radius's error may be the sample's size in diameters, not the rule"
            )
    return out


def _interval_words(m: dict) -> str:
    lo, hi = m["interval"] if m["interval"] is not None else (None, None)
    if lo is None:
        return f"{m['metric']} {_pct(m['signed_error'])}"
    pairs = ", paired" if m.get("paired") else ""
    return f"{m['metric']} {_pct(m['level_error'])} [{_pct(lo)}, {_pct(hi)}{pairs}]"


def _scaled_law(spec, rule, radius: float) -> dict:
    """The reference's pair law scaled by ``rule`` to ``radius`` [m], as JSON (its ``type``
    and fields in SI units): what to run at the coarsest radius."""
    from ..core.records import to_dict

    base = spec.reference.pair_law
    law = base.scaled(radius / spec.reference.radius, *rule.exponents(base))
    return {"type": type(law).__name__, **to_dict(law)}


def _law_text(law: dict) -> str:
    """A scaled law's stiffness and adhesion parameters in words."""
    units = {"k1": "N/m", "k2": "N/m", "f0": "N", "kadh": "N/m"}
    parts = [
        f"{k.upper() if k != 'kadh' else 'kadh'} = {law[k]:.4g} {u}"
        for k, u in units.items()
        if k in law
    ]
    return ", ".join(parts) or law["type"]


def resolution_lines(resolution: list[dict], rule_errors: list[dict], spec) -> list[str]:
    """The advisor's lines on the controls: per rule and radius whether the rule holds
    against its control (its own error), and per radius what a sample that many diameters
    across loses against the reference."""
    lines = []
    exact = (
        {
            rule.name
            for rule in spec.rules
            if tuple(rule.exponents(spec.reference.pair_law)) == (1.0, 2.0, 1.0)
            and type(spec.reference.pair_law).__name__ == "BilinearAdhesive"
        }
        if rule_errors
        else set()
    )
    for v in rule_errors:
        says = {"equivalent": "holds", "differs": "differs", "undecided": "is undecided"}
        parts = "; ".join(_interval_words(m) for m in v["metrics"])
        text = (
            f"{v['rule']} at R = {v['radius'] * 1e3:g} mm: the rule {says[v['verdict']]} "
            f"against its resolution control (the rule's own error: {parts})"
        )
        if v["rule"] in exact:
            text += (
                "; for this law the rule is an exact similarity, so this error measures "
                "only the clock: the inertial number at the same strain rate and the time "
                "step against the contact time"
            )
        lines.append(text)
    for v in resolution:
        d = v.get("diameters_across")
        across = f"{d:.1f} diameters across" if d else "the coarse cell's size in diameters"
        parts = "; ".join(_interval_words(m) for m in v["metrics"])
        lines.append(
            f"resolution at R = {v['radius'] * 1e3:g} mm: the reference law in a sample "
            f"{across} against the reference: {v['verdict']} ({parts}); resolution is a "
            "property of diameters across, not of the test cell: a process loses it too "
            "wherever a feature (a shear band, an outlet, a wall layer) is only a few "
            "coarse diameters wide"
        )
    return lines


def advise(
    spec,
    groups: list[dict],
    verdicts: list[dict],
    reference_strength: float | None,
    resolution: list[dict] | None = None,
    rule_errors: list[dict] | None = None,
    strengths: dict | None = None,
) -> dict:
    """The advisor: per rule the coarsest radius judged ``equivalent`` in a fixed sequence;
    the verdicts; the finite-size warnings; the best-fitting adhesion exponent per radius.

    The coarsest radius is a choice among radii, each verdict right at its own confidence:
    acting on the largest of several ``equivalent`` radii could be wrong more often than
    one verdict is. So a rule's radii are tested from fine to coarse and the sequence stops
    at the first one not ``equivalent`` (fixed-sequence testing, Maurer, Hothorn and Lehmacher
    1995): every verdict is made at the full rate, and the chance that any radius up to the
    one reported is not truly within tolerance is still at most 1 - confidence. An
    ``equivalent`` radius past the first one not ``equivalent`` is listed
    (``radii_equivalent``) but not reported as the coarsest."""
    rules = {}
    for rule in spec.rules:
        mine = sorted((v for v in verdicts if v["rule"] == rule.name), key=lambda v: v["radius"])
        best, stopped_at = None, None
        for v in mine:
            if v["verdict"] != "equivalent":
                stopped_at = v
                break
            best = v
        g = next(
            (
                g
                for g in groups
                if best and g["rule"] == rule.name and g["radius"] == best["radius"]
            ),
            None,
        )
        rules[rule.name] = {
            "coarsest_radius": best["radius"] if best else None,
            "coarsest_law": _scaled_law(spec, rule, best["radius"]) if best else None,
            "speedup": g["speedup"] if g else None,
            "radii_equivalent": [v["radius"] for v in mine if v["verdict"] == "equivalent"],
            "sequence_stopped_at": None
            if stopped_at is None
            else {"radius": stopped_at["radius"], "verdict": stopped_at["verdict"]},
        }
    lines = []
    for v in verdicts:
        lines.append(f"R = {v['radius'] * 1e3:g} mm, {v['rule']}: {v['verdict']}")
    for name, a in rules.items():
        if a["coarsest_radius"] is not None:
            lines.append(
                f"{name}: equivalent up to R = {a['coarsest_radius'] * 1e3:g} mm "
                f"({a['speedup']:.1f}x faster); the law there: {_law_text(a['coarsest_law'])}"
            )
        last = a["coarsest_radius"]
        beyond = [r for r in a["radii_equivalent"] if last is None or r > last]
        stop = a["sequence_stopped_at"]
        if beyond and stop is not None:
            lines.append(
                f"{name}: R = {', '.join(f'{r * 1e3:g}' for r in beyond)} mm equivalent but "
                f"not reported as the coarsest: R = {stop['radius'] * 1e3:g} mm, finer, is "
                f"{stop['verdict']} (radii are tested fine to coarse)"
            )
    resolution, rule_errors = resolution or [], rule_errors or []
    warnings = finite_size_warnings(groups, controlled=bool(resolution))
    control_lines = resolution_lines(resolution, rule_errors, spec)
    lines += control_lines
    adhesion = adhesion_advice(spec, groups, reference_strength, strengths)
    if adhesion:
        for r, v in adhesion["by_radius"].items():
            fit = ""
            if v.get("fitted") is not None:
                fit = f", fitted b = {v['fitted']:.2f}"
                if v.get("fitted_against") == "control" or strengths is not None:
                    iv = v.get("interval")
                    fit += (
                        f" [{iv[0]:.2f}, {iv[1]:.2f}]"
                        if iv is not None
                        else " (no bounded interval: the data do not fix it)"
                    )
                    fit += f" against the {v['fitted_against']}s"
            lines.append(
                f"adhesion exponent at R = {float(r) * 1e3:g} mm: closest b = {v['best']:g}{fit}"
            )
    return {
        "tolerances": dict(spec.tolerances),
        "confidence": getattr(spec, "confidence", CONFIDENCE),
        "rules": rules,
        "verdicts": verdicts,
        "warnings": warnings,
        "resolution": resolution,
        "rule_errors": rule_errors,
        "control_lines": control_lines,
        "adhesion_exponent": adhesion,
        "message": "; ".join(lines + warnings),
    }


def fit_exponent(by_b: dict[float, list[float]], target: list[float], confidence: float):
    r"""The adhesion exponent b at which the coarse strength meets ``target`` (strengths of
    the runs it should match), with Fieller's interval: the least-squares line
    :math:`\log \sigma_c = \alpha + \beta b` through the mean log strength of each exponent
    in ``by_b`` (b -> the strengths of its seeds), solved for the target's mean log,
    :math:`\hat b = (\bar y_T - \alpha) / \beta`. Numerator N and denominator D are linear
    combinations of independent means, so :math:`(N - b D)^2 \le t^2 \mathrm{Var}(N - b D)`
    gives the interval (Fieller 1954), at two-sided level ``confidence`` with
    :func:`engine.study.resolution.contrast_df` degrees of freedom. Returns (b, [low, high])
    with the interval None where the slope is not told apart from 0 (the interval is then
    unbounded: the data do not fix b), or None without two exponents of two or more positive
    strengths each and a target of two or more, or with a fitted slope of exactly 0."""
    from .resolution import contrast_df

    pts = sorted((b, np.log(v)) for b, v in by_b.items() if len(v) >= 2 and min(v) > 0)
    if len(pts) < 2 or len(target) < 2 or min(target) <= 0:
        return None
    bs = np.array([b for b, _ in pts])
    means = np.array([y.mean() for _, y in pts] + [np.log(target).mean()])
    counts = np.array([len(y) for _, y in pts] + [len(target)])
    var = np.array([y.var(ddof=1) for _, y in pts] + [np.log(target).var(ddof=1)]) / counts
    k = len(bs)
    sbb = float(np.sum((bs - bs.mean()) ** 2))
    d = np.r_[(bs - bs.mean()) / sbb, 0.0]  # the slope
    a = np.r_[1.0 / k - bs.mean() * d[:k], 0.0]  # the intercept
    n = np.r_[-a[:k], 1.0]  # target mean less the intercept
    num, den = float(n @ means), float(d @ means)
    if den == 0:
        return None
    b_hat = num / den
    vn, vd, cov = float(n**2 @ var), float(d**2 @ var), float((n * d) @ var)
    parts = (n - b_hat * d) ** 2 * var
    tot = float(parts.sum())
    df = contrast_df(counts, parts / tot if tot > 0 else np.zeros_like(parts))
    t2 = t_quantile(0.5 + 0.5 * confidence, df) ** 2
    qa = den**2 - t2 * vd
    qb = -2.0 * (num * den - t2 * cov)
    qc = num**2 - t2 * vn
    disc = qb * qb - 4 * qa * qc
    if qa <= 0 or disc < 0:
        return b_hat, None
    root = math.sqrt(disc)
    return b_hat, sorted([(-qb - root) / (2 * qa), (-qb + root) / (2 * qa)])


def adhesion_advice(
    spec, groups: list[dict], reference_strength: float | None, strengths: dict | None = None
) -> dict | None:
    """When rules differ only in their adhesion exponent: per radius the exponent whose
    strength is closest to the reference's, and the fitted one, solving
    log(strength(b)) = log(target strength) on the least-squares line of log strength
    against b (omitted with fewer than two positive strengths). With ``strengths``
    (``variants``: (radius, rule) -> the seeds' strengths; ``reference``; ``controls``:
    radius -> its controls' strengths) the fit is :func:`fit_exponent` with its interval,
    against the radius's resolution controls where it has them (the exponent that makes the
    coarse runs match the fine law in a sample as many diameters across: the rule's own
    mismatch, free of the sample's resolution loss), else against the references
    (``fitted_against`` says which; ``fitted_reference`` is always the latter)."""
    if not spec.reference.unconfined:
        return None
    families: dict[tuple, set] = {}
    for rule in spec.rules:
        a, b, _ = rule.exponents(spec.reference.pair_law)
        families.setdefault((a, rule.dt), set()).add(b)
    family = max(families.items(), key=lambda kv: len(kv[1]))
    if len(family[1]) < 2:
        return None
    a, dt = family[0]
    by_radius = {}
    for r in spec.coarse_radii:
        gs = [
            g
            for g in groups
            if g["radius"] == r
            and g["stiffness_exponent"] == a
            and g["dt"] == dt
            and "err_strength" in g
        ]
        if not gs:
            continue
        best = min(gs, key=lambda g: g["err_strength"])
        entry = {
            "best": best["adhesion_exponent"],
            "err_strength": best["err_strength"],
            "fitted": None,
        }
        pts = [
            (g["adhesion_exponent"], g["unconfined_strength"])
            for g in gs
            if g.get("unconfined_strength", 0.0) > 0
        ]
        if reference_strength and reference_strength > 0 and len({b for b, _ in pts}) >= 2:
            b, strength = np.array(pts).T
            slope, icept = np.polyfit(b, np.log(strength), 1)
            if slope > 0:
                entry["fitted"] = float((math.log(reference_strength) - icept) / slope)
        entry["fitted_against"] = "reference" if entry["fitted"] is not None else None
        entry["fitted_reference"] = entry["fitted"]
        entry["interval"] = None
        if strengths is not None:
            by_b = {
                g["adhesion_exponent"]: strengths["variants"].get((r, g["rule"]), []) for g in gs
            }
            conf = getattr(spec, "confidence", CONFIDENCE)
            ref_fit = fit_exponent(by_b, strengths.get("reference") or [], conf)
            ctl = (strengths.get("controls") or {}).get(r) or []
            fit = fit_exponent(by_b, ctl, conf) if len(ctl) >= 2 else None
            if ref_fit is not None:
                entry["fitted_reference"] = ref_fit[0]
                entry["fitted_reference_interval"] = ref_fit[1]
            if fit is not None:
                entry.update(fitted=fit[0], interval=fit[1], fitted_against="control")
            elif ref_fit is not None:
                entry.update(fitted=ref_fit[0], interval=ref_fit[1], fitted_against="reference")
        by_radius[f"{r:g}"] = entry
    return {"stiffness_exponent": a, "dt": dt, "by_radius": by_radius} if by_radius else None


def judge_groups(
    spec,
    ref_values: list[dict],
    variants: dict[tuple, list[dict]],
    names,
    look: int = 1,
    looks: int = 1,
) -> tuple[dict, list[dict]]:
    """Noise floor and verdicts: ``ref_values`` per reference seed, ``variants`` maps
    (radius, rule name) to the metric values of its seeds; ``looks``: how many times a
    study may judge its data (1 for a fixed study). Returns (noise floor per metric as
    JSON-friendly numbers, verdicts list)."""
    cons = spec.reference.consolidation_stress
    floor = noise_floor(ref_values, names, cons)
    alpha_e, alpha_d = error_rates(getattr(spec, "confidence", CONFIDENCE), len(names), look, looks)
    out = []
    for (radius, rule), values in variants.items():
        per_metric = [
            judge_metric(n, values, floor[n], spec.tolerances[n], cons, alpha_e, alpha_d)
            for n in names
        ]
        out.append(_judged(radius, rule, per_metric, len(values)))
    noise = {n: floor[n]["noise"] for n in names}
    return noise, out


def _judged(radius: float, rule: str, per_metric: list[dict], seeds: int) -> dict:
    v, reason = verdict(per_metric)
    return {
        "radius": radius,
        "rule": rule,
        "verdict": v,
        "reason": reason,
        "to_decide": what_decides(per_metric) if v == "undecided" else None,
        "seeds": seeds,
        "metrics": per_metric,
    }


def judge_rule_error(
    spec,
    radius: float,
    rule: str,
    values: dict[int, dict],
    controls: dict[int, dict],
    names,
    look: int = 1,
    looks: int = 1,
) -> dict:
    """A coarse variant against the resolution controls of its radius: the rule's own error
    (docs/PHYSICS.md section 7.4). ``values`` and ``controls`` map packing seed to metric
    values. A control and a coarse run of one seed start from the same scaled cloud, so a
    metric is judged on the per-seed differences of the seeds both have where
    :func:`pairing_pays` (their correlation, measured, narrows the interval more than the
    lost degrees of freedom widen it), else unpaired on all seeds of each side (for the
    metrics whose measured correlation is nil). The verdicts, rates and seed projections
    are those of :func:`judge_groups`; each metric says whether it was paired."""
    cons = spec.reference.consolidation_stress
    alpha_e, alpha_d = error_rates(getattr(spec, "confidence", CONFIDENCE), len(names), look, looks)
    both = sorted(set(values) & set(controls))
    c_all, k_all = list(values.values()), list(controls.values())
    floor_all = noise_floor(k_all, names, cons)
    floor_paired = noise_floor([controls[s] for s in both], names, cons) if both else None
    per_metric = []
    for n in names:
        tol = spec.tolerances[n]
        if pairing_pays(n, len(both), len(c_all), len(k_all), alpha_e):
            m = judge_metric(
                n,
                [values[s] for s in both],
                floor_paired[n],
                tol,
                cons,
                alpha_e,
                alpha_d,
                paired=True,
                against="control",
            )
        else:
            m = judge_metric(n, c_all, floor_all[n], tol, cons, alpha_e, alpha_d, against="control")
        per_metric.append(m)
    out = _judged(radius, rule, per_metric, len(c_all))
    out["control_seeds"] = len(k_all)
    out["paired_seeds"] = len(both)
    return out


__all__ = [
    "CONFIDENCE",
    "METRICS",
    "VERDICTS",
    "adhesion_advice",
    "advise",
    "error_rates",
    "finite_size_warnings",
    "fit_exponent",
    "judge_groups",
    "judge_metric",
    "judge_rule_error",
    "judge_samples",
    "look_alpha",
    "noise_floor",
    "pairing_pays",
    "resolution_lines",
    "seeds_needed",
    "two_sample_intervals",
    "variant_decided",
    "verdict",
    "what_decides",
]
