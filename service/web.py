"""The studies web page: server-rendered HTML (Jinja2 templates in service/templates), with a
little JavaScript that polls the JSON API for live progress. No build step.

    /                          the caller's studies, newest first: status and live progress
    /studies/{id}/page         one study: progress, verdicts, the summary table, the plots
                               and links to the HDF5 file and the JSON endpoints
    /calibrations/{id}/page    one calibration: progress, each parameter and how well the
                               data determine it, the targets met, the compression curve and
                               flow function against the lab points, the Sobol indices
    /login, /logout            the API token kept in a cookie (service.weblogin)

The pages read the same database and result files as the API and, like it, show a token only
its own studies; they are left out of the OpenAPI description (they are for people).
"""

from __future__ import annotations

import math
from pathlib import Path

from fastapi import APIRouter, HTTPException, Request
from fastapi.responses import HTMLResponse
from fastapi.templating import Jinja2Templates
from sqlmodel import select

from engine.calibration.calibrate import TARGET_UNITS, determination
from engine.io.figures import KINDS
from engine.study.kinds import kind_for_json
from engine.study.reasons import describe, interval_words, pct, shown
from engine.study.report import StudyReport
from engine.study.run import duration_words

from . import h5store, transitions
from .deps import CalibrationDep, OwnerDep, SessionDep, SettingsDep, StudyDep
from .jobs import jobs_page
from .models import TERMINAL, Kind, Run, Status
from .plots import study_kinds
from .routes.calibrations import public as calibration_public
from .routes.calibrations import read_result as read_calibration
from .routes.studies import public

router = APIRouter(include_in_schema=False)
templates = Jinja2Templates(directory=Path(__file__).parent / "templates")
#: "3 min 20 s": the time left and the run time as demscale job and demscale study say them
templates.env.filters["duration"] = duration_words

#: Columns of the run table on a study page: key in the summary table, heading, scale, format.
RUN_COLUMNS = (
    ("run", "run", None, "{}"),
    ("rule", "rule", None, "{}"),
    ("radius", "R [mm]", 1e3, "{:g}"),
    ("particles", "particles [-]", None, "{}"),
    ("wall_time", "run time [s]", 1.0, "{:.1f}"),
    ("setup_time", "compile [s]", 1.0, "{:.1f}"),
    ("speedup", "speed-up [x]", 1.0, "{:.2f}"),
    ("speedup_steps", "speed-up in particle-steps [x]", 1.0, "{:.2f}"),
    ("overburden_ratio", "self-weight / consolidation [-]", 1.0, "{:.3f}"),
    ("unconfined_strength", "strength [kPa]", 1e-3, "{:.3g}"),
    # relative RMS errors against the mean reference (unsigned; the verdicts sign them)
    ("err_density", "density err [%]", 100.0, "{:.1f}"),
    ("err_loading_stiffness", "loading stiffness err [%]", 100.0, "{:.1f}"),
    ("err_unloading_stiffness", "unloading stiffness err [%]", 100.0, "{:.1f}"),
    ("err_coordination_interior", "coordination err [%]", 100.0, "{:.1f}"),
    ("err_strength", "strength err [%]", 100.0, "{:.1f}"),
    # a shear study's: its run's yield locus, flow function point and bulk density, then
    # the errors of the shear metrics (engine.study.metrics.SHEAR_METRICS)
    ("cohesion", "cohesion [kPa]", 1e-3, "{:.3g}"),
    ("friction_angle", "friction angle [deg]", 1.0, "{:.1f}"),
    ("sigma_1", "sigma_1 [kPa]", 1e-3, "{:.3g}"),
    ("sigma_c", "sigma_c [kPa]", 1e-3, "{:.3g}"),
    ("ffc", "ffc [-]", 1.0, "{:.2f}"),
    ("bulk_density", "bulk density [kg/m^3]", 1.0, "{:.0f}"),
    ("err_yield_locus", "yield locus err [%]", 100.0, "{:.1f}"),
    ("err_sigma_1", "sigma_1 err [%]", 100.0, "{:.1f}"),
    ("err_sigma_c", "sigma_c err [%]", 100.0, "{:.1f}"),
    ("err_ffc", "ffc err [%]", 100.0, "{:.1f}"),
    ("err_bulk_density", "bulk density err [%]", 100.0, "{:.1f}"),
    # a hopper study's (docs/HOPPER.md): its steady discharge, whether it arched, its flow
    # mode's index, then the error of its discharge number
    ("discharge_number", "discharge number [-]", 1.0, "{:.3g}"),
    ("discharge_rate", "discharge rate [g/s]", 1e3, "{:.3g}"),
    ("arched", "arched [-]", 1.0, "{:.0f}"),
    ("mass_flow_index", "mass-flow index [-]", 1.0, "{:.2f}"),
    ("err_discharge_number", "discharge number err [%]", 100.0, "{:.1f}"),
)


