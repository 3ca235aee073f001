"""The FastAPI application. ``create_app()`` is the factory (``uvicorn --factory
service.app:create_app``); with ``DEMSCALE_EMBEDDED_WORKER`` (the default) the app runs one
worker subprocess for as long as it serves.

Every route but ``/healthz`` and the API description needs a bearer token
(:mod:`service.guard`); an app without any configured token refuses to be built.
"""

from __future__ import annotations

import re
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager

from fastapi import FastAPI, Request
from fastapi.exception_handlers import http_exception_handler
from sqlmodel import func, select
from starlette.exceptions import HTTPException as StarletteHTTPException

import engine

from .db import engine_for
from .deps import SessionDep
from .embedded import EmbeddedWorker
from .guard import Guard, Tokens
from .models import Status, Study
from .routes import results, studies
from .settings import ConfigError, Settings, get_settings
from .web import router as web_router
from .weblogin import BrowserLogin

DESCRIPTION = """Coarse-graining studies for cohesive DEM. Submit a study (a fine reference
uniaxial test, coarse radii and scaling rules); a worker runs every run; fetch the summary
(errors against the reference, run time, speed-up), JSON curves, PNG plots and the HDF5 file.

Every route but `/healthz` needs `Authorization: Bearer <token>`; a token sees only the
studies it submitted."""


_METHODS = frozenset({"GET", "PUT", "POST", "DELETE", "OPTIONS", "HEAD", "PATCH", "TRACE"})


def allowed_methods(app: FastAPI, path: str) -> list[str]:
    """The methods the OpenAPI document lists for ``path`` (the ``Allow`` header of a 405:
    Starlette names only those of the first route that matched the path)."""
    methods: set[str] = set()
    for template, operations in app.openapi()["paths"].items():
        pattern = re.sub(r"\\{[^/]+?\\}", "[^/]+", re.escape(template))
        if re.fullmatch(pattern, path):
            methods |= {m.upper() for m in operations if m.upper() in _METHODS}
    return sorted(methods)


def create_app(settings: Settings | None = None) -> FastAPI:
    """The API. ``settings`` (default: from the environment) also override the
    ``get_settings`` dependency, so tests can point one app at a temporary store. Raises
    :class:`service.settings.ConfigError` when no API token is configured."""
    settings = settings or get_settings()
    tokens = Tokens(settings.tokens())
    if not tokens:
        raise ConfigError(
            "no API token: set DEMSCALE_API_TOKEN (one token) or DEMSCALE_API_TOKEN_FILE "
            "(a file of tokens, one per line)"
        )

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
        title="demscale",
        version=engine.__version__,
        description=DESCRIPTION,
        lifespan=lifespan,
        redoc_url=None,  # one API browser: /docs
    )
    app.dependency_overrides[get_settings] = lambda: settings
    app.state.worker = None
    app.add_middleware(Guard, tokens=tokens, max_body_bytes=settings.max_body_bytes)
    app.add_middleware(BrowserLogin)  # outside the guard: the web page's token cookie
    app.include_router(studies.router)
    app.include_router(results.router)
    app.include_router(web_router)  # the studies web page at /

    @app.exception_handler(StarletteHTTPException)
    async def http_error(request: Request, exc: StarletteHTTPException):
        """As FastAPI answers, but a 405 lists every method of the path (Starlette names
        only those of the first route that matched it)."""
        allow = allowed_methods(request.app, request.url.path) if exc.status_code == 405 else []
        if allow:
            exc = StarletteHTTPException(405, exc.detail, headers={"Allow": ", ".join(allow)})
        return await http_exception_handler(request, exc)

    @app.get("/healthz", tags=["health"])
    def healthz(request: Request, session: SessionDep) -> dict:
        """Liveness (no token needed): the database answers; queue counts; the embedded
        worker's state."""
        counts = dict(session.exec(select(Study.status, func.count()).group_by(Study.status)).all())
        worker = request.app.state.worker
        return {
            "status": "ok",
            "studies": {s.value: counts.get(s, 0) for s in Status},
            "embedded_worker": None if worker is None else worker.alive,
        }

    return app
