r"""The resolution curve: each property against d / L, extrapolated to the bulk
(docs/PHYSICS.md section 7.5).

A study with resolution controls has the reference law at several sample sizes: the
references, ``L / d`` diameters across (d the particle diameter, L the cell's thickness), and
per coarse radius the controls, fewer diameters across. Per property, with
:math:`x = d / L` and :math:`y` the logarithm of the property (the mean over stress levels
for density and coordination), the line

.. math:: y(x) = a + b\,x

through the sizes' mean logs :math:`\bar y_g` (one point per size, ordinary least squares,
so noisy weights do not enter) gives the bulk value :math:`e^a` at :math:`d / L = 0` and the
reference's own distance from it, :math:`e^{b x_{ref}} - 1`. A wall layer or a shear band a
few diameters wide is a fraction of the sample that goes as d / L, so linear in d / L is the
leading term; with three or more sizes the report shows how far the means lie from the line
(in their standard errors), the check of that assumption the data allow.

Both :math:`a` and :math:`b x_{ref}` are linear combinations :math:`\sum_g \lambda_g \bar y_g`
of independent size means, so their variance is :math:`\sum_g \lambda_g^2 s_g^2 / n_g` from the
seeds' spreads, and their interval a Student-t one with the degrees of freedom of
:func:`engine.study.intervals.interval_df` generalised to several groups: the smallest
:math:`(n_g - 1) / c_g`, :math:`c_g` a size's share of the variance (a lower bound of
Welch-Satterthwaite's), or :math:`\min_g n_g - 1` where a size has fewer than three seeds.

**Pooled spreads** (``pooled=True``, the resolution benchmark's rule since 2026-12-04). A size
of two seeds has one degree of freedom of its own, and by the bound above it sets every
interval's t quantile (12.7 at 95 %, 76 with the linearity check's Bonferroni over six sizes):
one more size made every answer worse. The sizes' spreads are then pooled as the study pools
its groups' (:mod:`engine.study.pooling`), on a stated size scaling: the seed variance of a
size's log value is taken as :math:`\sigma^2 (x_g / x_{ref})^p` with
:data:`SPREAD_EXPONENT` p = 2. A property set on a plane through the sample (a shear band,
the layer at a platen) averages over :math:`(L / d)^2` grains, so its spread falls at least
as fast as :math:`d / L`; a volume average falls as :math:`(d / L)^3` (one over the particle
count). The scaling is an assumption, so it only widens: a size's variance is the larger of
its own and the pool's (a true fall faster than assumed under-states the coarser sizes'
spread, and alone that costs coverage: 92.5 % at a fall as (d / L)^3, simulated). The
one-sided F screen at :data:`engine.study.pooling.SCREEN_LEVEL` keeps a size whose scaled
spread is larger than the pool of the others on its own spread (as a noisier group keeps its
own in a study), and a combination's degrees of freedom are those of :func:`sources_df` over
its variance sources (the pool, and each size on its own spread). Coverage and false alarms
are simulated in tests/engine/test_resolution.py for spreads that fall as
:math:`(d / L)^0` to :math:`(d / L)^5` (docs/PHYSICS.md section 7.5 gives the rates).
"""

from __future__ import annotations

import math

import numpy as np

from .intervals import WELCH_MIN_SEEDS, t_quantile
from .pooling import SCREEN_LEVEL, pool_arrays
from .reasons import _pct, interval_words

#: The false-alarm rate [-] of the linearity check (:func:`linearity`): the chance that a
#: property truly linear in d / L is called not linear, jointly over the sizes (Bonferroni).
LINEARITY_ALPHA = 0.05
#: The fewest sizes a fit keeps when :func:`asymptotic_curve` leaves out the smallest
#: samples: three, so that linearity can still be checked.
MIN_SIZES = 3
#: The exponent p [-] of the pooled fit's size scaling of the seed variance of a log value,
#: :math:`\propto (d / L)^p`: 2, a property set on a plane through the sample (the slowest
#: fall the physics gives; a volume average falls as 3), for that reason (module
#: docstring); chosen after the stored sizes' own spreads had been seen and before the
#: pooled rule was first applied to them (docs/RESOLUTION.md says so).
SPREAD_EXPONENT = 2.0