def cell(value, scale: float | None, fmt: str) -> str:
    """One table cell: scaled and formatted; a dash for a missing number or NaN, the sign
    of infinity for an infinite one (a shear run's ffc where sigma_c = 0)."""
    if value is None:
        return "-"
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        if math.isnan(value):
            return "-"
        if math.isinf(value):
            return "∞" if value > 0 else "-∞"
        if scale is not None:
            value = value * scale
    return fmt.format(value)


def verdict_table(groups, tolerances: dict) -> dict:
    """A table of judged groups (a :class:`engine.study.report.StudyReport`'s ``verdicts``,
    ``rule_errors`` or ``resolution``): a row per (radius, rule), a column per metric.
    Each cell holds the metric's signed error and, below it, its interval (an interval
    with an end beyond +-1000 % as unbounded, engine.study.reasons.interval_words), its
    verdict (the cell's colour) and, on hover, how the interval was made, the tolerance
    and the seeds; each row's reasons, a line per metric, and what would decide it go in
    a detail row."""
    names: list[str] = []
    for v in groups:
        names += [m.metric for m in v.metrics if m.metric not in names]
    rows = []
    for v in groups:
        by_name = {m.metric: m for m in v.metrics}
        cells = []
        for name in names:
            m = by_name.get(name)
            if m is None:
                cells.append(None)
                continue
            # the words are engine.study.reasons', on the judged metric's record
            err, interval, how = shown(m.to_dict())
            bounds = interval_words(interval) if interval is not None else how
            cells.append(
                {
                    "verdict": m.verdict,
                    "error": "-" if err is None else pct(err),
                    "interval": bounds,
                    "title": f"{name}: {m.verdict}; {pct(err)}, interval {bounds}"
                    + (f" ({how})" if interval is not None else "")
                    + f"; tolerance ± {100 * m.tolerance:g} %; {m.seeds} seeds against "
                    f"{m.reference_seeds}",
                }
            )
        rows.append(
            {
                "radius": v.radius,
                "rule": v.rule,
                "verdict": v.verdict,
                "seeds": v.seeds,
                "speedup": v.speedup,
                "cells": cells,
                "lines": [describe(m.to_dict()) for m in v.metrics],
                "to_decide": v.to_decide,
            }
        )
    return {"metrics": [(n, tolerances.get(n)) for n in names], "rows": rows}


def curve_table(report: StudyReport) -> list[dict]:
    """The resolution curve per property (engine.study.resolution): how far the reference
    is from the bulk value, with its interval (unbounded beyond +-1000 %), and the sizes
    the line was fitted to."""
    curve = report.resolution_curve
    rows = []
    for name, c in (curve.metrics if curve is not None else {}).items():
        rows.append(
            {
                "metric": name,
                "across": c.get("reference_diameters_across"),
                "offset": pct(c.get("reference_offset")),
                "interval": interval_words(c.get("reference_offset_interval")),
                "sizes": ", ".join(f"{s['diameters_across']:.1f}" for s in c.get("sizes", [])),
                "linear": c.get("linear"),
            }
        )
    return rows


def report_tables(report: StudyReport) -> dict:
    """The study page's tables of ``report``: the verdicts, the rule errors, the resolution
    errors (:func:`verdict_table`) and the resolution curve (:func:`curve_table`)."""
    tables = {
        "verdicts": verdict_table(report.verdicts, report.tolerances),
        "rule_errors": verdict_table(report.rule_errors, report.tolerances),
        "resolution": verdict_table(report.resolution, report.tolerances),
    }
    tables["curve"] = curve_table(report)
    return tables


