r"""Intervals with the coverage they state, for the verdicts (docs/PHYSICS.md section 7).

Everything here is plain numpy and :mod:`math` (the engine carries no scipy):

- :func:`t_cdf` / :func:`t_quantile`: Student's t distribution for any real degrees of
  freedom :math:`\nu > 0` (the regularised incomplete beta function by its continued
  fraction, inverted by bisection to 1e-12);
- :func:`welch`: the difference of two sample means with its standard uncertainty and the
  Welch-Satterthwaite effective degrees of freedom

  .. math:: u^2 = \frac{s_c^2}{n_c} + \frac{s_r^2}{n_r}, \qquad
            \nu = \frac{u^4}{\frac{(s_c^2/n_c)^2}{n_c - 1} + \frac{(s_r^2/n_r)^2}{n_r - 1}};

- :func:`fieller`: the interval of a ratio of two means (a relative error), whose degrees of
  freedom (:func:`hsu_df`) hold for any ratio of the two spreads.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

_EPS = 1e-15
_TINY = 1e-300


@njit(cache=True)
def _betacf(a: float, b: float, x: float) -> float:
    """Continued fraction of the incomplete beta function (modified Lentz)."""
    qab, qap, qam = a + b, a + 1.0, a - 1.0
    c, d = 1.0, 1.0 - qab * x / qap
    d = 1.0 / (d if abs(d) > _TINY else _TINY)
    h = d
    for m in range(1, 10_000):
        m2 = 2 * m
        aa = m * (b - m) * x / ((qam + m2) * (a + m2))
        d = 1.0 + aa * d
        d = 1.0 / (d if abs(d) > _TINY else _TINY)
        c = 1.0 + aa / c
        c = c if abs(c) > _TINY else _TINY
        h *= d * c
        aa = -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2))
        d = 1.0 + aa * d
        d = 1.0 / (d if abs(d) > _TINY else _TINY)
        c = 1.0 + aa / c
        c = c if abs(c) > _TINY else _TINY
        delta = d * c
        h *= delta
        if abs(delta - 1.0) < _EPS:
            return h
    return h  # not reached for the a, b, x a t distribution needs


def betainc(a: float, b: float, x: float) -> float:
    """Regularised incomplete beta function :math:`I_x(a, b)` for a, b > 0, x in [0, 1]."""
    if not (a > 0 and b > 0 and 0.0 <= x <= 1.0):
        raise ValueError(f"betainc: needs a, b > 0 and x in [0, 1] (got {a}, {b}, {x})")
    return _betainc(float(a), float(b), float(x))


@njit(cache=True)
def _betainc(a: float, b: float, x: float) -> float:
    if x == 0.0 or x == 1.0:
        return x
    ln = math.lgamma(a + b) - math.lgamma(a) - math.lgamma(b) + a * math.log(x) + b * math.log1p(-x)
    front = math.exp(ln)
    if x < (a + 1.0) / (a + b + 2.0):
        return front * _betacf(a, b, x) / a
    return 1.0 - front * _betacf(b, a, 1.0 - x) / b


def t_cdf(x: float, df: float) -> float:
    """P(T <= x) of Student's t with ``df`` > 0 degrees of freedom (inf: the normal)."""
    if not df > 0:
        raise ValueError(f"t_cdf: degrees of freedom {df} must be > 0")
    return _t_cdf(float(x), float(df))


@njit(cache=True)
def _t_cdf(x: float, df: float) -> float:
    if math.isinf(df):
        return 0.5 * math.erfc(-x / math.sqrt(2.0))
    tail = 0.5 * _betainc(0.5 * df, 0.5, df / (df + x * x))
    return 1.0 - tail if x > 0 else tail


@njit(cache=True)
def t_pdf(x: float, df: float) -> float:
    """Density of Student's t with ``df`` > 0 degrees of freedom."""
    if math.isinf(df):
        return math.exp(-0.5 * x * x) / math.sqrt(2.0 * math.pi)
    ln = (
        math.lgamma(0.5 * (df + 1.0))
        - math.lgamma(0.5 * df)
        - 0.5 * math.log(df * math.pi)
        - 0.5 * (df + 1.0) * math.log1p(x * x / df)
    )
    return math.exp(ln)


