r"""Intervals with the coverage they state, for the verdicts (docs/PHYSICS.md section 7).

Student's t and the normal come from :mod:`scipy.special`, imported on first use (a
well-kept library where it has the function; until issue 42 they were hand-written).
What stays here is the verdicts' own arithmetic:

- :func:`welch`: the difference of two sample means with its standard uncertainty and the
  Welch-Satterthwaite effective degrees of freedom

  .. math:: u^2 = \frac{s_c^2}{n_c} + \frac{s_r^2}{n_r}, \qquad
            \nu = \frac{u^4}{\frac{(s_c^2/n_c)^2}{n_c - 1} + \frac{(s_r^2/n_r)^2}{n_r - 1}};

- :func:`interval_df`: the degrees of freedom a verdict's interval takes (a lower bound of
  Welch-Satterthwaite's, Hsu's where a side has fewer than three seeds), for spreads
  estimated from a side's own seeds or pooled over several groups (engine.study.pooling);
- :func:`log_ratio_interval`: the interval of a ratio of geometric means (a relative error),
  a t interval on the difference of mean logarithms.
"""

from __future__ import annotations

import math

import numpy as np

_SPECIAL = None


def _special():
    """scipy.special (Student's t as ufuncs: ``stdtr``, ``stdtrit``), imported when an
    interval is first asked for (``import engine`` and a run load only numpy and numba)."""
    global _SPECIAL
    if _SPECIAL is None:
        from scipy import special

        _SPECIAL = special
    return _SPECIAL


def t_cdf(x: float, df: float) -> float:
    """P(T <= x) of Student's t with ``df`` > 0 degrees of freedom (inf: the normal)."""
    if not df > 0:
        raise ValueError(f"t_cdf: degrees of freedom {df} must be > 0")
    return float(_special().stdtr(df, x))


def t_pdf(x: float, df: float) -> float:
    """Density of Student's t with ``df`` > 0 degrees of freedom (inf: the normal)."""
    from scipy import stats

    if math.isinf(df):
        return float(stats.norm.pdf(x))
    return float(stats.t.pdf(x, df))


def t_sf(x: float, df: float) -> float:
    """Upper tail P(T > x) of Student's t (a tail, not 1 - cdf: precise far out)."""
    return float(_special().stdtr(df, -x))


def t_quantile(p: float, df: float) -> float:
    """The x with P(T <= x) = ``p`` (0 < p < 1) of Student's t with ``df`` > 0 degrees of
    freedom (inf: the normal)."""
    if not 0.0 < p < 1.0:
        raise ValueError(f"t_quantile: p = {p} outside (0, 1)")
    if not df > 0:
        raise ValueError(f"t_quantile: degrees of freedom {df} must be > 0")
    if p < 0.5:  # the lower tail as a tail: precise far out
        return -float(_special().stdtrit(df, 1.0 - p))
    return float(_special().stdtrit(df, p))


def t_upper_quantiles(q: float, df) -> np.ndarray:
    """Element-wise :func:`t_quantile` (1 - ``q``, ``df``) for one upper-tail probability
    0 < ``q`` < 0.5 and an array of degrees of freedom > 0 (inf: the normal)."""
    if not 0.0 < q < 0.5:
        raise ValueError(f"t_upper_quantiles: q = {q} outside (0, 0.5)")
    if isinstance(df, float):  # one number: the same ufunc, without the array's checks
        if not df > 0:
            raise ValueError("t_upper_quantiles: degrees of freedom must be > 0")
        return -_special().stdtrit(df, q)
    df = np.asarray(df, dtype=float)
    if not np.all(df > 0):
        raise ValueError("t_upper_quantiles: degrees of freedom must be > 0")
    return (-_special().stdtrit(df, q))[()]


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


