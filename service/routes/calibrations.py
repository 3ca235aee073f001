"""Calibration endpoints: submit, list, status and result, curves against the laboratory
points, the figure, the calibrated law for LIGGGHTS, cancel, delete.

A calibration is a job of the same queue as the studies (:mod:`service.models`): the same
quotas (queued or running jobs in all and per token, submissions per second, storage per
token), the same workers, heartbeats, cancel and resume after a worker's death (its runs
are stored as they finish; a run in flight starts again)."""

from __future__ import annotations

import io
import json
import os
import shutil
from enum import Enum
from typing import Annotated

from fastapi import APIRouter, HTTPException, Query, Response
from fastapi.exceptions import RequestValidationError
from sqlmodel import select

from engine.calibration.calibrate import determination
from engine.io.figures import FIGURES_VERSION, calibration_status  # matplotlib: when drawn

from .. import transitions
from ..admission import SpecRejected, admit_calibration
from ..deps import CalibrationDep, OwnerDep, SessionDep, SettingsDep
from ..errors import answers
from ..jobs import calibration_row, jobs_page, worst_case_bytes
from ..models import (
    CalibrationDetail,
    CalibrationPublic,
    CalibrationsPublic,
    Kind,
    Run,
    RunPublic,
    Status,
    Study,
    StudySubmitted,
)
from ..spec import CalibrationCreate
from .studies import MAX_LIMIT, MAX_OFFSET, enqueue, submitted

router = APIRouter(prefix="/calibrations", tags=["calibrations"], responses=answers(401))


def links(job_id: object) -> dict[str, str]:
    """URLs (relative to the API root) of a calibration and its results."""
    base = f"/calibrations/{job_id}"
    return {
        "self": base,
        "curves": f"{base}/curves",
        "plot": f"{base}/plot.png",
        "law": f"{base}/law",
        "cancel": f"{base}/cancel",
        "page": f"{base}/page",
    }


def outcome(job: Study, settings) -> dict:
    """Whether a succeeded calibration's check run met every target, and in words
    (``all_targets_met``, ``outcome``; None before it has succeeded or without its file)."""
    try:
        result = read_result(job, settings)
    except HTTPException:
        result = None
    if not result:
        return {"all_targets_met": None, "all_free": None, "outcome": None}
    met = all(q.get("met") for q in result.get("targets_met", []))
    # stored before calibrations said it: from its parameters and Sobol indices
    free = (result.get("determination") or determination(result))["all_free"]
    return {"all_targets_met": met, "all_free": free, "outcome": calibration_status(result)}


def public(job: Study, session, settings) -> CalibrationPublic:
    """The API view of a calibration row (with the study it queued, if any, and once it has
    succeeded whether its law met every target)."""
    return CalibrationPublic.model_validate(
        job,
        update={
            "links": links(job.id),
            "study_id": transitions.child_of(session, job.id),
            **outcome(job, settings),
        },
    )


def read_result(job: Study, settings) -> dict | None:
    """The result of a succeeded calibration (None before); 404 if its file is gone."""
    if job.status is not Status.succeeded:
        return None
    path = settings.calibration_path(job.id)
    try:
        return json.loads(path.read_text())
    except FileNotFoundError:
        raise HTTPException(
            status_code=404, detail=f"the result file of calibration {job.id} is gone"
        ) from None


def _result(job: Study, settings) -> dict:
    """The result, or 409 while the calibration has not succeeded."""
    out = read_result(job, settings)
    if out is None:
        raise HTTPException(
            status_code=409,
            detail=f"calibration {job.id} is {job.status.value}: results exist only for a "
            "succeeded calibration" + (f" (error: {job.error})" if job.error else ""),
        )
    return out


@router.post(
    "",
    status_code=202,
    response_model=StudySubmitted,
    responses=submitted("calibration"),
)
def submit_calibration(
    body: CalibrationCreate,
    session: SessionDep,
    settings: SettingsDep,
    owner: OwnerDep,
    response: Response,
) -> StudySubmitted:
    """Queue a calibration of the test's pair law to laboratory targets (and, with
    ``then_study``, the scaling study of the calibrated law when it succeeds). 422 with
    field-level errors for a request the engine refuses (a target this test cannot measure,
    a parameter the law has not, a box with low >= high, too few design runs) or beyond the
    caps; 429 and 507 as for a study."""
    try:
        admitted = admit_calibration(body, settings)
    except SpecRejected as e:
        raise RequestValidationError(e.errors) from e
    job = calibration_row(admitted, owner, body.name)
    job = enqueue(session, settings, job, [], worst_case_bytes(admitted))
    response.headers["Location"] = f"/calibrations/{job.id}"
    return StudySubmitted(id=job.id, status=job.status, links=links(job.id))


@router.get("", response_model=CalibrationsPublic)
def list_calibrations(
    session: SessionDep,
    owner: OwnerDep,
    settings: SettingsDep,
    offset: Annotated[int, Query(ge=0, le=MAX_OFFSET, description="Jobs to skip.")] = 0,
    limit: Annotated[int, Query(ge=1, le=MAX_LIMIT, description="Most returned.")] = 100,
) -> CalibrationsPublic:
    """This token's calibrations, newest first, with status and progress."""
    rows, count = jobs_page(session, owner, Kind.calibration, offset, limit)
    return CalibrationsPublic(data=[public(j, session, settings) for j in rows], count=count)


