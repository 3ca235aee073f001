r"""The statistics of one comparison: one metric of one group against another, from compared
values and spreads to its interval, bias and verdict (docs/PHYSICS.md section 7.1).

For every verdict metric (:data:`engine.study.metrics.METRICS`) a coarse variant's seeds
are compared with the reference seeds (or, for the rule's own error, with its radius's
resolution controls) on the scale :mod:`engine.study.noise` chose, with the spreads it
pooled:

- the relative error at a level is :math:`\rho - 1` with the ratio of geometric means
  :math:`\rho = \exp(\overline{\log c} - \overline{\log r})` (a strength weaker than 5 % of
  the consolidation stress: the difference over that floor); its interval is the t interval
  of the difference of the means, with each side's spread (pooled over its radius, or its
  own) and :func:`engine.study.intervals.interval_df` degrees of freedom;
- ``equivalent`` when at **every** level the interval at one-sided rate
  :math:`\alpha_e = \alpha/2` lies inside the tolerance (:data:`EQUIVALENCE_LEVEL`: the
  two-sided :math:`1 - \alpha` interval); ``differs`` when the interval of the per-seed
  level means lies wholly outside it at :math:`\alpha_k / 2M` per end (Bonferroni over the
  :math:`M` metrics, the two ends and the looks :math:`k`); else ``undecided``;
- every metric also carries its **signed error** and that two-sided :math:`1 - \alpha`
  interval of the level mean: where it excludes zero the metric is *biased* high or low,
  whatever the tolerance question answers (a user needs the direction and size of a bias
  while the tolerance is still open);
- with fewer than two seeds on a side (and no pool) a spread is unknown: ``undecided``.

A (radius, rule) differs when any metric differs, is equivalent when all are, undecided
otherwise. The functions here are pure: arrays in, verdicts out; tests/engine/test_coverage.py
simulates their rates and power with :func:`judge_samples`, which runs the same arithmetic
over many studies at once.

The error rates spent are :mod:`engine.study.rates`' policy; how many seeds an undecided
metric needs is :func:`engine.study.seeds.seeds_needed`; whether a comparison is paired by
seed is :func:`engine.study.seeds.pairing_pays`' (:func:`paired_where_it_pays`); a group's
verdict over its metrics is :mod:`engine.study.judge`.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from .intervals import _interval_df_scalar, _scalars, interval_df, t_quantile, t_upper_quantiles
from .metrics import relative_error, signed_error
from .pooling import SCREEN_LEVEL, Spread, pool_arrays
from .seeds import PLANNED_POWER, pairing_pays, seeds_needed


class Space:
    """How one metric is compared at one radius: ``kind`` ``"log"`` (logarithms: a
    difference d of mean logs is the ratio exp(d) of geometric means, relative error
    exp(d) - 1, a tolerance's bounds log(1 -/+ tol)) or ``"difference"`` (the values over
    ``scale``: relative error d, bounds -/+ tol)."""

    def __init__(self, kind: str, scale=None):
        self.kind = kind
        self.scale = scale

    def map(self, a: np.ndarray) -> np.ndarray:
        return np.log(a) if self.kind == "log" else a / self.scale

    def rel(self, d):
        """A difference on this scale as a relative error [-]."""
        return float(np.expm1(d)) if self.kind == "log" else float(d)

    def bounds(self, tolerance: float) -> tuple[float, float]:
        if self.kind == "log":
            lo = np.log(1.0 - tolerance) if tolerance < 1 else -np.inf
            return float(lo), float(np.log1p(tolerance))
        return -tolerance, tolerance


def difference_interval(d, vc, vr, nc, nr, dfc, dfr, alpha, shared=False):
    """Difference ``d`` of two means with its interval at one-sided rate ``alpha`` per end:
    ``vc``, ``vr`` the per-seed variances of the two sides (numbers or arrays), ``nc``,
    ``nr`` their seeds, ``dfc``, ``dfr`` their spreads' degrees of freedom, ``shared`` one
    pooled spread for both. Returns arrays (low, high, dof, standard error). The one
    computation behind every interval of a verdict."""
    if _scalars(d, vc, vr, dfc, dfr):  # the same doubles, without numpy's overhead
        uc = float(vc) / nc
        ur = float(vr) / nr
        df = _interval_df_scalar(nc, nr, uc, ur, dfc, dfr, shared)
        u = math.sqrt(uc + ur)
        h = float(t_upper_quantiles(alpha, max(df, 1e-9))) * u if u > 0 else 0.0
        d = float(d)
        return np.float64(d - h), np.float64(d + h), np.asarray(df), np.float64(u)
    d = np.asarray(d, dtype=float)
    if d.shape == (1,) and all(np.shape(v) in ((), (1,)) for v in (vc, vr, dfc, dfr)):
        # one level (the commonest case): the number's path, as arrays of one
        one = [_number(v) for v in (vc, vr)]
        dfs = [_number(v) for v in (dfc, dfr)]
        lo, hi, df, u = difference_interval(float(d[0]), *one, nc, nr, *dfs, alpha, shared)
        return np.array([lo]), np.array([hi]), np.array([float(df)]), np.array([u])
    uc = np.asarray(vc, dtype=float) / nc
    ur = np.asarray(vr, dtype=float) / nr
    df = np.asarray(interval_df(nc, nr, uc, ur, dfc, dfr, shared), dtype=float)
    u = np.sqrt(uc + ur)
    h = np.where(u > 0, t_upper_quantiles(alpha, np.maximum(df, 1e-9)) * u, 0.0)
    return d - h, d + h, df, u


class Comparison:
    """One metric of one group against another (the references, or the controls of its
    radius) on the compared scale: means per level and of the per-seed level means, the two
    spreads (:class:`engine.study.pooling.Spread`), the bounds of the tolerance.
    ``paired``: the rows are matched by seed and the interval is the one-sample t of the
    per-seed differences (a rule against its controls); ``shared``: both sides take one
    pooled spread."""

    def __init__(
        self,
        space: Space,
        c: np.ndarray,
        r: np.ndarray,
        sc: Spread,
        sr: Spread,
        tolerance: float,
        paired: bool = False,
    ):
        self.space = space
        self.kind = space.kind
        self.lo, self.hi = space.bounds(tolerance)
        self.tolerance = tolerance
        self.paired = paired
        c, r = np.atleast_2d(c), np.atleast_2d(r)
        self.nc, self.nr = len(c), len(r)
        if self.nc == 0 or self.nr == 0:  # nothing to compare (e.g. no run failed)
            width = max(c.shape[1], r.shape[1])
            c = np.zeros((0, width)) if self.nc == 0 else c
            r = np.zeros((0, width)) if self.nr == 0 else r
            self.mc = c.mean(axis=0) if self.nc else np.zeros(width)
            self.mr = r.mean(axis=0) if self.nr else np.zeros(width)
            self.mcs = self.mrs = 0.0
            self.sc, self.sr, self.shared = sc, sr, False
            self.paired = False
            return
        if paired:
            dd = c - r
            self.mc, self.mr = dd.mean(axis=0), np.zeros(dd.shape[1])
            ds = dd.mean(axis=1)
            self.mcs, self.mrs = float(ds.mean()), 0.0
            own = len(dd) > 1
            self.sc = Spread(
                dd.var(axis=0, ddof=1) if own else np.zeros(dd.shape[1]),
                float(ds.var(ddof=1)) if own else 0.0,
                float(len(dd) - 1),
                False,
                ("paired",),
            )
            self.sr = Spread(np.zeros(dd.shape[1]), 0.0, math.inf, False, ("paired",))
            self.shared = False
            return
        self.mc, self.mr = c.mean(axis=0), r.mean(axis=0)
        self.mcs, self.mrs = float(c.mean(axis=1).mean()), float(r.mean(axis=1).mean())
        self.sc, self.sr = sc, sr
        self.shared = sc.pooled and sr.pooled and set(sc.pool) == set(sr.pool)

    def own_known(self, nc=None, nr=None) -> bool:
        """Whether both sides' own spreads are known (two or more seeds each) at the observed
        or projected counts."""
        nc = self.nc if nc is None else nc
        nr = self.nr if nr is None else nr
        return nc >= 2 and (self.paired or nr >= 2)

    @property
    def known(self) -> bool:
        """Whether both spreads are known (the interval exists)."""
        if self.nc == 0 or self.nr == 0:
            return False
        if self.paired:
            return self.nc > 1
        return self.sc.known and self.sr.known and self.nc > 0 and self.nr > 0

    def interval(self, alpha: float, nc=None, nr=None, summed: bool = False, own=False):
        """(difference, low, high, dof, standard error) per level, or of the level means
        (``summed``), at the observed counts or, projected, ``nc`` and ``nr`` seeds (a
        spread gains a degree of freedom per added seed); with each side's own spread
        (``own``: the ``differs`` test and the bias) or the pooled one (equivalence)."""
        nc = self.nc if nc is None else nc
        nr = self.nr if nr is None else nr
        sc, sr, n_r, dfc, dfr, shared = self._sides(nc, nr, own)
        if summed:
            d = self.mcs - self.mrs
            vc, vr = sc.var_summed, sr.var_summed
        else:
            d = self.mc - self.mr
            vc, vr = sc.var, sr.var
        vr = 0.0 if self.paired else vr
        lo, hi, df, u = difference_interval(d, vc, vr, nc, n_r, dfc, dfr, alpha, shared)
        return np.asarray(d, dtype=float), lo, hi, df, u

    def _sides(self, nc: int, nr: int, own: bool):
        """The two spreads at ``nc`` and ``nr`` seeds, as :func:`difference_interval` takes
        them: (coarse spread, reference spread, reference count, coarse and reference
        degrees of freedom, shared). Paired: the per-seed differences against a reference
        of no spread (one count, infinite degrees of freedom)."""
        add_c, add_r = nc - self.nc, nr - self.nr
        sc, sr = (self.sc.own, self.sr.own) if own else (self.sc, self.sr)
        shared = self.shared and not own
        dfc = sc.grown(add_c)
        dfr = sr.grown(add_r)
        if shared:
            dfc = dfr = sc.df + add_c + add_r
        if self.paired:
            return sc, sr, 1, dfc, math.inf, False
        return sc, sr, nr, dfc, dfr, shared

    def _one_level(self, alpha: float, nc: int, nr: int):
        """:meth:`interval` (``alpha``, ``nc``, ``nr``)'s difference, upper end and standard
        error as numbers where the metric has one level, else None: the path
        :func:`difference_interval` takes for one level, its conversions made once per
        comparison (the seed allocator asks for these hundreds of thousands of times in
        the coverage simulations)."""
        if not self._level_terms:
            return None
        d, vc, vr = self._level_terms
        _, _, n_r, dfc, dfr, shared = self._sides(nc, nr, own=False)
        _, hi, _, u = difference_interval(
            d, vc, vr, nc, n_r, _number(dfc), _number(dfr), alpha, shared
        )
        return d, hi, u

    @functools.cached_property
    def _level_terms(self) -> tuple:
        """(difference, the two variances) as numbers for :meth:`_one_level`, or () where
        the metric has more than one level."""
        one = ((), (1,))
        if np.shape(self.mc) != (1,) or np.shape(self.mr) != (1,):
            return ()
        if np.shape(self.sc.var) not in one or (
            not self.paired and np.shape(self.sr.var) not in one
        ):
            return ()
        vr = 0.0 if self.paired else _number(self.sr.var)
        return float((self.mc - self.mr)[0]), _number(self.sc.var), vr

    def equivalent(self, alpha: float, nc=None, nr=None) -> bool:
        """Every level's interval inside the bounds."""
        _, lo, hi, _, _ = self.interval(alpha, nc, nr)
        return bool(np.all(lo >= self.lo) and np.all(hi <= self.hi))

    def differs(self, alpha: float, nc=None, nr=None) -> bool:
        """The interval of the level means, with each side's own spread, wholly beyond a
        bound."""
        if not self.own_known(nc, nr):
            return False
        _, lo, hi, _, _ = self.interval(alpha, nc, nr, summed=True, own=True)
        return bool(lo > self.hi or hi < self.lo)

    def projected(self, n: int, m: int, alpha_e: float, alpha_d: float) -> str | None:
        """The verdict with ``n`` and ``m`` seeds if the means and spreads stayed as
        observed (None: undecided)."""
        if self.differs(alpha_d, n, m):
            return "differs"
        return "equivalent" if self.equivalent(alpha_e, n, m) else None

    def chance(self, n: int, m: int, alpha_e: float, alpha_d: float, truth=None):
        """Chance that this metric is decided with ``n`` and ``m`` seeds, if its spreads
        stayed as observed and its true difference were ``truth`` (a number for every level;
        default: the observed differences): each estimate normal about the truth with its
        projected standard error, against the bounds narrowed (equivalence, at the level
        where that is least likely: an upper bound of every level's being inside) or widened
        (differs, on the level means) by the projected half-widths. Returns the chances
        of ``equivalent`` and of ``differs``."""
        z = _normal_cdf
        one = self._one_level(alpha_e, n, m)
        if one is not None:  # one level (a scalar metric): numbers, the same doubles
            d, hi, u = one
            levels = ((d, hi, u, d if truth is None else float(truth)),)
        else:
            d, _, hi, _, u = self.interval(alpha_e, n, m)
            mu = np.broadcast_to(d if truth is None else float(truth), np.shape(d))
            levels = zip(np.atleast_1d(d), np.atleast_1d(hi), np.atleast_1d(u), np.atleast_1d(mu))
        p_eq = 1.0
        for dl, hl, ul, ml in levels:
            h = float(hl - dl)
            if ul > 0:
                p = z((self.hi - h - ml) / ul) - z((self.lo + h - ml) / ul)
            else:
                p = float(self.lo + h <= ml <= self.hi - h)
            p_eq = min(p_eq, max(0.0, p))
        if not self.own_known(n, m):
            return p_eq, 0.0
        ds, _, hi_d, _, us = self.interval(alpha_d, n, m, summed=True, own=True)
        ms = float(ds) if truth is None else float(truth)
        h = float(hi_d - ds)
        us = float(us)
        if us > 0:
            p_di = 1.0 - z((self.hi + h - ms) / us) + z((self.lo - h - ms) / us)
        else:
            p_di = float(ms > self.hi + h or ms < self.lo - h)
        return p_eq, min(1.0, p_di)

    def planned_power(self, n: int, m: int, alpha_e: float) -> bool:
        """Whether with ``n`` and ``m`` seeds, a true error of 0 and the spreads as observed,
        the chance of ``equivalent`` is at least :data:`PLANNED_POWER` at every level."""
        _, lo, hi, _, u = self.interval(alpha_e, n, m)
        z = t_quantile(0.5 + 0.5 * PLANNED_POWER, math.inf)
        return bool(np.all(0.5 * (hi - lo) + z * u <= min(self.hi, -self.lo)))