def sources_df(dofs, shares) -> float:
    """Degrees of freedom of a linear combination whose variance comes from independent
    variance estimates (sources) of ``dofs`` degrees of freedom each, ``shares`` of the
    variance (summing to 1): min dof_s / c_s over the sources that carry variance, at least
    their min dof_s (a lower bound of Welch-Satterthwaite's); min dof_s where a source has
    fewer than :data:`WELCH_MIN_SEEDS` - 1 degrees of freedom. Infinite where no source
    carries variance."""
    dofs = np.asarray(dofs, dtype=float)
    shares = np.asarray(shares, dtype=float)
    hsu = float(dofs.min())
    if hsu < WELCH_MIN_SEEDS - 1:
        return hsu
    live = shares > 0
    if not live.any():
        return math.inf
    return max(float(np.min(dofs[live] / shares[live])), hsu)


def contrast_df(counts, shares) -> float:
    """Degrees of freedom of a linear combination of independent group means, with ``counts``
    values per group and ``shares`` of its variance (summing to 1): min (n_g - 1) / c_g over
    the groups that carry variance, at least min n_g - 1; min n_g - 1 where a group has
    fewer than :data:`WELCH_MIN_SEEDS` values (:func:`sources_df`, each group its own
    source). Infinite where no group carries variance."""
    return sources_df(np.asarray(counts, dtype=float) - 1.0, shares)


class _Noise:
    """The size means' variances [log units^2] and where they come from: ``sources`` is a
    list of (degrees of freedom, indices of the sizes whose variance that estimate sets)."""

    def __init__(self, var_of_mean, sources):
        self.var_of_mean = np.asarray(var_of_mean, dtype=float)
        self.sources = sources

    def df(self, parts: np.ndarray) -> float:
        """Degrees of freedom of a combination whose variance is ``parts`` per size."""
        v = float(parts.sum())
        dofs = np.array([d for d, _ in self.sources], dtype=float)
        shares = np.array([parts[idx].sum() / v if v > 0 else 0.0 for _, idx in self.sources])
        return sources_df(dofs, shares)


def size_noise(sizes: list[dict], pooled: bool) -> _Noise:
    """The variances of ``sizes``' mean logs: each size's own seed spread, or (``pooled``)
    the pool over the sizes on the scaling of :data:`SPREAD_EXPONENT` with the one-sided
    F screen of :func:`engine.study.pooling.pool_arrays`, and never below the size's own
    spread (module docstring)."""
    counts = np.array([len(s["logs"]) for s in sizes], dtype=float)
    own = np.array([np.var(s["logs"], ddof=1) for s in sizes])
    dof = counts - 1.0
    if not pooled or len(sizes) < 2:
        return _Noise(own / counts, [(d, np.array([i])) for i, d in enumerate(dof)])
    x = np.array([s["x"] for s in sizes])
    xr = next(s["x"] for s in sizes if s["reference"])
    scale = (x / xr) ** SPREAD_EXPONENT
    u = own / scale  # the spreads at the reference's size
    var, _, df, member, _ = pool_arrays(u[:, None], u, dof, SCREEN_LEVEL)
    # never below a size's own spread: the scaling is an assumption, and a size that
    # scatters more than it predicts keeps what it shows
    var_of_mean = np.maximum(var[:, 0] * scale, own) / counts
    sources = [(float(df[member][0]), np.flatnonzero(member))] if member.any() else []
    sources += [(float(dof[i]), np.array([i])) for i in np.flatnonzero(~member)]
    return _Noise(var_of_mean, sources)


