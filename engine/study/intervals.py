r"""Intervals with the coverage they state, for the verdicts (docs/PHYSICS.md section 7).

Everything here is plain numpy and :mod:`math` (the engine carries no scipy):

- :func:`t_cdf` / :func:`t_quantile`: Student's t distribution for any real degrees of
  freedom :math:`\nu > 0` (the regularised incomplete beta function by its continued
  fraction, inverted by bisection to 1e-12);
- :func:`welch`: the difference of two sample means with its standard uncertainty and the
  Welch-Satterthwaite effective degrees of freedom

  .. math:: u^2 = \frac{s_c^2}{n_c} + \frac{s_r^2}{n_r}, \qquad
            \nu = \frac{u^4}{\frac{(s_c^2/n_c)^2}{n_c - 1} + \frac{(s_r^2/n_r)^2}{n_r - 1}};

- :func:`log_ratio_interval`: the interval of a ratio of geometric means (a relative error),
  a t interval on the difference of mean logarithms, with Welch-Satterthwaite degrees of
  freedom where both sides have three or more values and Hsu's min(n_c, n_r) - 1 otherwise
  (:func:`interval_df`).
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


def t_upper_quantiles(q: float, df) -> np.ndarray:
    """Element-wise :func:`t_quantile` (1 - ``q``, ``df``) for one upper-tail probability
    0 < ``q`` < 0.5 and an array of degrees of freedom > 0 (inf: the normal)."""
    if not 0.0 < q < 0.5:
        raise ValueError(f"t_upper_quantiles: q = {q} outside (0, 0.5)")
    df = np.asarray(df, dtype=float)
    if not np.all(df > 0):
        raise ValueError("t_upper_quantiles: degrees of freedom must be > 0")
    return _t_upper_many(float(q), df.ravel()).reshape(df.shape)


@njit(cache=True)
def _t_upper_many(q: float, df: np.ndarray) -> np.ndarray:
    out = np.empty(df.size)
    for i in range(df.size):
        out[i] = _t_upper(q, df[i])
    return out


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
    two spreads: min(n_c, n_r) - 1 (Hsu 1938; Scheffe 1970)."""
    return min(nc, nr) - 1


#: Fewest seeds on each side for the Welch-Satterthwaite degrees of freedom; with fewer on a
#: side the interval takes Hsu's min(n_c, n_r) - 1 (docs/PHYSICS.md section 7.1).
WELCH_MIN_SEEDS = 3


def interval_df(nc: int, nr: int, vc, vr):
    r"""Degrees of freedom of a two-sample interval with ``nc`` and ``nr`` values whose squared
    standard errors are ``vc`` = s_c^2 / n_c and ``vr`` = s_r^2 / n_r (numbers or arrays,
    element-wise). With :data:`WELCH_MIN_SEEDS` or more on each side, the smaller of
    :math:`(n_i - 1) / c_i` over the two sides, :math:`c_i` a side's share of the squared
    standard error,

    .. math:: \nu = \min_i \frac{n_i - 1}{c_i}, \qquad c_c = \frac{v_c}{v_c + v_r},

    a lower bound of Welch-Satterthwaite's :math:`1 / \sum_i c_i^2 / (n_i - 1)` (the
    shares sum to 1) and at least Hsu's min(n_c, n_r) - 1, equal to both where one side
    carries all the variance. Welch-Satterthwaite overshoots where a side of three seeds
    carries most of the variance and its spread came out small by chance, the more so for
    skewed values (simulated: up to 5.5 % wrong ``differs`` at a nominal 2.5 % per end,
    docs/PHYSICS.md section 7.1);
    this bound does not. With fewer seeds on a side, Hsu's min(n_c, n_r) - 1, which holds for
    any two spreads. Infinite where both spreads are zero."""
    vc = np.asarray(vc, dtype=float)
    vr = np.asarray(vr, dtype=float)
    hsu = float(hsu_df(nc, nr))
    if min(nc, nr) < WELCH_MIN_SEEDS:
        return np.full(np.broadcast_shapes(vc.shape, vr.shape), hsu)[()]
    u2 = vc + vr
    with np.errstate(divide="ignore", invalid="ignore"):
        nu = np.minimum(
            np.where(vc > 0, (nc - 1) * u2 / np.where(vc > 0, vc, 1.0), np.inf),
            np.where(vr > 0, (nr - 1) * u2 / np.where(vr > 0, vr, 1.0), np.inf),
        )
    return np.maximum(nu, hsu)[()]


def log_ratio_interval(c, r, alpha: float) -> tuple[float, float, float, float]:
    r"""Ratio of the geometric means of the positive samples ``c`` and ``r`` (1-D, two or more
        values each, independent, spreads not assumed equal) with its interval at one-sided rate
        ``alpha`` per end: the t interval of the difference of the mean logarithms,

        .. math:: ar{\ell}_c - ar{\ell}_r \pm t_{1-lpha,
    u}
                  \sqrt{s_{\ell c}^2 / n_c + s_{\ell r}^2 / n_r},

        mapped back by exp (Schuirmann 1987, the bioequivalence two one-sided tests), with
        :func:`interval_df` degrees of freedom. Bounded for any data, unlike Fieller's interval
        of a ratio of arithmetic means, and its degrees of freedom do not depend on the ratio.
        Returns (ratio, low end, high end, degrees of freedom)."""
    c = np.asarray(c, dtype=float)
    r = np.asarray(r, dtype=float)
    nc, nr = len(c), len(r)
    if nc < 2 or nr < 2:
        raise ValueError(f"log_ratio_interval needs two or more values per sample (got {nc}, {nr})")
    if not (np.all(c > 0) and np.all(r > 0)):
        raise ValueError("log_ratio_interval needs positive values")
    lc, lr = np.log(c), np.log(r)
    vc, vr = float(lc.var(ddof=1)) / nc, float(lr.var(ddof=1)) / nr
    df = float(interval_df(nc, nr, vc, vr))
    d = float(lc.mean() - lr.mean())
    h = t_quantile(1.0 - alpha, df) * math.sqrt(vc + vr)
    return math.exp(d), math.exp(d - h), math.exp(d + h), df


def welch_interval(c, r, alpha: float) -> tuple[float, float, float, float]:
    """Difference of means of ``c`` and ``r`` (1-D) with its interval at one-sided error
    rate ``alpha`` per end, unequal spreads, :func:`interval_df` degrees of freedom:
    (difference, low, high, degrees of freedom)."""
    d, u, _ = welch(c, r)
    d, u = float(d), float(u)
    nc, nr = len(c), len(r)
    c, r = np.asarray(c, dtype=float), np.asarray(r, dtype=float)
    df = float(interval_df(nc, nr, c.var(ddof=1) / nc, r.var(ddof=1) / nr))
    t = t_quantile(1.0 - alpha, df)
    return d, d - t * u, d + t * u, df


__all__ = [
    "WELCH_MIN_SEEDS",
    "betainc",
    "hsu_df",
    "interval_df",
    "log_ratio_interval",
    "t_cdf",
    "t_pdf",
    "t_quantile",
    "t_sf",
    "t_upper_quantiles",
    "welch",
    "welch_interval",
]
