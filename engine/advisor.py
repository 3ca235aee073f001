r"""From metric values to verdicts (docs/PHYSICS.md section 7).

For every verdict metric (:data:`engine.metrics.METRICS`):

- the **reference** is the mean of the reference seeds' values; its **noise floor** is their
  seed-to-seed spread (sample standard deviation) relative to the mean: how much one fine run
  differs from another with nothing changed but the packing;
- a coarse variant (radius, rule) has the **error** of its seeds' mean values against the
  reference (relative RMS over the stress levels), and the **uncertainty** of that error,
  :math:`u = \sqrt{s_r^2/n_r + s_c^2/n_c}` relative to the reference, from the reference
  spread :math:`s_r` over :math:`n_r` seeds and the variant's spread :math:`s_c` over its
  :math:`n_c` seeds (with a single coarse seed, :math:`s_c` is taken as :math:`s_r`);
- the verdict on the metric, with the expanded uncertainty :math:`U = 2u` (about 95 %
  coverage, the metrology convention): ``equivalent`` when :math:`e + U \le` tolerance,
  ``differs`` when :math:`e - U >` tolerance, else ``undecided`` (noise too large to tell);
  with fewer than two reference seeds there is no noise floor and every verdict is
  ``undecided``.

A (radius, rule) ``differs`` when any metric differs, is ``equivalent`` when all are, and is
``undecided`` otherwise; its reason says which metrics decided, with numbers. These rules
were fixed before any study was judged by them.
"""

from __future__ import annotations

import math

import numpy as np

from .metrics import METRICS, reference_scale, relative_error, signed_error
from .uniaxial_spec import MIN_THICKNESS_DIAMETERS

#: Coverage factor of the expanded uncertainty (2: about 95 % for a normal error).
COVERAGE = 2.0

VERDICTS = ("equivalent", "differs", "undecided")


def _stack(values: list[dict], name: str) -> np.ndarray:
    return np.array([v[name] for v in values], dtype=float)


def noise_floor(ref_values: list[dict], names, consolidation_stress: float) -> dict:
    """Per metric, the reference mean values, spread (per level) and the relative noise
    floor [-] (RMS over levels of spread / scale); the floor is None with one seed."""
    out = {}
    for n in names:
        a = _stack(ref_values, n)
        mean = a.mean(axis=0)
        sd = a.std(axis=0, ddof=1) if len(a) > 1 else None
        scale = reference_scale(n, mean, consolidation_stress)
        floor = None if sd is None else float(np.sqrt(np.mean((sd / scale) ** 2)))
        out[n] = {"mean": mean, "sd": sd, "noise": floor, "seeds": len(a)}
    return out


def judge_metric(name: str, values: list[dict], ref: dict, tolerance: float,
                 consolidation_stress: float) -> dict:
    """Error, uncertainty and verdict of one metric of one (radius, rule) (module
    docstring). ``values``: the variant's metric values per seed; ``ref``: this metric's
    entry of :func:`noise_floor`."""
    a = _stack(values, name)
    mean = a.mean(axis=0)
    err = relative_error(name, mean, ref["mean"], consolidation_stress)
    signed = signed_error(name, mean, ref["mean"], consolidation_stress)
    out = {"metric": name, "error": err, "signed_error": signed, "tolerance": tolerance,
           "noise": ref["noise"], "seeds": len(a), "reference_seeds": ref["seeds"]}
    if ref["sd"] is None:
        out.update(uncertainty=None, verdict="undecided")
        return out
    sd_c = a.std(axis=0, ddof=1) if len(a) > 1 else ref["sd"]
    scale = reference_scale(name, ref["mean"], consolidation_stress)
    u2 = (ref["sd"] / scale) ** 2 / ref["seeds"] + (sd_c / scale) ** 2 / len(a)
    u = float(np.sqrt(np.mean(u2)))
    big_u = COVERAGE * u
    if err + big_u <= tolerance:
        verdict = "equivalent"
    elif err - big_u > tolerance:
        verdict = "differs"
    else:
        verdict = "undecided"
    out.update(uncertainty=u, verdict=verdict)
    return out


def _one_seed_note(metrics: list[dict]) -> str:
    if metrics and metrics[0].get("seeds") == 1:
        return ("; one seed of this variant: its spread is taken as the reference's, which "
                "understates it for a coarse bed of fewer particles; run two or more seeds")
    return ""


def _describe(m: dict) -> str:
    direction = "over" if m["signed_error"] > 0 else "under"
    u = "" if m["uncertainty"] is None else f" ± {COVERAGE * m['uncertainty']:.1%}"
    return (f"{m['metric']} {m['error']:.1%}{u} ({direction}) against tolerance "
            f"{m['tolerance']:.0%}")