def _combination(lam: np.ndarray, means: np.ndarray, noise: _Noise, q: float):
    """Value, interval at two-sided level ``q`` and dof of sum(lam * means)."""
    value = float(lam @ means)
    parts = lam**2 * noise.var_of_mean
    v = float(parts.sum())
    df = noise.df(parts)
    h = t_quantile(0.5 + 0.5 * q, df) * math.sqrt(v) if v > 0 else 0.0
    return value, value - h, value + h, df


def fit_curve(sizes: list[dict], confidence: float, pooled: bool = False) -> dict | None:
    """The line of log property against d / L through ``sizes`` (each: ``x`` = d / L,
    ``logs`` the seeds' log values, ``reference`` True for the references' size), with the
    bulk value and the reference's distance from it at two-sided level ``confidence``, each
    size's spread its own or (``pooled``) pooled over the sizes (:func:`size_noise`); None
    with fewer than two sizes or a size of one seed."""
    if len(sizes) < 2 or any(len(s["logs"]) < 2 for s in sizes):
        return None
    x = np.array([s["x"] for s in sizes])
    means = np.array([np.mean(s["logs"]) for s in sizes])
    counts = np.array([len(s["logs"]) for s in sizes])
    noise = size_noise(sizes, pooled)
    design = np.column_stack([np.ones_like(x), x])
    lam = np.linalg.pinv(design)  # rows: intercept and slope as combinations of the means
    a, a_lo, a_hi, a_df = _combination(lam[0], means, noise, confidence)
    b, b_lo, b_hi, b_df = _combination(lam[1], means, noise, confidence)
    ref = next(s for s in sizes if s["reference"])
    xr = ref["x"]
    off, off_lo, off_hi, off_df = _combination(xr * lam[1], means, noise, confidence)
    fitted = a + b * x
    lack, limit = linearity(design, means, noise)
    return {
        "bulk": math.exp(a),
        "bulk_interval": [math.exp(a_lo), math.exp(a_hi)],
        "bulk_df": a_df,
        "slope": b,
        "slope_interval": [b_lo, b_hi],
        "slope_df": b_df,
        "reference_offset": math.expm1(off),
        "reference_offset_interval": [math.expm1(off_lo), math.expm1(off_hi)],
        "reference_offset_df": off_df,
        "reference_diameters_across": 1.0 / xr,
        "lack_of_fit": lack,
        "lack_of_fit_limit": limit,
        "linear": None if lack is None else bool(lack <= limit),
        "left_out": [],
        "pooled": bool(pooled),
        "pooled_sizes": [
            float(1.0 / x[i]) for d, idx in noise.sources if len(idx) > 1 for i in idx
        ],
        "sizes": [
            {
                "diameters_across": 1.0 / s["x"],
                "d_over_L": s["x"],
                "reference": s["reference"],
                "seeds": int(n),
                "mean": float(math.exp(m)),
                "fitted": float(math.exp(f)),
                "offset_from_bulk": math.expm1(float(f - a)),
            }
            for s, n, m, f in zip(sizes, counts, means, fitted)
        ],
    }