@njit(cache=True)
def t_sf(x: float, df: float) -> float:
    """Upper tail P(T > x) of Student's t (computed as a tail, not as 1 - cdf, so that
    it keeps its relative precision far out)."""
    return _t_cdf(-x, df)


def t_quantile(p: float, df: float) -> float:
    """The x with P(T <= x) = ``p`` (0 < p < 1) of Student's t with ``df`` > 0 degrees of
    freedom, to about 1e-10 relative for df up to 1e4: Newton steps on the upper tail
    :func:`t_sf` from the Cornish-Fisher expansion of the normal quantile, kept inside a
    bracket that bisection narrows where a step would leave it."""
    if not 0.0 < p < 1.0:
        raise ValueError(f"t_quantile: p = {p} outside (0, 1)")
    if not df > 0:
        raise ValueError(f"t_quantile: degrees of freedom {df} must be > 0")
    if p < 0.5:
        return -_t_upper(p, float(df))
    if p == 0.5:
        return 0.0
    return _t_upper(1.0 - p, float(df))


@njit(cache=True)
def _t_upper(q: float, df: float) -> float:
    """The x > 0 with P(T > x) = q < 0.5."""
    lo, hi = 0.0, 1.0
    while t_sf(hi, df) > q:
        lo, hi = hi, 4.0 * hi
        if hi > 1e300:
            return math.inf
    z = _normal_quantile(q)
    x = (
        z
        if math.isinf(df)
        else z + (z**3 + z) / (4 * df) + (5 * z**5 + 16 * z**3 + 3 * z) / (96 * df**2)
    )
    if not lo < x < hi:
        x = 0.5 * (lo + hi)
    for _ in range(200):
        f = q - t_sf(x, df)  # increasing in x
        if f < 0:
            lo = x
        else:
            hi = x
        nxt = x - f / max(t_pdf(x, df), _TINY)
        if not lo < nxt < hi:
            nxt = 0.5 * (lo + hi)
        if abs(nxt - x) <= 1e-14 * abs(nxt) or hi - lo <= 1e-14 * hi:
            return nxt
        x = nxt
    return x


@njit(cache=True)
def _normal_quantile(q: float) -> float:
    """Standard normal upper quantile: the x > 0 with P(Z > x) = ``q`` < 0.5 (Newton on
    erfc from the Abramowitz-Stegun 26.2.23 start)."""
    t = math.sqrt(-2.0 * math.log(q))
    x = t - (2.515517 + 0.802853 * t + 0.010328 * t * t) / (
        1.0 + 1.432788 * t + 0.189269 * t * t + 0.001308 * t**3
    )
    for _ in range(50):
        f = q - 0.5 * math.erfc(x / math.sqrt(2.0))
        step = f / (math.exp(-0.5 * x * x) / math.sqrt(2.0 * math.pi))
        x -= step
        if abs(step) <= 1e-15 * max(abs(x), 1.0):
            break
    return x


