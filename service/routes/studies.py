"""Study endpoints: submit, list, status, cancel, delete."""

from __future__ import annotations

import shutil
from typing import Annotated

from fastapi import APIRouter, HTTPException, Query, Response
from fastapi.exceptions import RequestValidationError
from sqlmodel import select

from .. import transitions
from ..admission import Admitted, SpecRejected, admit
from ..cost import output_bytes, stored_bytes
from ..cost import worst_case as cost_of
from ..deps import OwnerDep, SessionDep, SettingsDep, StudyDep
from ..errors import answers
from ..jobs import calibration_bytes, jobs_page, study_rows
from ..models import (
    Kind,
    Run,
    RunPublic,
    Status,
    StudiesPublic,
    Study,
    StudyDetail,
    StudyPublic,
    StudySubmitted,
)
from ..plots import study_kinds
from ..spec import StudyCreate

router = APIRouter(prefix="/studies", tags=["studies"], responses=answers(401))

#: Largest offset of a listing (SQLite integers stop at 2^63; no store holds 2^31 studies).
MAX_OFFSET = 2**31 - 1
#: Largest page of a listing.
MAX_LIMIT = 1000


def links(study: Study) -> dict[str, str]:
    """URLs (relative to the API root) of a study and its results: a plot only of the kinds
    its kind of test has (service.plots.study_kinds)."""
    base = f"/studies/{study.id}"
    out = {
        "self": base,
        "summary": f"{base}/summary",
        "curves": f"{base}/curves",
        "results": f"{base}/results.h5",
        "cancel": f"{base}/cancel",
    }
    out.update({f"plot_{k}": f"{base}/plots/{k}.png" for k in study_kinds(study.spec)})
    return out


def runs_added(study: Study) -> int:
    """Runs a ``decide`` study has added to its stored plan so far."""
    return max(0, study.n_runs - len(study.plan["runs"])) if study.plan else 0


def public(study: Study) -> StudyPublic:
    """The API view of a study row."""
    return StudyPublic.model_validate(
        study, update={"links": links(study), "runs_added": runs_added(study)}
    )


def check_storage(session, settings, owner: str, new_id, new_bytes: float) -> None:
    """507 when the owner's studies would take more than ``DEMSCALE_MAX_STORAGE_PER_TOKEN``:
    what each holds on disk (a queued or running one: at least its worst-case size, it has
    yet to write) plus the worst-case size of the new one (``new_id``, already inserted in
    this transaction: two submissions cannot both slip under the quota)."""
    rows = session.exec(
        select(Study.id, Study.status, Study.spec, Study.kind).where(
            Study.owner == owner, Study.id != new_id
        )
    ).all()
    used = 0.0
    for sid, status, spec, kind in rows:
        held = stored_bytes([settings.study_dir(sid)])
        if status in (Status.queued, Status.running):
            try:
                worst = (
                    calibration_bytes(spec)
                    if kind == Kind.calibration
                    else output_bytes(cost_of(spec))
                )
                held = max(held, worst)
            except Exception:  # a spec stored by an older version: what it holds now
                pass
        used += held
    limit = settings.max_storage_per_token
    if used + new_bytes > limit:
        raise HTTPException(
            status_code=507,
            detail=f"this token's studies and calibrations take up to {used / 1e6:.1f} MB "
            f"and this one could take {new_bytes / 1e6:.1f} MB more; the limit is "
            f"{limit / 1e6:.1f} MB per token (DEMSCALE_MAX_STORAGE_PER_TOKEN): "
            "delete finished studies or calibrations first",
        )


def submitted(what: str) -> dict:
    """The OpenAPI answers of a submission: 202 with the new job's ``Location``, and the
    refusals."""
    return {
        202: {
            "headers": {
                "Location": {
                    "schema": {"type": "string"},
                    "required": True,
                    "description": f"URL of the new {what}.",
                }
            }
        },
        **answers(400, 413, 429, 507),
    }