def interval_df(nc: int, nr: int, vc, vr, dfc=None, dfr=None, shared: bool = False):
    r"""Degrees of freedom of a two-sample interval with ``nc`` and ``nr`` values whose squared
    standard errors are ``vc`` = s_c^2 / n_c and ``vr`` = s_r^2 / n_r (numbers or arrays,
    element-wise); ``dfc`` and ``dfr`` are the degrees of freedom of each side's spread
    (default n - 1: its own seeds; more where it is pooled over several groups,
    engine.study.pooling). With two or more on each side, the smaller of
    :math:`\nu_i / c_i` over the two sides, :math:`c_i` a side's share of the squared
    standard error,

    .. math:: \nu = \min_i \frac{\nu_i}{c_i}, \qquad c_c = \frac{v_c}{v_c + v_r},

    a lower bound of Welch-Satterthwaite's :math:`1 / \sum_i c_i^2 / \nu_i` (the shares sum
    to 1) and at least :math:`\min_i \nu_i` (Hsu's min(n_c, n_r) - 1 for own spreads),
    equal to both where one side carries all the variance. Welch-Satterthwaite overshoots
    where a side of three seeds carries most of the variance and its spread came out small
    by chance, the more so for skewed values (simulated: up to 5.5 % wrong ``differs`` at a
    nominal 2.5 % per end, docs/PHYSICS.md section 7.1); this bound does not. With fewer than
    two on a side (fewer than three seeds of its own), :math:`\min_i \nu_i`, which holds for
    any two spreads (Hsu 1938). ``shared``: both sides' spread is one pooled estimate (a
    coarse variant and the controls of its radius), whose ``dfc`` the interval takes, as the
    pooled two-sample t does. Infinite where both spreads are zero."""
    if _scalars(vc, vr, dfc, dfr):
        return np.float64(_interval_df_scalar(nc, nr, float(vc), float(vr), dfc, dfr, shared))
    vc = np.asarray(vc, dtype=float)
    vr = np.asarray(vr, dtype=float)
    dfc = np.asarray(nc - 1 if dfc is None else dfc, dtype=float)
    dfr = np.asarray(nr - 1 if dfr is None else dfr, dtype=float)
    shape = np.broadcast_shapes(vc.shape, vr.shape, dfc.shape, dfr.shape)
    if shared:
        return np.broadcast_to(dfc, shape).astype(float)[()]
    floor = np.minimum(dfc, dfr)
    u2 = vc + vr
    with np.errstate(divide="ignore", invalid="ignore"):
        nu = np.minimum(
            np.where(vc > 0, dfc * u2 / np.where(vc > 0, vc, 1.0), np.inf),
            np.where(vr > 0, dfr * u2 / np.where(vr > 0, vr, 1.0), np.inf),
        )
    nu = np.where(floor < WELCH_MIN_SEEDS - 1, floor, np.maximum(nu, floor))
    return np.broadcast_to(nu, shape).astype(float)[()]


def _scalars(*values) -> bool:
    """Whether every value is a number (None counts as one): the scalar paths below, the
    same IEEE arithmetic without numpy's per-call overhead (the seed allocator asks for
    tens of thousands of intervals in a study's simulation of its own rates)."""
    for v in values:  # a loop, not all(...): called hundreds of thousands of times
        if v is not None and not isinstance(v, (int, float)):
            return False
    return True


def _interval_df_scalar(nc, nr, vc: float, vr: float, dfc, dfr, shared: bool) -> float:
    """:func:`interval_df` for numbers: the same operations in the same order, so the same
    double (numpy's float64 arithmetic is IEEE's, as Python's is)."""
    dfc = float(nc - 1 if dfc is None else dfc)
    dfr = float(nr - 1 if dfr is None else dfr)
    if shared:
        return dfc
    floor = min(dfc, dfr)
    u2 = vc + vr
    a = dfc * u2 / vc if vc > 0 else math.inf
    b = dfr * u2 / vr if vr > 0 else math.inf
    nu = min(a, b)
    return floor if floor < WELCH_MIN_SEEDS - 1 else max(nu, floor)


def log_ratio_interval(c, r, alpha: float) -> tuple[float, float, float, float]:
    r"""Ratio of the geometric means of the positive samples ``c`` and ``r`` (1-D, two or more
    values each, independent, spreads not assumed equal) with its interval at one-sided rate
    ``alpha`` per end: the t interval of the difference of the mean logarithms,

    .. math:: \bar\ell_c - \bar\ell_r \pm t_{1-\alpha, \nu}
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
