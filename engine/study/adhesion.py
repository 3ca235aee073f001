r"""The adhesion exponent a study's coarse runs point to (docs/PHYSICS.md section 7): where
rules differ only in their adhesion exponent b, per coarse radius the b whose strength is
closest to the reference's and the b fitted to it, with Fieller's interval
(:func:`fit_exponent`). Part of the study's report (engine.study.report.AdhesionFit)."""

from __future__ import annotations

import math

import numpy as np

from .intervals import t_quantile
from .rates import CONFIDENCE
from .report import AdhesionAtRadius, AdhesionFit


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
) -> AdhesionFit | None:
    """When rules differ only in their adhesion exponent: per radius the exponent whose
    strength is closest to the reference's, and the fitted one, solving
    log(strength(b)) = log(target strength) on the least-squares line of log strength
    against b (omitted with fewer than two positive strengths). With ``strengths``
    (``variants``: (radius, rule) -> the seeds' strengths; ``reference``) the fit is
    :func:`fit_exponent` with its interval, against the references only: the exponent
    that makes a coarse run match the fine law in the user's own cell. (Against a
    radius's resolution controls the fit would test nothing: for the bilinear law b = 2 is
    an exact similarity, so a coarse run under it is its control in other units,
    docs/PHYSICS.md section 5.1.) ``fitted_against`` is "reference" where there is a fit.
    None where the study is not unconfined or its rules are not such a family."""
    if not getattr(spec.reference, "unconfined", False):
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
        fitted = None
        pts = [
            (g["adhesion_exponent"], g["unconfined_strength"])
            for g in gs
            if g.get("unconfined_strength", 0.0) > 0
        ]
        if reference_strength and reference_strength > 0 and len({b for b, _ in pts}) >= 2:
            b, strength = np.array(pts).T
            slope, icept = np.polyfit(b, np.log(strength), 1)
            if slope > 0:
                fitted = float((math.log(reference_strength) - icept) / slope)
        entry = AdhesionAtRadius(
            best=best["adhesion_exponent"],
            err_strength=best["err_strength"],
            fitted=fitted,
            fitted_against="reference" if fitted is not None else None,
            fitted_reference=fitted,
            interval=None,
        )
        if strengths is not None:
            by_b = {
                g["adhesion_exponent"]: strengths["variants"].get((r, g["rule"]), []) for g in gs
            }
            conf = getattr(spec, "confidence", CONFIDENCE)
            ref_fit = fit_exponent(by_b, strengths.get("reference") or [], conf)
            if ref_fit is not None:
                entry = AdhesionAtRadius(
                    best=entry.best,
                    err_strength=entry.err_strength,
                    fitted=ref_fit[0],
                    fitted_against="reference",
                    fitted_reference=ref_fit[0],
                    interval=None if ref_fit[1] is None else tuple(ref_fit[1]),
                    fieller=True,
                )
        by_radius[f"{r:g}"] = entry
    return AdhesionFit(a, dt, by_radius) if by_radius else None
