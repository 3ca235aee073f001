"""What the commands write and print: the one text report of a study's result, printed by
``demscale study`` (from the :class:`engine.StudyResult` it ran) and by ``demscale job``
(from the service's ``/studies/{id}/summary``), both from the same summary dict
(``StudyResult.to_summary``); the layout of ``study``'s summary.json and ``run``'s
result.json; ``calibrate``'s report of the calibrated law."""

from __future__ import annotations

import json
import math
from pathlib import Path


def strict(obj):
    """``obj`` with NaN and infinities as None and numpy scalars as Python numbers."""
    if isinstance(obj, dict):
        return {str(k): strict(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [strict(v) for v in obj]
    if hasattr(obj, "item") and not isinstance(obj, (str, bytes)):
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def write_json(path: Path, obj) -> None:
    """``obj`` as strict JSON (:func:`strict`), indented, into ``path``."""
    path.write_text(json.dumps(strict(obj), indent=1, allow_nan=False))


def study_summary(spec, result_summary: dict, out: Path, files: dict) -> dict:
    """``demscale study``'s summary.json: the answer first, the spec, the result's summary
    (``StudyResult.to_summary``) and the files written under ``out``: ``files`` holds
    ``results`` (the HDF5 file), ``plots`` (paths), ``curves`` and ``snapshots`` (by run)."""
    rel = lambda p: str(Path(p).relative_to(out))  # noqa: E731
    return {
        "answer": result_summary["answer"],  # first: what the study decided
        "spec": spec.to_dict(),
        **result_summary,
        "files": {
            "results": Path(files["results"]).name,
            "plots": [rel(p) for p in files["plots"]],
            "curves": {k: rel(p) for k, p in files["curves"].items()},
            "snapshots": {k: [rel(p) for p in v] for k, v in files["snapshots"].items()},
        },
    }


def run_summary(test, result, out: Path, snapshot_paths, time_steps) -> dict:
    """``demscale run``'s result.json: the test, its scalars with their units, the curves'
    file and the snapshots (``snapshot_paths`` under ``out``, a PNG section per stage, the
    snapshot files' ``time_steps``)."""
    from engine.uniaxial.results import SCALAR_UNITS

    return {
        "test": test.to_dict(),
        "scalars": result.scalars,
        "units": {k: SCALAR_UNITS.get(k, "") for k in result.scalars},
        "curves": "curves.csv",
        "snapshots": {
            "files": [
                *(str(p.relative_to(out)) for p in snapshot_paths),
                *(f"snapshots/{k}.png" for k in result.stages),
            ],
            "time_steps": time_steps,
        },
    }


def _unit(q: dict) -> str:
    return f" {q['unit']}" if q.get("unit") not in (None, "", "1") else ""


def calibration_lines(cal, summary: dict, radius: float) -> list[str]:
    """``demscale calibrate``'s report: first whether the data determine the parameters
    (and which target would determine a free one:
    engine.calibration.calibrate.determination), each parameter calibrated for particles
    of ``radius`` [m] (median, 90 % interval, status), each target against the laboratory's
    value (met, or not with its z)."""
    lines = list(summary["determination"]["lines"])
    lines.append(f"parameters (calibrated for R = {radius:g} m):")
    for n, p in cal.parameters.items():
        lo, hi = p["interval"]
        u = _unit(p)
        lines.append(f"  {n} = {p['median']:.4g}{u} (90 %: {lo:.4g} to {hi:.4g}{u}), {p['status']}")
    lines.append("targets (check run of the calibrated law against the laboratory, 1 sd):")
    for q in cal.targets_met:
        u = _unit(q)
        z = "the check run failed" if q["z"] is None else f"z = {q['z']:+.1f}"
        lines.append(
            f"  {q['name']}: {q['value']:.4g}{u} against {q['lab']:.4g} +/- {q['sd']:.2g}{u}: "
            + ("met" if q["met"] else f"NOT met ({z})")
        )
    return lines


def answer_of(summary: dict) -> list[str]:
    """The summary's answer lines (a summary stored before it had them: made from its
    report, the reference radius read from its table)."""
    from engine.study.advice import answer_lines
    from engine.study.report import StudyReport

    if summary.get("answer"):
        return list(summary["answer"])
    refs = [row["radius"] for row in summary.get("table", []) if not row.get("rule")]
    report = StudyReport.from_dict(summary.get("advisor"))
    return answer_lines(report, min(refs) if refs else None)


def summary_text(summary: dict, details: bool = False) -> str:
    """The answer first (one line, then the line that qualifies it), one short line per
    verdict (with ``details`` its full reason and what would decide it), then per run its
    size, cost and errors against the mean reference, the reference's strength, the
    controls' lines, the seeds the study added and the warnings."""
    from engine.study.advice import verdict_line
    from engine.study.report import StudyReport

    report = StudyReport.from_dict(summary.get("advisor"))
    lines = answer_of(summary)
    if report.verdicts:
        lines.append(
            f"\nverdicts at {report.confidence:.0%} confidence (docs/PHYSICS.md section 7):"
        )
    for v in report.verdicts:
        lines.append(verdict_line(v))
        if details:
            lines.append(f"  why: {v.reason}")
            if v.to_decide:
                lines.append(f"  to decide it: {v.to_decide}")
    if not details and any(v.reason for v in report.verdicts):
        lines.append("(the reasons and what would decide each: --details, or the summary JSON)")
    lines.append("")
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
    lines += [head, "-" * len(head)]
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
    ref = report.reference
    strength = ref.mean("unconfined_strength") if ref is not None else None
    if strength is not None:
        parts = [
            f"strength {strength / 1e3:.2f} ± "
            f"{(ref.std('unconfined_strength') or 0.0) / 1e3:.2f} kPa"
        ]
        if ref.mean("unconfined_strength_platen") is not None:
            parts.append(f"top platen {ref.mean('unconfined_strength_platen') / 1e3:.2f} kPa")
        if ref.mean("self_weight_stress") is not None:
            parts.append(
                f"self-weight rho g H / 2 = {ref.mean('self_weight_stress') / 1e3:.2f} kPa "
                "beside it"
            )
        failed = ref.mean("unconfined_failure")
        if failed is not None:
            parts.append(f"{failed:.0%} of the references failed at a peak")
        lines.append("\nreference: " + "; ".join(parts))
    lines += report.control_lines
    adaptive = report.adaptive
    if adaptive is not None:
        added = adaptive.added_runs
        kinds = {}
        for a in added:
            kinds[a["kind"]] = kinds.get(a["kind"], 0) + 1
        what = ", ".join(f"{n} {k}" for k, n in sorted(kinds.items())) or "none"
        lines.append(
            f"seeds until decided: {adaptive.planned_runs} planned runs (the pilot), "
            f"{len(added)} added ({what}); verdicts at look {adaptive.look} of "
            f"{adaptive.looks}; stopped: {adaptive.stopped or 'still adding'}"
        )
        for a in added:
            lines.append(f"  + {a['run']}: {a['reason']}")
    lines += [f"warning: {w}" for w in report.warnings]
    return "\n".join(lines)