def paired_where_it_pays(comp: Comparison, name: str, c_rows, r_rows, alpha: float) -> Comparison:
    """``comp`` (unpaired) as the comparison of the per-seed differences where
    :func:`engine.study.seeds.pairing_pays` at one-sided rate ``alpha`` (a rule against its
    controls, or the protocol check against the references: runs of one packing seed start
    from one scaled cloud), else ``comp`` itself. ``c_rows``, ``r_rows``: both sides' raw
    values of the seeds they share, in one order. A strength is never paired: it compares
    the runs that failed at a peak, and the two runs of a seed need not both have."""
    df_unpaired = float(np.min(comp.interval(alpha)[3])) if comp.known else None
    if name == "strength" or not pairing_pays(
        name, len(c_rows), comp.nc, comp.nr, alpha, df_unpaired
    ):
        return comp
    sp = comp.space
    c = sp.map(np.array([np.atleast_1d(v) for v in c_rows], dtype=float))
    r = sp.map(np.array([np.atleast_1d(v) for v in r_rows], dtype=float))
    return Comparison(sp, c, r, comp.sc, comp.sr, comp.tolerance, paired=True)


def _number(v):
    """``v`` (a number or an array of one) as a float, as :func:`difference_interval` reads
    one level's terms; None stays None."""
    if v is None or isinstance(v, float):
        return v
    return float(np.asarray(v).reshape(-1)[0])