@router.get("/", response_class=HTMLResponse)
def studies_page(
    request: Request, session: SessionDep, owner: OwnerDep, settings: SettingsDep
) -> HTMLResponse:
    """The caller's studies and calibrations, newest first (the latest 200 of each)."""
    return templates.TemplateResponse(
        request,
        "studies.html",
        {
            "studies": [public(s) for s in jobs_page(session, owner, Kind.study)[0]],
            "calibrations": [
                calibration_public(c, session, settings)
                for c in jobs_page(session, owner, Kind.calibration)[0]
            ],
            "terminal": TERMINAL,
        },
    )


@router.get("/calibrations/{calibration_id}/page", response_class=HTMLResponse)
def calibration_page(
    request: Request, job: CalibrationDep, session: SessionDep, settings: SettingsDep
) -> HTMLResponse:
    """One calibration: progress while it runs; parameters, targets, the figure and the
    sensitivities once done."""
    runs = session.exec(select(Run).where(Run.study_id == job.id).order_by(Run.position)).all()
    result, missing = None, None
    if job.status is Status.succeeded:
        try:
            result = read_calibration(job, settings)
        except HTTPException as e:
            missing = e.detail
    return templates.TemplateResponse(
        request,
        "calibration.html",
        {
            "job": calibration_public(job, session, settings),
            "asked": job.spec,  # the calibration as submitted ("request" is the page's)
            "runs": runs,
            "result": result,
            # whether the data determine the parameters, said first (stored results of
            # earlier versions: from their parameters and Sobol indices)
            "determination": (result or {}).get("determination")
            or (determination(result) if result else {}),
            "missing": missing,
            "study_id": transitions.child_of(session, job.id),
            "terminal": TERMINAL,
            "fmt": cell,
            # results stored before targets carried units: by the kind of target
            "target_unit": lambda name: TARGET_UNITS.get(name.split("@")[0], ""),
        },
    )


def _plots(spec: dict) -> dict[str, str]:
    """The plots a study's page shows, kind -> title: those its kind of test has
    (service.plots.study_kinds, as its links and the API): the unconfined plot only where
    the test has that stage, the resolution plot only with resolution controls."""
    return {k: KINDS[k] for k in study_kinds(spec)}


@router.get("/studies/{study_id}/page", response_class=HTMLResponse)
def study_page(
    request: Request, study: StudyDep, session: SessionDep, settings: SettingsDep
) -> HTMLResponse:
    """One study: progress while it runs; verdicts, runs, plots and downloads once done."""
    runs = session.exec(select(Run).where(Run.study_id == study.id).order_by(Run.position)).all()
    summary, missing = None, None
    path = settings.results_path(study.id)
    if study.status is Status.succeeded:
        if path.is_file():
            summary = h5store.read_summary(path)
        else:
            missing = "the results file of this study is gone"
    table, verdicts, report = [], {}, None
    if summary is not None:
        report = StudyReport.from_dict(summary.get("advisor"))
        verdicts = report_tables(report)
        # each run's kernel compilation (set-up), kept out of its run time and speed-up; the
        # scalars its kind may have infinite as stored (the summary's JSON has null there);
        # the columns its kind leaves out (engine.study.kinds.TestKind)
        kind = kind_for_json(study.spec.get("reference") or {})
        stored = h5store.read_run_scalars(path, ("setup_time", *kind.infinite_scalars))
        rows = [{**row, **stored.get(row.get("run"), {})} for row in summary["table"]]
        hidden = kind.hidden_columns
        cols = [c for c in RUN_COLUMNS if c[0] not in hidden and any(c[0] in row for row in rows)]
        table = [[cell(row.get(k), s, f) for k, _, s, f in cols] for row in rows]
        headings = [h for _, h, _, _ in cols]
    else:
        headings = []
    return templates.TemplateResponse(
        request,
        "study.html",
        {
            "study": public(study),
            "runs": runs,
            "summary": summary,
            "report": report,
            "missing": missing,
            "headings": headings,
            "table": table,
            "verdicts": verdicts,
            "plots": _plots(study.spec),
            "terminal": TERMINAL,
            "fmt": cell,
            "snapshots": settings.snapshot_files(study.id) if summary is not None else {},
        },
    )
