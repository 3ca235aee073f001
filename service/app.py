"""The FastAPI application. ``create_app()`` is the factory (``uvicorn --factory
service.app:create_app``); with ``DEMSCALE_EMBEDDED_WORKER`` (the default) the app runs one
worker subprocess for as long as it serves.

Every route but ``/healthz`` and the API description needs a bearer token
(:mod:`service.guard`); an app without any configured token refuses to be built.
"""

from __future__ import annotations

import json
import logging
import re
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from pathlib import Path

from fastapi import FastAPI, Request
from fastapi.exception_handlers import http_exception_handler
from fastapi.exceptions import RequestValidationError
from fastapi.responses import HTMLResponse, JSONResponse
from fastapi.staticfiles import StaticFiles
from markupsafe import Markup, escape
from sqlmodel import Session, func, select
from starlette.exceptions import HTTPException as StarletteHTTPException

import engine

from .body import JsonBody
from .db import engine_for
from .embedded import EmbeddedWorker
from .errors import validation_error
from .guard import Guard, Tokens
from .headers import SecurityHeaders
from .models import Status, Study
from .ratelimit import Buckets, SubmitRateLimit
from .routes import calibrations, plans, results, studies
from .settings import ConfigError, Settings, get_settings, secure_data_dir, session_secret
from .web import router as web_router
from .web import templates
from .weblogin import BrowserLogin, SessionCookie

log = logging.getLogger("demscale.api")

#: The pages' script, style sheet (and nothing else): served without a token.
STATIC_DIR = Path(__file__).parent / "static"

DESCRIPTION = """Coarse-graining studies for cohesive DEM. Submit a study (a fine reference
uniaxial test, coarse radii and scaling rules); a worker runs every run; fetch the summary
(errors against the reference, run time, speed-up), JSON curves, PNG plots and the HDF5 file.

Every route but `/healthz` (up or down only, without a token) and this description needs
`Authorization: Bearer <token>`; a token sees only the studies it submitted."""


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


def _kind(schema: dict) -> Markup:
    """A schema's type in words for the docs page (a reference links to its schema)."""
    if not isinstance(schema, dict):
        return escape("any")
    if "$ref" in schema:
        name = schema["$ref"].rsplit("/", 1)[-1]
        return Markup('<a href="#schema-{0}">{0}</a>').format(name)
    for key in ("anyOf", "oneOf"):
        if key in schema:
            return Markup(" or ").join(_kind(s) for s in schema[key])
    if schema.get("type") == "array":
        return Markup("list of ") + _kind(schema.get("items", {}))
    if schema.get("type") == "object" and "additionalProperties" in schema:
        return Markup("object of ") + _kind(schema["additionalProperties"])
    if "const" in schema:
        return escape(json.dumps(schema["const"]))
    if "enum" in schema:
        return escape(" | ".join(json.dumps(v) for v in schema["enum"]))
    return escape(schema.get("type", "any"))


def _default(schema: dict) -> str:
    if "default" not in schema:
        return ""
    text = json.dumps(schema["default"])
    return text if len(text) <= 80 else text[:77] + "..."


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
        secure_data_dir(settings)  # the database 0600, the data directory 0700
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
        docs_url=None,  # the service's own page (below): no script or style from a CDN
        redoc_url=None,
    )
    app.dependency_overrides[get_settings] = lambda: settings
    app.state.worker = None
    # innermost: a body that is not UTF-8 JSON is a 400 before FastAPI reads it
    app.add_middleware(JsonBody)
    # inside the guard (it knows the owner): a token's submissions, refused ones included
    app.add_middleware(
        SubmitRateLimit, per_minute=settings.submit_rate, burst=settings.submit_burst
    )
    # wrong tokens per client address, the header's and the login form's in one bucket
    failures = Buckets(settings.auth_failure_rate, settings.auth_failure_burst)
    app.add_middleware(
        Guard, tokens=tokens, max_body_bytes=settings.max_body_bytes, failures=failures
    )
    # outside the guard: the pages' login, in a signed, expiring session cookie
    app.add_middleware(
        BrowserLogin, tokens=tokens, failures=failures, max_age=settings.session_max_age
    )
    app.add_middleware(
        SessionCookie, secret_key=session_secret(settings), max_age=settings.session_max_age
    )
    app.add_middleware(SecurityHeaders)  # outermost: on every answer, the guard's too
    app.mount("/static", StaticFiles(directory=STATIC_DIR), name="static")
    app.include_router(studies.router)
    app.include_router(calibrations.router)
    app.include_router(results.router)
    app.include_router(plans.router)
    app.include_router(web_router)  # the studies web page at /

    app.add_exception_handler(RequestValidationError, validation_error)

    @app.exception_handler(StarletteHTTPException)
    async def http_error(request: Request, exc: StarletteHTTPException):
        """As FastAPI answers, but a 405 lists every method of the path (Starlette names
        only those of the first route that matched it)."""
        allow = allowed_methods(request.app, request.url.path) if exc.status_code == 405 else []
        if allow:
            exc = StarletteHTTPException(405, exc.detail, headers={"Allow": ", ".join(allow)})
        return await http_exception_handler(request, exc)

    @app.get("/docs", include_in_schema=False, response_class=HTMLResponse)
    def docs(request: Request) -> HTMLResponse:
        """The API described from its OpenAPI document, drawn here (no CDN, no script)."""
        return templates.TemplateResponse(
            request,
            "docs.html",
            {
                "api": request.app.openapi(),
                "kind": _kind,
                "default": _default,
                "base": str(request.base_url),
            },
        )

    @app.get("/healthz", tags=["health"], responses={503: {"description": "Down."}})
    def healthz(request: Request):
        """Liveness: ``{"status": "ok"}`` when the database answers, 503 ``down`` when not.
        Without a token that is all; with one, also the counts of that token's studies per
        status and whether the embedded worker is alive."""
        owner = getattr(request.state, "owner", None)
        try:
            with Session(engine_for(settings)) as session:
                query = select(Study.status, func.count()).group_by(Study.status)
                if owner is not None:
                    query = query.where(Study.owner == owner)
                counts = dict(session.exec(query).all())
        except Exception:  # the store does not answer: down, whatever the reason
            log.exception("health check: the database does not answer")
            return JSONResponse({"status": "down"}, status_code=503)
        if owner is None:
            return {"status": "ok"}
        worker = request.app.state.worker
        return {
            "status": "ok",
            "studies": {s.value: counts.get(s, 0) for s in Status},
            "embedded_worker": None if worker is None else worker.alive,
        }

    return app
