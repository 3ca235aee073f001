"""What a JSON request body must be before FastAPI reads it: UTF-8 JSON (RFC 8259), sent as
``application/json``; anything else is a 400 naming what is wrong (docs/SERVICE.md).

FastAPI would take a UTF-16 or UTF-32 body (Python's JSON parser guesses the encoding from
the first bytes), answer a syntax error with a 422 at ``["body", <byte>]``, and pass the
raw bytes of a body sent without a JSON media type to the model, whose 422 answer then
cannot encode them. :class:`JsonBody` reads the body (the guard has bounded its size),
decodes it as strict UTF-8 and parses it once, and hands the same bytes on; 422 stays the
answer for a body that parses but whose fields are wrong.
"""

from __future__ import annotations

import json

from .guard import _answer

#: The methods whose body is a JSON document (the API's only ones are POSTs).
_WITH_BODY = frozenset({"POST", "PUT", "PATCH"})
#: Path prefixes whose POST bodies are JSON (the login form posts a form, elsewhere).
JSON_PATHS = ("/studies", "/calibrations")


def _media_type(headers) -> str | None:
    for name, value in headers:
        if name == b"content-type":
            return value.decode("latin-1").split(";", 1)[0].strip().lower()
    return None


def body_problem(body: bytes, media_type: str | None) -> str | None:
    """Why ``body`` (sent as ``media_type``) is not a UTF-8 JSON document, in words; None
    when it is one (or empty: FastAPI then reports the missing body as a 422)."""
    if not body:
        return None
    if media_type is not None and not (
        media_type == "application/json"
        or (media_type.startswith("application/") and media_type.endswith("+json"))
    ):
        return f"the body is sent as {media_type!r}: send it as application/json (UTF-8 JSON)"
    try:
        text = body.decode("utf-8")
    except UnicodeDecodeError as e:
        return (
            f"the body is not UTF-8 (byte {body[e.start]:#04x} at position {e.start}): "
            "JSON is sent as UTF-8 (RFC 8259)"
        )
    if text.startswith("\ufeff"):
        return "the body starts with a byte order mark: send UTF-8 JSON without one"
    try:
        json.loads(text)
    except json.JSONDecodeError as e:
        return f"the body is not JSON: {e.msg} at line {e.lineno}, column {e.colno}"
    except RecursionError:
        return "the body is not JSON this API reads: nested too deeply"
    return None


class JsonBody:
    """ASGI middleware inside the guard and the submission rate limit: a POST to the API's
    JSON paths whose body is not UTF-8 JSON gets 400 ``{"detail": ...}``; any other request
    passes untouched."""

    def __init__(self, app):
        self.app = app

    async def __call__(self, scope, receive, send) -> None:
        if (
            scope["type"] != "http"
            or scope["method"] not in _WITH_BODY
            or not scope["path"].startswith(JSON_PATHS)
        ):
            await self.app(scope, receive, send)
            return
        chunks, more = [], True
        while more:
            message = await receive()
            if message["type"] != "http.request":  # the client went away (or the guard's 413)
                await self.app(scope, _replay([message], receive), send)
                return
            chunks.append(message.get("body", b""))
            more = message.get("more_body", False)
        body = b"".join(chunks)
        problem = body_problem(body, _media_type(scope.get("headers", [])))
        if problem is not None:
            await _answer(send, 400, problem)
            return
        await self.app(scope, _replay([{"type": "http.request", "body": body}], receive), send)


def _replay(messages: list[dict], receive):
    """A ``receive`` that gives ``messages``, then what the client sends next (a
    disconnect)."""
    pending = list(messages)

    async def replayed():
        return pending.pop(0) if pending else await receive()

    return replayed