@router.get("/{calibration_id}", response_model=CalibrationDetail, responses=answers(404))
def read_calibration(
    job: CalibrationDep, session: SessionDep, settings: SettingsDep
) -> CalibrationDetail:
    """Status, progress, runs and, once succeeded, the result: the calibrated law, each
    parameter (median, 90 % interval, determined or free), every target met or not (and by
    how much), the Sobol indices, every run, the check run's curves and the study it
    queued."""
    runs = session.exec(select(Run).where(Run.study_id == job.id).order_by(Run.position)).all()
    return CalibrationDetail.model_validate(
        job,
        update={
            "links": links(job.id),
            "study_id": transitions.child_of(session, job.id),
            **outcome(job, settings),
            "request": job.spec,
            "runs": [RunPublic.model_validate(r) for r in runs],
            "result": read_result(job, settings),
        },
    )


@router.get("/{calibration_id}/curves", responses=answers(404, 409))
def curves(job: CalibrationDep, settings: SettingsDep) -> dict:
    """The fitted curves against the laboratory points: the check run's compression curve
    (porosity against the top platen's stress, loading and unloading), flow function and
    yield loci (with shear targets), the laboratory points with their 1-sd uncertainties,
    and what every run measured."""
    result = _result(job, settings)
    targets = job.spec["targets"]
    return {
        "units": {
            "stress": "Pa",
            "porosity": "1",
            "strength": "Pa",
            "consolidation_stress": "Pa",
            # yield loci: stresses (sigma_pre, sigma_n, sigma, tau, cohesion, sigma_1,
            # sigma_c) in Pa, slope tan(phi) and ffc [-], bulk density
            "sigma_pre": "Pa",
            "tau": "Pa",
            "slope": "1",
            "ffc": "1",
            "bulk_density": "kg/m^3",
        },
        "check_run": result.get("curves", {}),
        "laboratory": {
            "compression": targets.get("compression", []),
            "strength": targets.get("strength", []),
            "shear": targets.get("shear", []),
        },
        "targets": result["targets_met"],
        "runs": result["runs"],
    }


@router.get(
    "/{calibration_id}/plot.png",
    response_class=Response,
    responses={
        200: {"content": {"image/png": {"schema": {"type": "string", "format": "binary"}}}},
        **answers(404, 409),
    },
)
def plot(job: CalibrationDep, settings: SettingsDep) -> Response:
    """The compression curve and the flow function against the laboratory points (PNG;
    drawn once, then cached beside the result)."""
    result = _result(job, settings)
    cached = settings.study_dir(job.id) / "plots" / f"calibration.v{FIGURES_VERSION}.png"
    if not cached.is_file():
        from engine.io.figures import calibration_figure

        buf = io.BytesIO()
        calibration_figure(result).savefig(buf, format="png")
        cached.parent.mkdir(parents=True, exist_ok=True)
        tmp = cached.with_name(f".calibration.{os.getpid()}.{id(buf)}.tmp")
        tmp.write_bytes(buf.getvalue())
        os.replace(tmp, cached)
    return Response(cached.read_bytes(), media_type="image/png")


LawFormat = Enum("LawFormat", {k: k for k in ("json", "csv", "liggghts")}, type=str)


@router.get(
    "/{calibration_id}/law",
    responses={
        200: {"content": {"text/plain": {"schema": {"type": "string"}}}},
        **answers(404, 409),
    },
)
def law(
    job: CalibrationDep,
    settings: SettingsDep,
    format: Annotated[
        LawFormat, Query(description="json or csv: a table with units; liggghts: a fragment")
    ] = LawFormat.json,
) -> Response:
    """The calibrated law: a table of its parameters with units (JSON or CSV), or a LIGGGHTS
    ``edinburgh``/``stiffness`` input fragment (engine.io.liggghts)."""
    import engine
    from engine.core.records import from_dict
    from engine.io.liggghts import law_table, to_liggghts

    raw = dict(_result(job, settings)["law"])
    law = from_dict(
        {"BilinearAdhesive": engine.BilinearAdhesive, "EEPA": engine.EEPA}[raw.pop("type")], raw
    )
    if format is LawFormat.liggghts:
        try:
            text = to_liggghts(law, note=f"calibrated by demscale, calibration {job.id}")
        except engine.ParameterError as e:
            raise HTTPException(status_code=409, detail=f"no LIGGGHTS fragment: {e}") from e
        return Response(text, media_type="text/plain")
    if format is LawFormat.csv:
        return Response(law_table(law, "csv"), media_type="text/csv")
    return Response(json.dumps(law_table(law)), media_type="application/json")


@router.post(
    "/{calibration_id}/cancel",
    status_code=202,
    response_model=CalibrationPublic,
    responses=answers(404, 409),
)
def cancel_calibration(
    job: CalibrationDep, session: SessionDep, settings: SettingsDep
) -> CalibrationPublic:
    """Cancel a queued calibration now, or ask the worker of a running one to stop (at its
    run's next progress report; the runs stored so far are kept until it is deleted). 409
    when finished."""
    if not transitions.request_cancel(session, job.id):
        raise HTTPException(
            status_code=409,
            detail=f"calibration {job.id} is {job.status.value}: nothing to cancel",
        )
    session.refresh(job)
    return public(job, session, settings)


@router.delete(
    "/{calibration_id}", status_code=204, response_class=Response, responses=answers(404, 409)
)
def delete_calibration(job: CalibrationDep, session: SessionDep, settings: SettingsDep) -> Response:
    """Remove a finished calibration and its files (the study it queued stays); 409 while it
    is queued or running."""
    if not transitions.remove(session, job.id):
        raise HTTPException(
            status_code=409,
            detail=f"calibration {job.id} is {job.status.value}: cancel it and wait until it "
            "stops first",
        )
    shutil.rmtree(settings.study_dir(job.id), ignore_errors=True)
    return Response(status_code=204)