def verdict(metrics: list[dict]) -> tuple[str, str]:
    """Overall verdict and its reason from the per-metric judgements."""
    if metrics and metrics[0]["reference_seeds"] < 2:
        return "undecided", ("one reference seed: the reference's own spread is unknown, so "
                             "no error can be told apart from noise; run two or more "
                             "reference seeds")
    differs = [m for m in metrics if m["verdict"] == "differs"]
    undecided = [m for m in metrics if m["verdict"] == "undecided"]
    note = _one_seed_note(metrics)
    if differs:
        return "differs", "differs beyond noise in " + "; ".join(
            _describe(m) for m in differs) + note
    if undecided:
        ok = [m["metric"] for m in metrics if m["verdict"] == "equivalent"]
        reason = "noise too large to tell for " + "; ".join(_describe(m) for m in undecided)
        if ok:
            reason += "; within tolerance: " + ", ".join(ok)
        return "undecided", reason + note
    return "equivalent", "within tolerance beyond noise: " + "; ".join(
        _describe(m) for m in metrics) + note


def finite_size_warnings(groups: list[dict]) -> list[str]:
    """Warnings for radii whose cell is under :data:`MIN_THICKNESS_DIAMETERS` diameters."""
    out, seen = [], set()
    for g in groups:
        if g["radius"] in seen:
            continue
        seen.add(g["radius"])
        t = g["thickness_diameters"]
        if t < MIN_THICKNESS_DIAMETERS:
            out.append(f"R = {g['radius'] * 1e3:g} mm: the cell is {t:.1f} particle "
                       f"diameters thick, under the {MIN_THICKNESS_DIAMETERS:g} a bulk sample "
                       "needs (Thakur et al. 2013): wall and periodic-image effects may "
                       "dominate")
    return out


def advise(spec, groups: list[dict], verdicts: list[dict],
           reference_strength: float | None) -> dict:
    """The advisor: per rule the coarsest radius judged ``equivalent``; the verdicts; the
    finite-size warnings; the best-fitting adhesion exponent per radius."""
    rules = {}
    for rule in spec.rules:
        ok = [v for v in verdicts if v["rule"] == rule.name and v["verdict"] == "equivalent"]
        best = max(ok, key=lambda v: v["radius"]) if ok else None
        g = next((g for g in groups if best and g["rule"] == rule.name
                  and g["radius"] == best["radius"]), None)
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
            lines.append(f"{name}: equivalent up to R = {a['coarsest_radius'] * 1e3:g} mm "
                         f"({a['speedup']:.1f}x faster)")
    warnings = finite_size_warnings(groups)
    adhesion = adhesion_advice(spec, groups, reference_strength)
    if adhesion:
        for r, v in adhesion["by_radius"].items():
            fit = f", fitted b = {v['fitted']:.2f}" if v.get("fitted") is not None else ""
            lines.append(f"adhesion exponent at R = {float(r) * 1e3:g} mm: closest b = "
                         f"{v['best']:g}{fit}")
    return {"tolerances": dict(spec.tolerances), "coverage": COVERAGE, "rules": rules,
            "verdicts": verdicts, "warnings": warnings, "adhesion_exponent": adhesion,
            "message": "; ".join(lines + warnings)}


def adhesion_advice(spec, groups: list[dict], reference_strength: float | None
                    ) -> dict | None:
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
        gs = [g for g in groups if g["radius"] == r and g["stiffness_exponent"] == a
              and g["dt"] == dt and "err_strength" in g]
        if not gs:
            continue
        best = min(gs, key=lambda g: g["err_strength"])
        entry = {"best": best["adhesion_exponent"], "err_strength": best["err_strength"],
                 "fitted": None}
        pts = [(g["adhesion_exponent"], g["unconfined_strength"]) for g in gs
               if g.get("unconfined_strength", 0.0) > 0]
        if reference_strength and reference_strength > 0 and len({b for b, _ in pts}) >= 2:
            b, strength = np.array(pts).T
            slope, icept = np.polyfit(b, np.log(strength), 1)
            if slope > 0:
                entry["fitted"] = float((math.log(reference_strength) - icept) / slope)
        by_radius[f"{r:g}"] = entry
    return {"stiffness_exponent": a, "dt": dt, "by_radius": by_radius} if by_radius else None


def judge_groups(spec, ref_values: list[dict], variants: dict[tuple, list[dict]],
                 names) -> tuple[dict, list[dict]]:
    """Noise floor and verdicts: ``ref_values`` per reference seed, ``variants`` maps
    (radius, rule name) to the metric values of its seeds. Returns (noise floor per metric
    as JSON-friendly numbers, verdicts list)."""
    cons = spec.reference.consolidation_stress
    floor = noise_floor(ref_values, names, cons)
    out = []
    for (radius, rule), values in variants.items():
        per_metric = [judge_metric(n, values, floor[n], spec.tolerances[n], cons)
                      for n in names]
        v, reason = verdict(per_metric)
        out.append({"radius": radius, "rule": rule, "verdict": v, "reason": reason,
                    "seeds": len(values), "metrics": per_metric})
    noise = {n: floor[n]["noise"] for n in names}
    return noise, out


__all__ = ["COVERAGE", "METRICS", "VERDICTS", "adhesion_advice", "advise",
           "finite_size_warnings", "judge_groups", "judge_metric", "noise_floor", "verdict"]