def linearity(design: np.ndarray, means, noise) -> tuple:
    r"""How far the size means lie from the fitted line: the largest standardised residual
    :math:`\max_g |r_g| / \hat\sigma(r_g)` and the limit it is held to, or (None, None)
    with fewer than three sizes (the line goes through two).

    The residuals are :math:`r = (I - H)\,\bar y` with :math:`H` the least-squares hat
    matrix, so :math:`\mathrm{var}(r_g) = \sum_h (I - H)_{gh}^2\, s_h^2 / n_h`, estimated
    from the seeds' spreads; each standardised residual is held to Student's t at
    :math:`1 - \alpha / (2 G)` (:data:`LINEARITY_ALPHA`, Bonferroni over the G sizes), on
    the degrees of freedom of the size means' variance sources (``noise``, from
    :func:`size_noise`; :func:`contrast_df` on each size's own spread). A property linear
    in d / L is called not linear at most :data:`LINEARITY_ALPHA` of the time (simulated in
    tests/engine/test_resolution.py); with three seeds a size the check sees only large
    departures, which is what three seeds can tell."""
    means = np.asarray(means, dtype=float)
    var_of_mean = noise.var_of_mean
    g = len(means)
    if g < 3:
        return None, None
    m = np.eye(g) - design @ np.linalg.pinv(design)
    r = m @ means
    worst, limit = 0.0, 0.0
    for i in range(g):
        parts = m[i] ** 2 * var_of_mean
        v = float(parts.sum())
        df = noise.df(parts)
        q = t_quantile(1.0 - LINEARITY_ALPHA / (2 * g), df) if math.isfinite(df) else None
        if v > 0:
            z = abs(float(r[i])) / math.sqrt(v)
            if z >= worst:
                worst, limit = z, q
        elif abs(float(r[i])) > 1e-12:
            return math.inf, q if q is not None else 0.0
    if limit == 0.0:  # no residual carries noise and every one is zero
        fewest = min(d for d, _ in noise.sources)
        limit = t_quantile(1.0 - LINEARITY_ALPHA / (2 * g), float(fewest))
    return worst, limit


def asymptotic_curve(sizes: list[dict], confidence: float, pooled: bool = False) -> dict | None:
    """:func:`fit_curve` over the sizes where the leading term, linear in d / L, holds: while
    the means lie off the line (:func:`linearity`), the smallest sample is left out, as long
    as :data:`MIN_SIZES` sizes and the references' size remain. Samples a few diameters
    across leave the asymptotic regime (a column that buckles or collapses after its
    release, a wall layer that is most of the sample); the fit then answers only for the
    sizes it kept (``left_out`` lists the others, in diameters across), and a curve still off
    its line keeps ``linear`` False. ``pooled``: as in :func:`fit_curve`."""
    kept = sorted(sizes, key=lambda s: s["x"])
    curve = fit_curve(kept, confidence, pooled)
    left_out = []
    while (
        curve is not None
        and curve["linear"] is False
        and len(kept) > MIN_SIZES
        and not kept[-1]["reference"]
    ):
        left_out.append(1.0 / kept[-1]["x"])
        kept = kept[:-1]
        curve = fit_curve(kept, confidence, pooled)
    if curve is not None:
        curve["left_out"] = left_out
    return curve


def diameters_needed(curve: dict, tolerance: float) -> dict:
    r"""The fewest diameters across a sample (or a feature: a shear band, an outlet, a wall
    layer) needs for a property to stay within ``tolerance`` (relative) of its bulk value,
    at the curve's confidence: on the line :math:`\log y = a + b\,x` the offset from the
    bulk at :math:`x = d / L` is :math:`e^{b x} - 1`, and its interval
    :math:`[e^{x b_{lo}} - 1, e^{x b_{hi}} - 1]` scales with x, so it stays inside
    :math:`\pm` tolerance up to

    .. math:: x_{max} = \min\left(\frac{\log(1 + tol)}{b_{hi}}\ (b_{hi} > 0),\;
              \frac{\log(1 - tol)}{b_{lo}}\ (b_{lo} < 0)\right),

    and the sample needs :math:`1 / x_{max}` diameters across. Only the measured sizes are
    trusted: a need below the coarsest size fitted is reported as at most that size
    (``bound`` "at_most"), one beyond the finest as more than it (``bound`` "more_than");
    a curve whose means lie off the line (``linear`` False, :func:`linearity`) gives
    none (``diameters`` None). ``bound95`` is 1 / x_max unclipped, ``point`` the same
    crossing on the fitted slope itself (:func:`point_need`): the point estimate."""
    b_lo, b_hi = curve["slope_interval"]
    point = point_need(curve["slope"], tolerance)
    limits = []
    if b_hi > 0:
        limits.append(math.log1p(tolerance) / b_hi)
    if b_lo < 0:
        limits.append(math.log1p(-tolerance) / b_lo)
    x_max = min(limits) if limits else math.inf
    across = [s["diameters_across"] for s in curve["sizes"]]
    fewest, most = min(across), max(across)
    need = 1.0 / x_max if x_max > 0 else math.inf
    if curve.get("linear") is False:
        return {"diameters": None, "bound": "not_linear", "tolerance": tolerance, "point": None}
    out = {"tolerance": tolerance, "point": point, "bound95": need}
    if need <= fewest:
        return {"diameters": fewest, "bound": "at_most", **out}
    if need > most:
        return {"diameters": most, "bound": "more_than", **out}
    return {"diameters": need, "bound": "needs", **out}


