"""The one text report of a study's result, printed by ``demscale study`` (from the
:class:`engine.StudyResult` it ran) and by ``demscale job`` (from the service's
``/studies/{id}/summary``): both are the same summary dict (``StudyResult.to_summary``)."""

from __future__ import annotations


def summary_text(summary: dict) -> str:
    """Per run: size, cost and its errors against the mean reference; then the verdicts
    with their reasons and the advisor's warnings."""
    cols = (
        ("err_density", "dens"),
        ("err_loading_stiffness", "K_ld"),
        ("err_unloading_stiffness", "K_ul"),
        ("err_coordination_interior", "Z"),
        ("err_strength", "UCS"),
    )
    if any("err_yield_locus" in row for row in summary["table"]):  # a shear study's metrics
        cols = (
            ("err_yield_locus", "locus"),
            ("err_sigma_1", "sig_1"),
            ("err_sigma_c", "sig_c"),
            ("err_ffc", "ffc"),
            ("err_bulk_density", "dens"),
        )
    head = (
        f"{'run':<22}{'R [mm]':>7}{'rule':>10}{'N':>7}{'cell [d]':>9}{'time [s]':>9}"
        f"{'speed-up':>9}" + "".join(f"{lab:>7}" for _, lab in cols)
    )
    lines = [head, "-" * len(head)]
    for row in summary["table"]:
        lines.append(
            f"{row['run']:<22}{row['radius'] * 1e3:>7.3g}{row['rule']:>10}"
            f"{row['particles']:>7}{row.get('thickness_diameters', 0):>9.1f}"
            f"{row['wall_time']:>9.1f}{row['speedup']:>9.2f}"
            + "".join(f"{100 * row[c]:>6.1f}%" if c in row else f"{'-':>7}" for c, _ in cols)
        )
    lines.append(
        "errors [%] against the mean of the reference seeds; cell [d]: thinnest "
        "side in particle diameters"
    )
    advisor = summary.get("advisor", {})
    ref = advisor.get("reference") or {}
    if "unconfined_strength" in ref:
        parts = [
            f"strength {ref['unconfined_strength'] / 1e3:.2f} ± "
            f"{ref.get('unconfined_strength_std', 0.0) / 1e3:.2f} kPa"
        ]
        if "unconfined_strength_platen" in ref:
            parts.append(f"top platen {ref['unconfined_strength_platen'] / 1e3:.2f} kPa")
        if "self_weight_stress" in ref:
            parts.append(
                f"self-weight rho g H / 2 = {ref['self_weight_stress'] / 1e3:.2f} kPa beside it"
            )
        failed = ref.get("unconfined_failure")
        if failed is not None:
            parts.append(f"{failed:.0%} of the references failed at a peak")
        lines.append("\nreference: " + "; ".join(parts))
    conf = advisor.get("confidence")
    if conf is not None:
        lines.append(f"\nverdicts at {conf:.0%} confidence (docs/PHYSICS.md section 7):")
    for v in advisor.get("verdicts", []):
        lines.append(
            f"R = {v['radius'] * 1e3:g} mm, {v['rule']}: {v['verdict'].upper()}: {v['reason']}"
        )
        if v.get("to_decide"):
            lines.append(f"  to decide it: {v['to_decide']}")
    for name, a in advisor.get("rules", {}).items():
        if a.get("coarsest_radius") is not None:
            lines.append(
                f"{name}: equivalent up to R = {a['coarsest_radius'] * 1e3:g} mm "
                f"({a['speedup']:.1f}x faster than the reference)"
            )
        else:
            lines.append(f"{name}: no coarse radius shown equivalent")
    lines += advisor.get("control_lines", [])
    adaptive = advisor.get("adaptive")
    if adaptive:
        added = adaptive.get("added_runs", [])
        kinds = {}
        for a in added:
            kinds[a["kind"]] = kinds.get(a["kind"], 0) + 1
        what = ", ".join(f"{n} {k}" for k, n in sorted(kinds.items())) or "none"
        lines.append(
            f"seeds until decided: {adaptive['planned_runs']} planned runs (the pilot), "
            f"{len(added)} added ({what}); verdicts at look {adaptive.get('look', '?')} of "
            f"{adaptive.get('looks', '?')}; stopped: {adaptive.get('stopped') or 'still adding'}"
        )
        for a in added:
            lines.append(f"  + {a['run']}: {a['reason']}")
    lines += [f"warning: {w}" for w in advisor.get("warnings", [])]
    return "\n".join(lines)
