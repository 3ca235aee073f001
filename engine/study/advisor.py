r"""From metric values to verdicts (docs/PHYSICS.md section 7).

For every verdict metric (:data:`engine.study.metrics.METRICS`), with the reference seeds' values
:math:`r_i` and a coarse variant's seeds' values :math:`c_j` (per stress level for density
and coordination):

- the **reference** is the mean of the reference seeds' values; its **noise floor** is their
  seed-to-seed spread (sample standard deviation) relative to the mean;
- the variant's relative error at a level is :math:`\rho - 1` with the ratio of means
  :math:`\rho = \mu_c / \mu_r` (for the strength of a reference weaker than 5 % of the
  consolidation stress: the difference over that floor); its interval is Fieller's for
  the ratio with min(n_c, n_r) - 1 degrees of freedom (Hsu: it holds for any two spreads, where
  Welch-Satterthwaite does not with two seeds on a side) and a Student-t quantile
  (:mod:`engine.study.intervals`): it holds for the seeds actually run, 2 or more on each side,
  spreads not assumed equal;
- the verdict is two one-sided tests (TOST) at error rate :math:`\alpha = 1 -`
  confidence (default 95 %): ``equivalent`` when, at every level, the interval at
  one-sided rate :math:`\alpha` lies inside ± tolerance (an intersection-union test: a
  variant whose true error exceeds the tolerance at any level is called equivalent in at
  most :math:`\alpha` of studies); ``differs`` when the interval of the level-summed ratio
  (for a curve; the value itself for a scalar metric) lies wholly outside ± tolerance at
  rate :math:`\alpha / 2M` per end over the :math:`M` metrics judged (Bonferroni over the
  metrics and the two ends, either of which may clear its bound: a variant inside the
  tolerance in every metric is called different in at most :math:`\alpha` of studies; the
  summed ratio is a weighted mean of the level ratios, positive reference values assumed,
  so it is outside the tolerance only if some level is); else ``undecided``;
- a study that adds seeds until decided looks at the data up to ``looks`` times; each look
  spends :math:`\alpha /` looks (Bonferroni over looks). The bound is proven for seed
  counts fixed in advance; the adaptive rule chooses them from the observed spreads
  (sample-size re-estimation, for which Bonferroni is not a proof), so its rates are shown
  by simulation (tests/engine/test_coverage.py);
- with fewer than two reference seeds, or fewer than two seeds of the variant, a spread is
  unknown and the metric is ``undecided``.

A (radius, rule) ``differs`` when any metric differs, is ``equivalent`` when all are, and is
``undecided`` otherwise; its reason says which metrics decided, with their intervals, and
an undecided metric says how many more seeds would decide it if the means and spreads
stayed as observed. docs/PHYSICS.md section 7 states why; tests/engine/test_coverage.py
checks the rates by simulation.
"""

from __future__ import annotations

import math

import numpy as np

from ..uniaxial.spec import MIN_THICKNESS_DIAMETERS
from .intervals import fieller, fieller_from_stats, hsu_df, t_quantile, welch_interval
from .metrics import METRICS, STRENGTH_FLOOR, reference_scale, relative_error, signed_error

#: Default confidence of a verdict: 1 - the largest rate of a wrong ``equivalent`` or of a
#: wrong ``differs`` [-].
CONFIDENCE = 0.95

#: Most seeds a "would need" estimate looks for (beyond it: "more than" this).
MAX_SEEDS_NEEDED = 100

VERDICTS = ("equivalent", "differs", "undecided")


def error_rates(confidence: float, metrics_judged: int, looks: int = 1) -> tuple[float, float]:
    """One-sided error rates per end of the intervals of one metric's tests for a variant
    judged on ``metrics_judged`` metrics over ``looks`` looks (module docstring):
    equivalence alpha / looks; differs alpha / (2 looks metrics), since either end of its
    interval may clear its tolerance bound."""
    if not 0.5 < confidence < 1.0:
        raise ValueError(f"confidence {confidence} outside (0.5, 1)")
    alpha = 1.0 - confidence
    return alpha / looks, alpha / (2 * looks * max(metrics_judged, 1))


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