def point_need(slope: float, tolerance: float) -> float:
    """The diameters across at which the fitted line log y = a + ``slope`` d / L leaves
    +-``tolerance`` of the bulk: the point estimate of :func:`diameters_needed`'s bound
    (1 where the slope is 0 or the tolerance holds at d / L = 1) [-]."""
    if slope < 0:
        x = math.log1p(-tolerance) / slope
    elif slope > 0:
        x = math.log1p(tolerance) / slope
    else:
        return 1.0
    return max(1.0, 1.0 / x)


def point_words(point: float, coarsest: float, unit: str = "", digits: int = 3) -> str:
    """A need's point estimate [diameters across] in words, ``unit`` after the number: the
    number to ``digits`` significant digits, or, where it lies below ``coarsest`` (the
    coarsest size run), "below" that size (coarser is not measured): a line extrapolated
    to fewer diameters than were run is not a measurement (:func:`point_need` floors it
    at 1, not at the sizes run)."""
    if point < coarsest:
        return f"below {coarsest:.3g}{unit}, the coarsest size run"
    return f"{point:.{digits}g}{unit}"


def needed_words(needed: dict | None) -> str:
    """The clause of :func:`curve_lines` for :func:`diameters_needed`'s answer."""
    if not needed or needed["diameters"] is None:
        return ""
    tol, n = 100 * needed["tolerance"], needed["diameters"]
    if needed["bound"] == "at_most":
        return (
            f"; within {tol:g} % of the bulk down to {n:.1f} diameters across, the coarsest "
            "size run (fewer not measured)"
        )
    if needed["bound"] == "more_than":
        return (
            f"; needs more than {n:.1f} diameters across (the finest size run) to be within "
            f"{tol:g} % of the bulk"
        )
    return (
        f"; within {tol:g} % of the bulk from {n:.1f} diameters across: a feature L wide "
        f"takes particles up to L / {n:.1f} in diameter"
    )


def coarsest_diameter(curves: dict, tolerances: dict, feature_width: float) -> dict:
    """The coarsest particle diameter [m] that keeps every property of ``curves`` (from
    :func:`resolution_curves`) within its tolerance in ``tolerances`` across a feature
    ``feature_width`` [m] wide: the feature width over the most diameters any property
    needs (:func:`diameters_needed`). ``diameters`` is that need, ``limited_by`` the
    property that sets it, ``bound`` as in :func:`diameters_needed` ("more_than": the
    finest size run is not enough for that property, so the diameter is an upper bound;
    "at_most": every property holds down to the coarsest size run, so the diameter is a
    lower bound of the coarsest allowed); None where no property has a curve.

    A property off its line (bound "not_linear") has no need of its own, so it leaves the
    answer undecided, except where another property already needs more than the finest
    size run: that upper bound on the diameter holds whatever the unresolved property needs
    (it could only make the particle finer still), and ``unresolved`` names the properties
    it leaves out."""
    needs = {
        n: diameters_needed(c, tolerances[n])
        for n, c in curves.get("metrics", {}).items()
        if n in tolerances
    }
    if not needs:
        return {"diameter": None, "diameters": None, "limited_by": None, "bound": None}
    unresolved = [n for n, v in needs.items() if v["diameters"] is None]
    beyond = [n for n, v in needs.items() if v["bound"] == "more_than"]
    if unresolved and not beyond:
        return {
            "diameter": None,
            "diameters": None,
            "limited_by": unresolved[0],
            "bound": "not_linear",
            "unresolved": unresolved,
            "per_metric": needs,
        }
    known = {n: v for n, v in needs.items() if v["diameters"] is not None}
    name = max(known, key=lambda n: (known[n]["bound"] == "more_than", known[n]["diameters"]))
    need = known[name]
    return {
        "diameter": feature_width / need["diameters"],
        "diameters": need["diameters"],
        "limited_by": name,
        "bound": need["bound"],
        "unresolved": unresolved,
        "per_metric": needs,
    }