def welch(c: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Difference of means of samples ``c`` (n_c, ...) and ``r`` (n_r, ...) along axis 0,
    its standard uncertainty and Welch-Satterthwaite degrees of freedom (module docstring),
    element-wise over the trailing axes. Needs n_c >= 2 and n_r >= 2. Where both spreads
    are zero the uncertainty is 0 and the degrees of freedom infinite."""
    c = np.asarray(c, dtype=float)
    r = np.asarray(r, dtype=float)
    nc, nr = len(c), len(r)
    if nc < 2 or nr < 2:
        raise ValueError(f"welch needs two or more values per sample (got {nc} and {nr})")
    vc = c.var(axis=0, ddof=1) / nc
    vr = r.var(axis=0, ddof=1) / nr
    u2 = vc + vr
    den = vc**2 / (nc - 1) + vr**2 / (nr - 1)
    with np.errstate(divide="ignore", invalid="ignore"):
        df = np.where(den > 0, u2**2 / np.where(den > 0, den, 1.0), np.inf)
    return c.mean(axis=0) - r.mean(axis=0), np.sqrt(u2), df


def hsu_df(nc: int, nr: int) -> int:
    """Degrees of freedom of the two-sample t interval that holds whatever the ratio of the
    two spreads: min(n_c, n_r) - 1 (Hsu 1938; Scheffe 1970). Welch-Satterthwaite's
    estimate is exact only in the limit; with two seeds on one side it covers less than it
    states (tests/engine/test_coverage.py measures it)."""
    return min(nc, nr) - 1


def fieller(c, r, alpha: float) -> tuple[float, float, float, int]:
    r"""Ratio of means :math:`\rho = \mu_c / \mu_r` of samples ``c`` and ``r`` (1-D, two or
    more values each, independent, spreads not assumed equal) with its Fieller interval:
    the :math:`\rho` for which the contrast :math:`\bar c - \rho \bar r` is not rejected by
    a one-sided t test at error rate ``alpha`` on either side,

    .. math:: (\bar c - \rho \bar r)^2 \le t_{1-\alpha,\nu}^2
              \left(\frac{s_c^2}{n_c} + \rho^2 \frac{s_r^2}{n_r}\right),

    with :math:`\nu` = :func:`hsu_df`, so that an end equal to a tolerance bound is a
    one-sided test at that bound whose rate is at most ``alpha`` for any two spreads.
    Returns (ratio, low end, high end, degrees of freedom). Where the reference mean is not
    told apart from zero the interval has no bounds: (ratio, -inf, inf, dof). Exact for
    normal means with equal spreads; with unequal spreads the Hsu degrees of freedom make it
    conservative."""
    c = np.asarray(c, dtype=float)
    r = np.asarray(r, dtype=float)
    nc, nr = len(c), len(r)
    if nc < 2 or nr < 2:
        raise ValueError(f"fieller needs two or more values per sample (got {nc} and {nr})")
    mc, mr = float(c.mean()), float(r.mean())
    vc, vr = float(c.var(ddof=1)) / nc, float(r.var(ddof=1)) / nr
    df = hsu_df(nc, nr)
    rho, lo, hi = fieller_from_stats(mc, mr, vc, vr, t_quantile(1.0 - alpha, df))
    return rho, lo, hi, df


def fieller_from_stats(
    mc: float, mr: float, vc: float, vr: float, t: float
) -> tuple[float, float, float]:
    """:func:`fieller` from summary statistics: the means ``mc``, ``mr``, the squared
    standard errors ``vc`` = s_c^2 / n_c and ``vr`` = s_r^2 / n_r, and the quantile ``t``.
    Returns (ratio, low end, high end); (ratio, -inf, inf) where the reference mean is not
    told apart from zero."""
    rho = mc / mr if mr != 0 else math.inf
    t2 = t * t
    a = mr * mr - t2 * vr
    if a <= 0:
        return rho, -math.inf, math.inf
    b = -2.0 * mc * mr
    cc = mc * mc - t2 * vc
    root = math.sqrt(max(b * b - 4 * a * cc, 0.0))
    return rho, (-b - root) / (2 * a), (-b + root) / (2 * a)


def welch_interval(c, r, alpha: float) -> tuple[float, float, float, float]:
    """Difference of means of ``c`` and ``r`` (1-D) with its interval at one-sided error
    rate ``alpha`` per end, unequal spreads, :func:`hsu_df` degrees of freedom:
    (difference, low, high, degrees of freedom)."""
    d, u, _ = welch(c, r)
    d, u = float(d), float(u)
    df = hsu_df(len(c), len(r))
    t = t_quantile(1.0 - alpha, df)
    return d, d - t * u, d + t * u, df


__all__ = [
    "betainc",
    "fieller",
    "fieller_from_stats",
    "hsu_df",
    "t_cdf",
    "t_pdf",
    "t_quantile",
    "t_sf",
    "welch",
    "welch_interval",
]
