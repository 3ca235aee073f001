"""The error answers of the API and how the OpenAPI document lists them.

Every error but 422 has the body ``{"detail": "<what went wrong>"}`` (:class:`ErrorMessage`);
422 has FastAPI's list of field errors. :func:`answers` gives the ``responses=`` entry of a
route for the statuses it can answer, so the document names each of them with its model
and headers.
"""

from __future__ import annotations

from pydantic import BaseModel, Field


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
        "(`DEMSCALE_MAX_ACTIVE`, `DEMSCALE_MAX_ACTIVE_PER_TOKEN`).",
        "headers": {
            "Retry-After": {**_INT_HEADER, "description": "Seconds to wait before trying again."}
        },
    },
}


def answers(*statuses: int) -> dict[int | str, dict]:
    """The OpenAPI ``responses`` of the given error statuses, each with :class:`ErrorMessage`."""
    return {s: {**_ANSWERS[s], "model": ErrorMessage} for s in statuses}