def relative_interval(
    c, r, alpha: float, floor: float | None = None
) -> tuple[float, float, float, float]:
    """Relative error of the mean of ``c`` against that of ``r`` (1-D samples, two or more
    values each) with its interval at one-sided rate ``alpha`` per end: (error, low, high,
    degrees of freedom). Fieller's interval of the ratio minus 1, or, with a constant
    ``floor`` scale, Welch's interval of the difference over it."""
    if floor is not None:
        d, lo, hi, df = welch_interval(np.asarray(c) / floor, np.asarray(r) / floor, alpha)
        return d, lo, hi, df
    rho, lo, hi, df = fieller(c, r, alpha)
    return rho - 1.0, lo - 1.0, hi - 1.0, df


def judge_metric(
    name: str,
    values: list[dict],
    ref: dict,
    tolerance: float,
    consolidation_stress: float,
    alpha_equivalent: float = 1 - CONFIDENCE,
    alpha_differs: float = 1 - CONFIDENCE,
) -> dict:
    """Error, interval and verdict of one metric of one (radius, rule) (module docstring).
    ``values``: the variant's metric values per seed; ``ref``: this metric's entry of
    :func:`noise_floor`; the two one-sided error rates as from :func:`error_rates`."""
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
    }
    if ref["seeds"] < 2 or len(a) < 2:
        out.update(verdict="undecided")
        return out
    r = ref["values"]
    levels = a.shape[1]
    floor = _floored(name, float(ref["mean"][0]), consolidation_stress) if levels == 1 else None
    per_level = [
        relative_interval(a[:, k], r[:, k], alpha_equivalent, floor) for k in range(levels)
    ]
    excess = [max(hi - tolerance, -tolerance - lo) for _, lo, hi, _ in per_level]
    k = int(np.argmax(excess))
    equivalent = excess[k] <= 0
    if levels == 1:
        dd = relative_interval(a[:, 0], r[:, 0], alpha_differs, floor)
    else:
        dd = relative_interval(a.sum(axis=1), r.sum(axis=1), alpha_differs)
    differs = dd[1] > tolerance or dd[2] < -tolerance
    sc = reference_scale(name, ref["mean"], consolidation_stress)
    u2 = (a.var(axis=0, ddof=1) / len(a) + r.var(axis=0, ddof=1) / len(r)) / sc**2
    out.update(
        interval=[per_level[k][1], per_level[k][2]],
        level=None if levels == 1 else k,
        level_error=per_level[k][0],
        df=per_level[k][3],
        differs_interval=[dd[1], dd[2]],
        differs_error=dd[0],
        uncertainty=float(np.sqrt(np.mean(u2))),
        verdict="differs" if differs else "equivalent" if equivalent else "undecided",
    )
    if out["verdict"] == "undecided":
        out["needs"] = seeds_needed(
            name, a, r, tolerance, consolidation_stress, alpha_equivalent, alpha_differs
        )
    return out


def _decides(
    c: np.ndarray,
    r: np.ndarray,
    n: int,
    m: int,
    tolerance: float,
    alpha_e: float,
    alpha_d: float,
    floor: float | None,
) -> bool:
    """Whether a metric would be decided with ``n`` coarse and ``m`` reference seeds if the
    means and spreads of the observed values ``c`` (seeds x levels) and ``r`` stayed as
    they are: the verdict's own intervals (Fieller per level for ``equivalent``, of the
    per-seed level sums for ``differs``; Welch over the floor for a floored strength) at the
    projected counts and their min(n, m) - 1 degrees of freedom."""
    df = hsu_df(n, m)
    te = t_quantile(1 - alpha_e, df)
    td = t_quantile(1 - alpha_d, df)
    cm, rm = c.mean(axis=0), r.mean(axis=0)
    cv, rv = c.var(axis=0, ddof=1) / n, r.var(axis=0, ddof=1) / m
    if floor is not None:
        d = float(cm[0] - rm[0]) / floor
        u = math.sqrt(float(cv[0] + rv[0])) / floor
        return abs(d) + te * u <= tolerance or abs(d) - td * u > tolerance
    inside = True
    for k in range(len(cm)):
        _, lo, hi = fieller_from_stats(float(cm[k]), float(rm[k]), float(cv[k]), float(rv[k]), te)
        if not (lo - 1.0 >= -tolerance and hi - 1.0 <= tolerance):
            inside = False
            break
    if inside:
        return True
    cs, rs = c.sum(axis=1), r.sum(axis=1)  # the level sums vary together within a seed
    _, lo, hi = fieller_from_stats(
        float(cs.mean()), float(rs.mean()), float(cs.var(ddof=1)) / n, float(rs.var(ddof=1)) / m, td
    )
    return lo - 1.0 > tolerance or hi - 1.0 < -tolerance


