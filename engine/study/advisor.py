r"""The advisor: what a study's verdicts mean for a user (docs/PHYSICS.md section 7).

Input: the verdicts (engine.study.judge) of every (radius, rule), the rule errors and
resolution errors of the controls, the groups' summaries. Output: per rule the coarsest
radius judged ``equivalent`` in a fixed sequence (so that the stated confidence holds for
the radius a user acts on), the lines of advice with each verdict's reason, the
finite-size warnings, the best-fitting adhesion exponent per radius. The statistics
themselves (pooling, intervals, verdicts, seed projections) live in engine.study.pooling,
engine.study.noise and engine.study.judge; their names are importable from here as
before.
"""

from __future__ import annotations

import math

import numpy as np

from ..uniaxial.spec import MIN_THICKNESS_DIAMETERS
from .intervals import t_quantile
from .judge import (
    CONFIDENCE,
    EQUIVALENCE_LEVEL,
    MAX_SEEDS_NEEDED,
    PAIRING_VARIANCE_RATIO,
    PILOT_SHARE,
    PLANNED_POWER,
    VERDICTS,
    error_rates,
    judge_groups,
    judge_metric,
    judge_rule_error,
    judge_samples,
    look_alpha,
    pairing_pays,
    seeds_needed,
    verdict,
    what_decides,
)
from .kinds import kind_of
from .metrics import METRICS
from .noise import noise_floor
from .reasons import _pct, interval_words


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
        if m.get("signed_error") is None:
            return f"{m['metric']} not compared (no failed run on a side)"
        return f"{m['metric']} {_pct(m['signed_error'])}"
    pairs = " (paired)" if m.get("paired") else ""
    return f"{m['metric']} {_pct(m['level_error'])} {interval_words((lo, hi))}{pairs}"


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
    """The advisor's lines on the controls: per rule and radius whether a coarse run agrees
    with its control (for a rule that is the law's exact similarity, a check of units that
    cannot test the rule), and per radius what a sample that many diameters across loses
    against the reference."""
    lines = []
    law = spec.reference.pair_law
    similarity = getattr(law, "similarity_exponents", None)
    exact = (
        {rule.name for rule in spec.rules if tuple(rule.exponents(law)) == tuple(similarity())}
        if rule_errors and similarity is not None
        else set()
    )
    for v in rule_errors:
        says = {"equivalent": "agrees", "differs": "differs", "undecided": "is undecided"}
        parts = "; ".join(_interval_words(m) for m in v["metrics"])
        text = (
            f"{v['rule']} at R = {v['radius'] * 1e3:g} mm against its resolution control: "
            f"{says[v['verdict']]} ({parts})"
        )
        if v["rule"] in exact:
            # docs/PHYSICS.md section 5.1: for this law the coarse run is its control in
            # other units, so the comparison can only see what the rule leaves unscaled
            fixed = kind_of(spec.reference).clock_constants
            text += (
                "; a check of units, not evidence for the rule: for this law the rule is an "
                "exact similarity (the coarse run is its control in other units), so this "
                f"compares only {fixed}"
            )
        lines.append(text)
    for v in resolution:
        d = v.get("diameters_across")
        across = f"{d:.1f} diameters across" if d else "the coarse cell's size in diameters"
        parts = "; ".join(_interval_words(m) for m in v["metrics"])
        lines.append(
            f"resolution at R = {v['radius'] * 1e3:g} mm: the reference law in a sample "
            f"{across} against the reference: {v['verdict']} ({parts}); the size effect of "
            "this test's sample at that many diameters across (other features, a free "
            "surface, a shear band, an outlet, need their own numbers: docs/RESOLUTION.md)"
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
                if strengths is not None:
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


def answer_lines(advisor: dict, reference_radius: float | None) -> list[str]:
    """The study's answer in one line (per rule, the coarsest radius equivalent on every
    metric, as a factor over the reference radius ``reference_radius`` [m], and its
    speed-up), then one line that says how it relates to what was run: the next radius's
    verdict, and that this is the answer for the study's cell, not for a process's feature
    (``demscale plan``)."""
    parts, beyond = [], []
    for name, a in (advisor.get("rules") or {}).items():
        r = a.get("coarsest_radius")
        if r is None:
            stop = a.get("sequence_stopped_at")
            why = "" if stop is None else f" (R = {stop['radius'] * 1e3:g} mm {stop['verdict']})"
            parts.append(f"{name}: no coarse radius shown equivalent{why}")
            continue
        factor = f", {r / reference_radius:.3g}x coarser" if reference_radius else ""
        speed = f", {a['speedup']:.2g}x faster" if a.get("speedup") else ""
        parts.append(f"{name}: equivalent on every metric up to R = {r * 1e3:g} mm{factor}{speed}")
        stop = a.get("sequence_stopped_at")
        if stop is not None:
            beyond.append(f"R = {stop['radius'] * 1e3:g} mm is {stop['verdict']} for {name}")
    if not parts:
        return ["Answer: no rule was judged"]
    lines = ["Answer: " + "; ".join(parts)]
    qualify = (
        "This is the answer for the study's own cell, each coarse run judged against the fine "
        "reference in it; how coarse a process's feature allows is `demscale plan`'s answer."
    )
    if beyond:
        qualify = f"Beyond it {'; '.join(beyond)} (next radius tested). " + qualify
    return [*lines, qualify]


def verdict_line(v: dict) -> str:
    """One short line per verdict: the radius, the rule, the verdict and the metrics that
    make it (those that differ, or those still undecided, with their errors)."""
    head = f"R = {v['radius'] * 1e3:g} mm, {v['rule']}: {v['verdict'].upper()}"
    ms = v.get("metrics") or []
    if v["verdict"] == "equivalent":
        return f"{head}, every metric within its tolerance"
    which = [m for m in ms if m.get("verdict") == v["verdict"]] or ms
    words = []
    for m in which:
        err = m.get("level_error", m.get("signed_error"))
        iv = m.get("differs_interval") if v["verdict"] == "differs" else m.get("interval")
        tol = m.get("tolerance")
        text = f"{m['metric']} {_pct(err)}" if err is not None else m["metric"]
        if iv is not None:
            text += f" {interval_words(iv)}"
        if tol:
            text += f" against +-{100 * tol:g} %"
        words.append(text)
    return f"{head} on " + "; ".join(words)


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
    (``variants``: (radius, rule) -> the seeds' strengths; ``reference``) the fit is
    :func:`fit_exponent` with its interval, against the references only: the exponent
    that makes a coarse run match the fine law in the user's own cell. (Against a
    radius's resolution controls the fit would test nothing: for the bilinear law b = 2 is
    an exact similarity, so a coarse run under it is its control in other units,
    docs/PHYSICS.md section 5.1.) ``fitted_against`` is "reference" where there is a fit."""
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
            if ref_fit is not None:
                entry.update(
                    fitted=ref_fit[0],
                    interval=ref_fit[1],
                    fitted_against="reference",
                    fitted_reference=ref_fit[0],
                    fitted_reference_interval=ref_fit[1],
                )
        by_radius[f"{r:g}"] = entry
    return {"stiffness_exponent": a, "dt": dt, "by_radius": by_radius} if by_radius else None


__all__ = [
    "CONFIDENCE",
    "EQUIVALENCE_LEVEL",
    "MAX_SEEDS_NEEDED",
    "METRICS",
    "PAIRING_VARIANCE_RATIO",
    "PILOT_SHARE",
    "PLANNED_POWER",
    "VERDICTS",
    "adhesion_advice",
    "advise",
    "answer_lines",
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
    "side_by_side",
    "verdict",
    "verdict_line",
    "what_decides",
]


def side_by_side(verdicts: dict[str, list[dict]]) -> list[dict]:
    """One rule judged on several tests (docs/PHYSICS.md section 11.1): ``verdicts`` maps a
    test's name (``"uniaxial"``, ``"shear"``) to its study's verdicts (``advisor
    ["verdicts"]``, studies with the same rules and radii: engine.study.spec.on_test).
    Returns per (radius, rule) its verdict on each test and the combined one:
    ``equivalent`` where every test's is (an intersection-union test, at each study's
    confidence with no correction), ``differs`` where any test's is (a wrong ``differs``
    on some test has up to the sum of the studies' rates), else ``undecided``; a test
    without the variant counts as ``undecided`` ("not run")."""
    keys = sorted({(v["radius"], v["rule"]) for vs in verdicts.values() for v in vs})
    out = []
    for radius, rule in keys:
        per = {}
        for test, vs in verdicts.items():
            v = next((v for v in vs if (v["radius"], v["rule"]) == (radius, rule)), None)
            per[test] = "not run" if v is None else v["verdict"]
        if all(x == "equivalent" for x in per.values()):
            both = "equivalent"
        elif any(x == "differs" for x in per.values()):
            both = "differs"
        else:
            both = "undecided"
        out.append({"radius": radius, "rule": rule, "tests": per, "verdict": both})
    return out
