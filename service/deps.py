"""FastAPI dependencies as ``Annotated`` aliases: settings, session, the caller's token
(owner), the study of the path (only the caller's own), and the results file of a succeeded
study."""

from __future__ import annotations

import uuid
from collections.abc import Iterator
from pathlib import Path
from typing import Annotated

from fastapi import Depends, HTTPException, Request, Security
from fastapi import Path as PathParam
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer
from sqlmodel import Session, select

from .db import session_scope
from .models import Kind, Status, Study
from .settings import Settings, get_settings

SettingsDep = Annotated[Settings, Depends(get_settings)]


def get_session(settings: SettingsDep) -> Iterator[Session]:
    """A database session for one request."""
    yield from session_scope(settings)


SessionDep = Annotated[Session, Depends(get_session)]


#: Declares the bearer scheme in the OpenAPI document; :class:`service.guard.Guard` checks it.
bearer = HTTPBearer(
    auto_error=False,
    description="A token of DEMSCALE_API_TOKEN or DEMSCALE_API_TOKEN_FILE.",
)


def get_owner(
    request: Request,
    _credentials: Annotated[HTTPAuthorizationCredentials | None, Security(bearer)],
) -> str:
    """The fingerprint of the caller's token, as the guard middleware found it."""
    owner = getattr(request.state, "owner", None)
    if owner is None:  # a route reached without the guard: refuse rather than serve
        raise HTTPException(
            status_code=401,
            detail="a valid bearer token is required",
            headers={"WWW-Authenticate": 'Bearer realm="demscale"'},
        )
    return owner


OwnerDep = Annotated[str, Depends(get_owner)]

StudyId = Annotated[uuid.UUID, PathParam(description="The study's id (a UUID).")]


def _job(job_id: uuid.UUID, kind: Kind, session: Session, owner: str) -> Study:
    job = session.exec(
        select(Study).where(Study.id == job_id, Study.owner == owner, Study.kind == kind)
    ).first()
    if job is None:
        raise HTTPException(status_code=404, detail=f"no {kind.value} {job_id}")
    return job


def get_study(study_id: StudyId, session: SessionDep, owner: OwnerDep) -> Study:
    """The caller's study of the path; 404 when there is none, or it is another token's."""
    return _job(study_id, Kind.study, session, owner)


StudyDep = Annotated[Study, Depends(get_study)]

CalibrationId = Annotated[uuid.UUID, PathParam(description="The calibration's id (a UUID).")]


def get_calibration(calibration_id: CalibrationId, session: SessionDep, owner: OwnerDep) -> Study:
    """The caller's calibration of the path; 404 when there is none, or it is another
    token's."""
    return _job(calibration_id, Kind.calibration, session, owner)


CalibrationDep = Annotated[Study, Depends(get_calibration)]


def get_results(study: StudyDep, settings: SettingsDep) -> Path:
    """The HDF5 file of a succeeded study; 409 while it has not succeeded."""
    if study.status is not Status.succeeded:
        raise HTTPException(
            status_code=409,
            detail=f"study {study.id} is {study.status.value}: results exist only for a "
            "succeeded study" + (f" (error: {study.error})" if study.error else ""),
        )
    path = settings.results_path(study.id)
    if not path.is_file():
        raise HTTPException(status_code=404, detail=f"the results file of {study.id} is gone")
    return path


ResultsDep = Annotated[Path, Depends(get_results)]