def seeds_needed(
    name: str,
    c: np.ndarray,
    r: np.ndarray,
    tolerance: float,
    consolidation_stress: float,
    alpha_e: float,
    alpha_d: float,
) -> dict:
    """How many more seeds would decide an undecided metric if its means and spreads stayed
    as observed: ``coarse`` (more coarse seeds, reference seeds as they are), or
    ``coarse_and_reference`` (the same number more of each) where coarse seeds alone cannot,
    each None when more than :data:`MAX_SEEDS_NEEDED` would be needed (an error that sits
    at the tolerance is decided by no seed count)."""
    floor = (
        _floored(name, float(r.mean(axis=0)[0]), consolidation_stress)
        if (c.shape[1] == 1)
        else None
    )
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

    coarse = first(lambda k: _decides(c, r, n0 + k, m0, tolerance, alpha_e, alpha_d, floor))
    both = (
        None
        if coarse is not None
        else first(lambda k: _decides(c, r, n0 + k, m0 + k, tolerance, alpha_e, alpha_d, floor))
    )
    return {"coarse": coarse, "coarse_and_reference": both}


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
    text = (
        f"{m['metric']} {_pct(m['level_error'])}{at} in [{_pct(lo)}, {_pct(hi)}] "
        f"({conf:.1%} one-sided per end, {m['df']:.1f} dof) against {tol}"
    )
    need = m.get("needs")
    if need is not None:
        if need["coarse"] is not None:
            text += f"; about {need['coarse']} more coarse seeds would decide it"
        elif need["coarse_and_reference"] is not None:
            text += (
                f"; about {need['coarse_and_reference']} more coarse and reference "
                "seeds each would decide it"
            )
        else:
            text += f"; more than {MAX_SEEDS_NEEDED} more seeds would be needed"
    return text


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


#: The finite-size effect measured by the control of docs/VALIDATION.md (experiment (b) at
#: the paper scale, benchmarks/finite_size.py): the 2.5 mm reference law in a bed 5
#: diameters thick against 10, 3 seeds each: relative change [-] and its two-sided 95 %
#: Fieller interval (tests/engine/test_verdicts.py recomputes them from the stored runs).
MEASURED_FINITE_SIZE = {
    "thickness_diameters": 5.0,
    "against_diameters": 10.0,
    "strength": (-0.172, -0.247, -0.088),
    "loading_stiffness": (-0.165, -0.275, -0.052),
}


def finite_size_warnings(groups: list[dict]) -> list[str]:
    """Warnings for radii whose cell is under 10 particle diameters thick, citing the
    finite-size effect measured at 5 diameters (:data:`MEASURED_FINITE_SIZE`), and under
    :data:`MIN_THICKNESS_DIAMETERS`, below the measured range."""
    m = MEASURED_FINITE_SIZE
    s, k = m["strength"], m["loading_stiffness"]
    measured = (
        f"a bed {m['thickness_diameters']:g} diameters thick of the 2.5 mm reference "
        f"law measured {s[0]:+.0%} in unconfined strength (95 % interval "
        f"{s[1]:+.0%} to {s[2]:+.0%}) and {k[0]:+.0%} in loading stiffness "
        f"({k[1]:+.0%} to {k[2]:+.0%}) against {m['against_diameters']:g} "
        "diameters, density, unloading stiffness and coordination within tolerance "
        "(finite-size control, docs/VALIDATION.md)"
    )
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
                "needs (Thakur et al. 2013) and thinner than any bed whose finite-size "
                f"effect was measured ({measured}): wall and periodic-image effects "
                "may dominate"
            )
        elif t < m["against_diameters"]:
            out.append(
                f"R = {g['radius'] * 1e3:g} mm: the cell is {t:.1f} particle "
                f"diameters thick; {measured}: part of this radius's error may be "
                "the bed's size, not the scaling rule"
            )
    return out