def resolution_curves(
    reference: list[tuple[float, dict]],
    controls: dict[float, list[tuple[float, dict]]],
    names,
    confidence: float,
    pooled: bool = False,
) -> dict:
    """Per metric in ``names`` the fitted resolution curve (:func:`fit_curve`) from the
    reference runs and the controls of each coarse radius, each given as
    (diameters across, metric values) per run; metrics with a non-positive value are left
    out (no logarithm); ``pooled``: as in :func:`fit_curve`. Returns {"metrics": {name:
    curve}, "confidence": confidence}."""
    groups = [(True, reference)] + [(False, runs) for _, runs in sorted(controls.items())]
    out = {}
    for n in names:
        sizes = []
        for is_ref, runs in groups:
            vals = [float(np.mean(v[n])) for _, v in runs]
            if not runs or min(vals) <= 0:
                sizes = None
                break
            across = float(np.mean([d for d, _ in runs]))
            sizes.append({"x": 1.0 / across, "logs": np.log(vals), "reference": is_ref})
        curve = asymptotic_curve(sizes, confidence, pooled) if sizes else None
        if curve is not None:
            out[n] = curve
    return {"metrics": out, "confidence": confidence}


def curve_lines(curves: dict) -> list[str]:
    """The report's lines on the resolution curve: per property the bulk value's
    extrapolation and how far the reference itself is from it."""
    lines = []
    conf = curves.get("confidence", 0.95)
    for n, c in curves.get("metrics", {}).items():
        lo, hi = c["reference_offset_interval"]
        sizes = ", ".join(f"{s['diameters_across']:.1f}" for s in c["sizes"])
        fit = ""
        if c.get("left_out"):
            fit += (
                "; left out: "
                + ", ".join(f"{d:.1f}" for d in c["left_out"])
                + " diameters across, off the line with the larger sizes"
            )
        if c["lack_of_fit"] is not None:
            fit += (
                f"; the size means lie within {c['lack_of_fit']:.1f} standard errors of the "
                f"line (limit {c['lack_of_fit_limit']:.1f})"
            )
            if c["linear"] is False:
                fit += (
                    ": the property is not linear in d / L over these sizes, and the "
                    "extrapolation is not to be trusted"
                )
        lines.append(
            f"resolution curve, {n}: the reference ({c['reference_diameters_across']:.1f} "
            f"diameters across) is {_pct(c['reference_offset'])} "
            f"{interval_words((lo, hi))} ({conf:.0%}) from the bulk value "
            f"extrapolated linearly in d / L to d / L = 0 (sizes {sizes} diameters across{fit})"
            + needed_words(c.get("needed"))
        )
    return lines


__all__ = [
    "asymptotic_curve",
    "coarsest_diameter",
    "contrast_df",
    "curve_lines",
    "diameters_needed",
    "fit_curve",
    "linearity",
    "needed_words",
    "point_words",
    "resolution_curves",
    "size_noise",
    "sources_df",
]
