"""The error answers of the API and how the OpenAPI document lists them.

Every error but 422 has the body ``{"detail": "<what went wrong>"}`` (:class:`ErrorMessage`);
422 has FastAPI's list of field errors. :func:`answers` gives the ``responses=`` entry of a
route for the statuses it can answer, so the document names each of them with its model
and headers.
"""

from __future__ import annotations

import math
from typing import Any

from fastapi.encoders import jsonable_encoder
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from pydantic import BaseModel, Field

from engine.contact.registry import LAWS
from engine.study.spec import TEST_TYPES

from .jsonsafe import finite


class ErrorMessage(BaseModel):
    """An error: what went wrong, in words."""

    detail: str = Field(description="What went wrong.")


_INT_HEADER = {"schema": {"type": "integer"}, "required": True}

_ANSWERS: dict[int, dict] = {
    400: {"description": "The body cannot be parsed (not UTF-8 JSON)."},
    401: {
        "description": "No valid bearer token (header `Authorization: Bearer <token>`).",
        "headers": {
            "WWW-Authenticate": {
                "description": 'The scheme to use: `Bearer realm="demscale"`.',
                "schema": {"type": "string"},
                "required": True,
            }
        },
    },
    404: {"description": "No such study for this token (or no such run, stage or file)."},
    409: {"description": "The study is not in a status that allows this."},
    413: {"description": "The request body is larger than `DEMSCALE_MAX_BODY_BYTES`."},
    429: {
        "description": "Too many queued or running studies, in all or of this token "
        "(`DEMSCALE_MAX_ACTIVE`, `DEMSCALE_MAX_ACTIVE_PER_TOKEN`), or too many submissions "
        "of this token in a short time (`DEMSCALE_SUBMIT_RATE` a minute, bursts of "
        "`DEMSCALE_SUBMIT_BURST`).",
        "headers": {
            "Retry-After": {**_INT_HEADER, "description": "Seconds to wait before trying again."}
        },
    },
    507: {
        "description": "The token's studies would take more disk than "
        "`DEMSCALE_MAX_STORAGE_PER_TOKEN`: delete finished studies first."
    },
}


def answers(*statuses: int) -> dict[int | str, dict]:
    """The OpenAPI ``responses`` of the given error statuses, each with :class:`ErrorMessage`."""
    return {s: {**_ANSWERS[s], "model": ErrorMessage} for s in statuses}


def _non_finite_paths(value: Any, loc: tuple = ()) -> list[tuple]:
    """Where in a parsed body a NaN or an infinity sits."""
    if isinstance(value, float) and not math.isfinite(value):
        return [loc]
    if isinstance(value, dict):
        return [p for k, v in value.items() for p in _non_finite_paths(v, (*loc, k))]
    if isinstance(value, (list, tuple)):
        return [p for i, v in enumerate(value) for p in _non_finite_paths(v, (*loc, i))]
    return []


async def validation_error(request, exc: RequestValidationError) -> JSONResponse:
    """FastAPI's 422 answer, always serialisable: a non-finite number anywhere in the body
    (Python's JSON parser takes ``NaN`` and ``Infinity``, which JSON does not have) gets an
    error of its own at its field, type ``finite_number``, and the echoed inputs are made
    finite (:func:`finite`)."""
    errors = [{**e, "loc": _reference_untagged(e.get("loc", ()))} for e in exc.errors()]
    errors = jsonable_encoder(errors)
    seen = {untagged(e.get("loc", ())) for e in errors}
    body = getattr(exc, "body", None)
    for path in _non_finite_paths(body):
        loc = ("body", *path)
        if untagged(loc) not in seen:
            errors.append(
                {
                    "type": "finite_number",
                    "loc": list(loc),
                    "msg": "Input should be a finite number (JSON has no NaN or Infinity)",
                    "input": body_at(body, path),
                }
            )
    return JSONResponse(status_code=422, content={"detail": finite(errors)})


#: The kinds of a study's reference (``"type"``: "UniaxialTest", the default, or
#: "ShearTest"): pydantic's tag after ``reference`` is left out of a 422's ``loc``, so that a
#: field of the reference is at ``["body", "reference", <field>]`` whatever its kind.
TEST_TAGS = frozenset(TEST_TYPES)
#: The tags pydantic puts into the ``loc`` of an error inside a tagged union (the contact
#: laws: ``["body", "reference", "pair_law", "EEPA", "n"]``), where the body has none.
UNION_TAGS = frozenset(LAWS) | TEST_TAGS


def _reference_untagged(loc) -> tuple:
    """``loc`` without the reference kind's tag right after ``reference``."""
    loc = tuple(loc)
    return tuple(
        p for i, p in enumerate(loc) if not (i and p in TEST_TAGS and loc[i - 1] == "reference")
    )


def untagged(loc) -> tuple:
    """``loc`` as a path into the body: the union tags pydantic adds left out, so that a
    field is one place however its error was found."""
    return tuple(p for p in loc if p not in UNION_TAGS)


def body_at(body: Any, path: tuple) -> Any:
    for key in path:
        body = body[key]
    return body