def advise(
    spec, groups: list[dict], verdicts: list[dict], reference_strength: float | None
) -> dict:
    """The advisor: per rule the coarsest radius judged ``equivalent``; the verdicts; the
    finite-size warnings; the best-fitting adhesion exponent per radius."""
    rules = {}
    for rule in spec.rules:
        ok = [v for v in verdicts if v["rule"] == rule.name and v["verdict"] == "equivalent"]
        best = max(ok, key=lambda v: v["radius"]) if ok else None
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
            "speedup": g["speedup"] if g else None,
            "radii_equivalent": sorted(v["radius"] for v in ok),
        }
    lines = []
    for v in verdicts:
        lines.append(f"R = {v['radius'] * 1e3:g} mm, {v['rule']}: {v['verdict']}")
    for name, a in rules.items():
        if a["coarsest_radius"] is not None:
            lines.append(
                f"{name}: equivalent up to R = {a['coarsest_radius'] * 1e3:g} mm "
                f"({a['speedup']:.1f}x faster)"
            )
    warnings = finite_size_warnings(groups)
    adhesion = adhesion_advice(spec, groups, reference_strength)
    if adhesion:
        for r, v in adhesion["by_radius"].items():
            fit = f", fitted b = {v['fitted']:.2f}" if v.get("fitted") is not None else ""
            lines.append(
                f"adhesion exponent at R = {float(r) * 1e3:g} mm: closest b = {v['best']:g}{fit}"
            )
    return {
        "tolerances": dict(spec.tolerances),
        "confidence": getattr(spec, "confidence", CONFIDENCE),
        "rules": rules,
        "verdicts": verdicts,
        "warnings": warnings,
        "adhesion_exponent": adhesion,
        "message": "; ".join(lines + warnings),
    }


def adhesion_advice(spec, groups: list[dict], reference_strength: float | None) -> dict | None:
    """When rules differ only in their adhesion exponent: per radius the exponent whose
    strength is closest to the reference's, and the fitted one, solving
    log(strength(b)) = log(reference strength) on the least-squares line of log strength
    against b (omitted with fewer than two positive strengths)."""
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
        by_radius[f"{r:g}"] = entry
    return {"stiffness_exponent": a, "dt": dt, "by_radius": by_radius} if by_radius else None


def judge_groups(
    spec, ref_values: list[dict], variants: dict[tuple, list[dict]], names, looks: int = 1
) -> tuple[dict, list[dict]]:
    """Noise floor and verdicts: ``ref_values`` per reference seed, ``variants`` maps
    (radius, rule name) to the metric values of its seeds; ``looks``: how many times a
    study may judge its data (1 for a fixed study). Returns (noise floor per metric as
    JSON-friendly numbers, verdicts list)."""
    cons = spec.reference.consolidation_stress
    floor = noise_floor(ref_values, names, cons)
    alpha_e, alpha_d = error_rates(getattr(spec, "confidence", CONFIDENCE), len(names), looks)
    out = []
    for (radius, rule), values in variants.items():
        per_metric = [
            judge_metric(n, values, floor[n], spec.tolerances[n], cons, alpha_e, alpha_d)
            for n in names
        ]
        v, reason = verdict(per_metric)
        out.append(
            {
                "radius": radius,
                "rule": rule,
                "verdict": v,
                "reason": reason,
                "seeds": len(values),
                "metrics": per_metric,
            }
        )
    noise = {n: floor[n]["noise"] for n in names}
    return noise, out


__all__ = [
    "CONFIDENCE",
    "MEASURED_FINITE_SIZE",
    "METRICS",
    "VERDICTS",
    "adhesion_advice",
    "advise",
    "error_rates",
    "finite_size_warnings",
    "judge_groups",
    "judge_metric",
    "noise_floor",
    "relative_interval",
    "seeds_needed",
    "verdict",
]
