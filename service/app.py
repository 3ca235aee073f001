"""The FastAPI application. ``create_app()`` is the factory (``uvicorn --factory
service.app:create_app``); with ``DEMSCALE_EMBEDDED_WORKER`` (the default) the app runs one
worker subprocess for as long as it serves."""

from __future__ import annotations

from collections.abc import AsyncIterator
from contextlib import asynccontextmanager

from fastapi import FastAPI, Request
from sqlmodel import func, select

import engine

from .db import engine_for
from .deps import SessionDep
from .embedded import EmbeddedWorker
from .models import Status, Study
from .routes import results, studies
from .settings import Settings, get_settings
from .web import router as web_router

DESCRIPTION = """Coarse-graining studies for cohesive DEM. Submit a study (a fine reference
uniaxial test, coarse radii and scaling rules); a worker runs every run; fetch the summary
(errors against the reference, run time, speed-up), JSON curves, PNG plots and the HDF5 file."""


def create_app(settings: Settings | None = None) -> FastAPI:
    """The API. ``settings`` (default: from the environment) also override the
    ``get_settings`` dependency, so tests can point one app at a temporary store."""
    settings = settings or get_settings()

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        engine_for(settings)  # create the tables before the worker starts
        worker = EmbeddedWorker(settings) if settings.embedded_worker else None
        app.state.worker = worker
        if worker is not None:
            worker.start()
        try:
            yield
        finally:
            if worker is not None:
                worker.stop()

    app = FastAPI(
        title="demscale", version=engine.__version__, description=DESCRIPTION, lifespan=lifespan
    )
    app.dependency_overrides[get_settings] = lambda: settings
    app.state.worker = None
    app.include_router(studies.router)
    app.include_router(results.router)
    app.include_router(web_router)  # the studies web page at /

    @app.get("/healthz", tags=["health"])
    def healthz(request: Request, session: SessionDep) -> dict:
        """Liveness: the database answers; queue counts; the embedded worker's state."""
        counts = dict(session.exec(select(Study.status, func.count()).group_by(Study.status)).all())
        worker = request.app.state.worker
        return {
            "status": "ok",
            "studies": {s.value: counts.get(s, 0) for s in Status},
            "embedded_worker": None if worker is None else worker.alive,
        }

    return app
