"""What every request passes before it reaches a route: the bearer token and the body size.

:class:`Guard` is a plain ASGI middleware, so that it answers before FastAPI reads a body or
matches a route: a request without a valid token gets 401 on every path but the public ones
(``/healthz`` and the API description), whatever its method, path or body; a body larger
than ``max_body_bytes`` gets 413 whether it announces its length or streams it.

Tokens are compared as SHA-256 digests with :func:`hmac.compare_digest` against every
configured token (no early exit), so the time taken says nothing about how close a guess
was. The request's owner (the token's fingerprint, see
:func:`service.settings.fingerprint`) is left in ``request.state.owner`` for the routes.
"""

from __future__ import annotations

import hashlib
import hmac
import json
import math

from .settings import FINGERPRINT_DIGITS

#: Paths open without a token: the health check (up or down only, unless a valid token
#: comes with it), and the API description (it holds the routes and schemas that are public
#: in the source anyway).
PUBLIC_PATHS = frozenset({"/healthz", "/docs", "/openapi.json"})
#: Prefix of the pages' script and style sheet, open too (they are the repository's files).
PUBLIC_PREFIX = "/static/"


class Tokens:
    """The accepted tokens, kept as SHA-256 digests."""

    def __init__(self, tokens: tuple[str, ...]):
        self._digests = tuple(hashlib.sha256(t.encode()).digest() for t in tokens)
        self._owners = frozenset(d.hex()[:FINGERPRINT_DIGITS] for d in self._digests)

    def __len__(self) -> int:
        return len(self._digests)

    def knows(self, owner: str) -> bool:
        """Whether ``owner`` is the fingerprint of an accepted token (a browser session's
        owner, whose token may have been revoked since it logged in)."""
        return owner in self._owners

    def owner(self, presented: bytes) -> str | None:
        """The fingerprint of ``presented`` if it is an accepted token, else None."""
        digest = hashlib.sha256(presented).digest()
        found = False
        for d in self._digests:  # every one, no early exit
            found |= hmac.compare_digest(digest, d)
        return digest.hex()[:FINGERPRINT_DIGITS] if found else None


async def _answer(send, status: int, detail: str, headers: dict[str, str] | None = None) -> None:
    body = json.dumps({"detail": detail}).encode()
    raw = [(b"content-type", b"application/json"), (b"content-length", str(len(body)).encode())]
    raw += [(k.lower().encode(), v.encode()) for k, v in (headers or {}).items()]
    await send({"type": "http.response.start", "status": status, "headers": raw})
    await send({"type": "http.response.body", "body": body})


def _bearer(headers: list[tuple[bytes, bytes]]) -> bytes | None:
    for name, value in headers:
        if name == b"authorization":
            scheme, _, token = value.strip().partition(b" ")
            if scheme.lower() == b"bearer" and token.strip():
                return token.strip()
            return None
    return None


def client_address(scope) -> str:
    """The client's address as the server saw it (a proxy's own, behind one)."""
    client = scope.get("client")
    return client[0] if client else "unknown"


def failure_wait(failures, scope) -> int:
    """Count a wrong token against the client's address (``failures``: a
    :class:`service.ratelimit.Buckets`, or None for no limit): 0 while within the limit, else
    the seconds to wait, for ``Retry-After``."""
    if failures is None:
        return 0
    wait = failures.take(client_address(scope))
    return max(1, math.ceil(wait)) if wait > 0 else 0


#: What a client past the limit on wrong tokens is told.
TOO_MANY_FAILURES = (
    "too many requests with a wrong token from this address: retry after "
    "{} s (DEMSCALE_AUTH_FAILURE_RATE)"
)


class Guard:
    """ASGI middleware: token check (401 with ``WWW-Authenticate: Bearer``), then body size
    (413)."""

    def __init__(self, app, tokens: Tokens, max_body_bytes: int, failures=None):
        self.app = app
        self.tokens = tokens
        self.max_body = max_body_bytes
        self.failures = failures  # service.ratelimit.Buckets of wrong tokens per address

    async def __call__(self, scope, receive, send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        headers = scope.get("headers", [])
        presented = _bearer(headers)
        owner = None if presented is None else self.tokens.owner(presented)
        if owner is None and presented is None and scope["method"] in ("GET", "HEAD"):
            # a browser's session (service.weblogin: signed, expiring, its token still
            # accepted): it reads, and never submits, cancels or deletes
            owner = scope.get("state", {}).get("session_owner")
        if owner is not None:
            scope.setdefault("state", {})["owner"] = owner
        path = scope["path"]
        if path not in PUBLIC_PATHS and not path.startswith(PUBLIC_PREFIX):
            if owner is None:
                challenge = 'Bearer realm="demscale"'
                if presented is not None:
                    wait = failure_wait(self.failures, scope)
                    if wait:
                        await _answer(
                            send, 429, TOO_MANY_FAILURES.format(wait), {"Retry-After": str(wait)}
                        )
                        return
                    challenge += ', error="invalid_token"'
                detail = "a valid bearer token is required (header 'Authorization: Bearer <token>')"
                await _answer(send, 401, detail, {"WWW-Authenticate": challenge})
                return
        for name, value in headers:
            if name == b"content-length":
                try:
                    length = int(value)
                except ValueError:
                    await _answer(send, 400, "Content-Length is not an integer")
                    return
                if length > self.max_body:
                    await _answer(send, 413, self._too_large())
                    return
        await self._limited(scope, receive, send)

    def _too_large(self) -> str:
        return f"the request body is larger than {self.max_body} bytes (DEMSCALE_MAX_BODY_BYTES)"

    async def _limited(self, scope, receive, send) -> None:
        """Run the app, counting a streamed body (no Content-Length) as the app reads it:
        past the limit the client gets 413, the app a disconnect, and its answer is dropped."""
        seen, answered = 0, False

        async def counted():
            nonlocal seen, answered
            message = await receive()
            if message["type"] == "http.request" and not answered:
                seen += len(message.get("body", b""))
                if seen > self.max_body:
                    answered = True
                    await _answer(send, 413, self._too_large())
                    return {"type": "http.disconnect"}
            return message

        async def sending(message) -> None:
            if not answered:
                await send(message)

        await self.app(scope, counted, sending)