def _normal_cdf(x: float) -> float:
    return 0.5 * math.erfc(-x / math.sqrt(2.0))


# ------------------------------------------------------------------------------- one metric
def judge_metric(
    name: str,
    comp: Comparison,
    alpha_equivalent: float,
    alpha_differs: float,
    raw_c: np.ndarray | None = None,
    raw_r: np.ndarray | None = None,
    consolidation_stress: float = 1.0,
    against: str = "reference",
    counts: dict | None = None,
) -> dict:
    """Error, interval, bias and verdict of one metric of one group (module docstring).
    ``raw_c``, ``raw_r``: the raw values (seeds x levels) for the reported RMS and signed
    errors; ``counts``: runs left out of this metric (hardening samples, for a strength)."""
    out = {
        "metric": name,
        "tolerance": comp.tolerance,
        "seeds": comp.nc,
        "reference_seeds": comp.nr,
        "alpha_equivalent": alpha_equivalent,
        "alpha_differs": alpha_differs,
        "interval": None,
        "differs_interval": None,
        "level": None,
        "df": None,
        "uncertainty": None,
        "needs": None,
        "paired": comp.paired,
        "against": against,
        "pooled": bool(comp.sc.pooled) and not comp.paired,
        "pool_df": float(comp.sc.df) if comp.sc.known else None,
        "screen": _screen_words(comp.sc, comp.paired),
        "bias": None,
        **(counts or {}),
    }
    if raw_c is not None and raw_r is not None and len(raw_c) and len(raw_r):
        mc, mr = np.asarray(raw_c).mean(axis=0), np.asarray(raw_r).mean(axis=0)
        out["error"] = relative_error(name, mc, mr, consolidation_stress)
        out["signed_error"] = signed_error(name, mc, mr, consolidation_stress)
    else:
        out["error"] = out["signed_error"] = None
    if not comp.known:
        out.update(verdict="undecided")
        return out
    sp = comp.space
    d, lo, hi, df, u = comp.interval(alpha_equivalent)
    excess = np.maximum(hi - comp.hi, comp.lo - lo)
    k = int(np.argmax(excess))
    equivalent = bool(excess[k] <= 0)
    own = comp.own_known()
    dd = comp.interval(alpha_differs, summed=True, own=True) if own else (d, lo, hi)
    differs = own and bool(dd[1] > comp.hi or dd[2] < comp.lo)
    ds, ls, hs, _, _ = comp.interval(alpha_equivalent, summed=True, own=own)
    bias = None
    if own and ls > 0:
        bias = "high"
    elif own and hs < 0:
        bias = "low"
    levels = len(np.atleast_1d(d))
    out.update(
        interval=[sp.rel(lo[k]), sp.rel(hi[k])],
        level=None if levels == 1 else k,
        level_error=sp.rel(d[k]),
        df=float(df[k]),
        differs_interval=[sp.rel(dd[1]), sp.rel(dd[2])] if own else None,
        differs_error=sp.rel(dd[0]) if own else None,
        uncertainty=float(np.sqrt(np.mean(np.asarray(u) ** 2))),
        scale=comp.kind,
        bias={
            "direction": bias,
            "error": sp.rel(ds),
            "interval": [sp.rel(ls), sp.rel(hs)],
            "confidence": 1.0 - 2.0 * alpha_equivalent,
        },
        verdict="differs" if differs else "equivalent" if equivalent else "undecided",
    )
    if out["verdict"] == "undecided":
        out["needs"] = seeds_needed(comp, alpha_equivalent, alpha_differs)
    return out


