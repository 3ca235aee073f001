"""FastAPI dependencies as ``Annotated`` aliases: settings, session, the study of the path,
and the results file of a succeeded study."""

from __future__ import annotations

import uuid
from collections.abc import Iterator
from pathlib import Path
from typing import Annotated

from fastapi import Depends, HTTPException
from sqlmodel import Session

from .db import session_scope
from .models import Status, Study
from .settings import Settings, get_settings

SettingsDep = Annotated[Settings, Depends(get_settings)]


def get_session(settings: SettingsDep) -> Iterator[Session]:
    """A database session for one request."""
    yield from session_scope(settings)


SessionDep = Annotated[Session, Depends(get_session)]


def get_study(study_id: str, session: SessionDep) -> Study:
    """The study of the path; 404 when there is none (a malformed id included)."""
    try:
        key = uuid.UUID(study_id)
    except ValueError:
        key = None
    study = session.get(Study, key) if key is not None else None
    if study is None:
        raise HTTPException(status_code=404, detail=f"no study {study_id}")
    return study


StudyDep = Annotated[Study, Depends(get_study)]


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