@router.post(
    "",
    status_code=202,
    response_model=StudySubmitted,
    responses=submitted("study"),
)
def submit_study(
    body: StudyCreate,
    session: SessionDep,
    settings: SettingsDep,
    owner: OwnerDep,
    response: Response,
) -> StudySubmitted:
    """Queue a study. 422 with field-level errors when the spec is invalid or too large;
    429 (with Retry-After) when too many studies are queued or running, or the token submits
    too fast; 507 when the token's studies would take more than its storage quota."""
    try:
        plan, costs = admit(body, settings)  # the study's one planning
    except SpecRejected as e:
        raise RequestValidationError(e.errors) from e
    study, runs = study_rows(Admitted(plan, costs), owner, body.name)
    study = enqueue(session, settings, study, runs, output_bytes(costs))
    response.headers["Location"] = f"/studies/{study.id}"
    return StudySubmitted(id=study.id, status=study.status, links=links(study))


def enqueue(session, settings, job: Study, runs: list, new_bytes: float) -> Study:
    """Insert a queued job (a study or a calibration) and its run rows, within the queue
    bounds (429 with ``Retry-After`` beyond them) and the owner's storage quota (507), both
    checked inside the insert's transaction (SQLite's one writer at a time)."""
    try:
        return transitions.submit(
            session,
            job,
            runs,
            settings.max_active,
            settings.max_active_per_token,
            check=lambda s: check_storage(s, settings, job.owner, job.id, new_bytes),
        )
    except transitions.QueueFull as e:
        raise HTTPException(
            status_code=429,
            detail=f"{e}: try again later",
            headers={"Retry-After": str(settings.retry_after)},
        ) from e


@router.get("", response_model=StudiesPublic)
def list_studies(
    session: SessionDep,
    owner: OwnerDep,
    offset: Annotated[int, Query(ge=0, le=MAX_OFFSET, description="Studies to skip.")] = 0,
    limit: Annotated[int, Query(ge=1, le=MAX_LIMIT, description="Most studies returned.")] = 100,
) -> StudiesPublic:
    """This token's studies, newest first, with status and progress; ``count`` is their
    total."""
    rows, count = jobs_page(session, owner, Kind.study, offset, limit)
    return StudiesPublic(data=[public(s) for s in rows], count=count)


@router.get("/{study_id}", response_model=StudyDetail, responses=answers(404))
def read_study(study: StudyDep, session: SessionDep) -> StudyDetail:
    """Status, progress (fraction, current run and stage), error, timings and runs."""
    runs = session.exec(select(Run).where(Run.study_id == study.id).order_by(Run.position)).all()
    return StudyDetail.model_validate(
        study,
        update={
            "links": links(study),
            "runs_added": runs_added(study),
            "plot_kinds": list(study_kinds(study.spec)),
            "runs": [RunPublic.model_validate(r) for r in runs],
        },
    )


@router.post(
    "/{study_id}/cancel", status_code=202, response_model=StudyPublic, responses=answers(404, 409)
)
def cancel_study(study: StudyDep, session: SessionDep) -> StudyPublic:
    """Cancel a queued study now, or ask the worker of a running one to stop (cooperative:
    the status becomes ``cancelled`` once the worker has stopped). 409 when finished."""
    if not transitions.request_cancel(session, study.id):
        raise HTTPException(
            status_code=409, detail=f"study {study.id} is {study.status.value}: nothing to cancel"
        )
    session.refresh(study)
    return public(study)


@router.delete("/{study_id}", status_code=204, response_class=Response, responses=answers(404, 409))
def delete_study(study: StudyDep, session: SessionDep, settings: SettingsDep) -> Response:
    """Remove a finished study and its files; 409 while it is queued or running."""
    if not transitions.remove(session, study.id):
        raise HTTPException(
            status_code=409,
            detail=f"study {study.id} is "
            f"{study.status.value}: cancel it and wait until it stops first",
        )
    shutil.rmtree(settings.study_dir(study.id), ignore_errors=True)
    return Response(status_code=204)