def _screen_words(s: Spread, paired: bool) -> str | None:
    """How a group's spread was taken, for the reason."""
    if paired:
        return "paired by seed"
    if s.pooled:
        return f"spread pooled over {len(s.pool)} groups at its radius, {s.df:g} dof"
    if s.ratio is not None and s.p_value is not None and s.p_value < SCREEN_LEVEL:
        return (
            f"spread {math.sqrt(s.ratio):.1f}x the pooled spread of the other groups at "
            f"its radius (one-sided F test, p = {s.p_value:.2g} < {SCREEN_LEVEL:g}): judged "
            f"on its own spread, {s.df:g} dof"
        )
    return None


# ------------------------------------------------------------------- many studies at once
def judge_samples(
    c,
    r,
    tolerance: float,
    alpha_e: float,
    alpha_d: float,
    paired: bool = False,
    others=(),
    level: float | None = SCREEN_LEVEL,
) -> np.ndarray:
    """The verdicts of many studies of one positive scalar metric at once: ``c`` (studies x
    coarse seeds), ``r`` (studies x reference seeds; ``paired``: as many, matched by
    column), ``others``: arrays (studies x seeds) of the other groups at the coarse side's
    radius, pooled with it (:func:`engine.study.pooling.pool_arrays`, screen at ``level``);
    the same arithmetic as :func:`judge_metric`. Returns an array of verdicts."""
    lc, lr = np.log(np.asarray(c, dtype=float)), np.log(np.asarray(r, dtype=float))
    nc, nr = lc.shape[1], lr.shape[1]
    lo_b, hi_b = Space("log").bounds(tolerance)
    if paired:
        dd = lc - lr
        d = dd.mean(1)
        vc, vr, dfc, dfr, shared = dd.var(1, ddof=1), 0.0, nc - 1.0, math.inf, False
        nr_eff = 1
    else:
        d = lc.mean(1) - lr.mean(1)
        vc, dfc = lc.var(1, ddof=1), float(nc - 1)
        if len(others):
            groups = [lc, *(np.log(np.asarray(o, dtype=float)) for o in others)]
            var = np.stack([g.var(1, ddof=1) for g in groups], axis=-1)[..., None]
            dof = np.array([g.shape[1] - 1 for g in groups], dtype=float)
            pv, _, pdf, _, _ = pool_arrays(var, var[..., 0], dof, level)
            vc, dfc = pv[:, 0, 0], pdf[:, 0]
        vr, dfr, shared, nr_eff = lr.var(1, ddof=1), float(nr - 1), False, nr
    lo, hi, _, _ = difference_interval(d, vc, vr, nc, nr_eff, dfc, dfr, alpha_e, shared)
    equivalent = (lo >= lo_b) & (hi <= hi_b)
    own_c = (lc - lr).var(1, ddof=1) if paired else lc.var(1, ddof=1)
    lo, hi, _, _ = difference_interval(d, own_c, vr, nc, nr_eff, nc - 1.0, dfr, alpha_d)
    differs = (lo > hi_b) | (hi < lo_b)
    return np.where(differs, "differs", np.where(equivalent, "equivalent", "undecided"))


__all__ = [
    "Comparison",
    "Space",
    "difference_interval",
    "judge_metric",
    "judge_samples",
    "paired_where_it_pays",
]
