"""Logging a browser in to the studies web page (:mod:`service.web`): a signed, expiring
session cookie (Starlette's :class:`~starlette.middleware.sessions.SessionMiddleware`, signed
with itsdangerous) that holds the token's fingerprint, never the token; the guard takes it as
the caller's identity on safe requests only. See :class:`BrowserLogin`."""

from __future__ import annotations

import re
import time
from urllib.parse import parse_qs, urlencode

from starlette.middleware.sessions import SessionMiddleware

from .guard import TOO_MANY_FAILURES, Tokens, failure_wait
from .web import templates

#: Name of the pages' session cookie.
COOKIE = "demscale_session"
#: Paths of the pages: asked for without a token, or with a bad one, they go to /login.
_PAGE = re.compile(r"/|/studies/[^/]+/page")
#: What ``next`` may be: a path of this site made of unreserved characters only, one slash
#: between segments. No scheme, host, query, percent sign (so no encoded tab, CR/LF or
#: slash), backslash, whitespace or control character can pass.
_LOCAL_PATH = re.compile(r"/(?:[A-Za-z0-9._~-]+/)*[A-Za-z0-9._~-]*")


def safe_next(target: str | None) -> str:
    """Where to go after logging in: a path of this site (:data:`_LOCAL_PATH`), else ``/``.
    Anything a browser could read as another site (``//host``, ``/\\host``, ``/%09/host``,
    which browsers turn into ``//host`` by dropping the tab) is refused, as is a CR or LF
    that would break the ``Location`` header."""
    if target and len(target) <= 512 and _LOCAL_PATH.fullmatch(target):
        return target
    return "/"


def _header(headers, name: bytes) -> str | None:
    for key, value in headers:
        if key == name:
            return value.decode("latin-1")
    return None


def same_origin(scope) -> bool:
    """Whether a state-changing request (login, logout) comes from this site's own page.

    A browser names the page that sent a form. ``Sec-Fetch-Site`` (every current browser
    sends it) decides when present: ``same-origin``, or ``none`` for a request the user
    made by hand. Without it, ``Origin`` (scheme, host and port) must name this host (the
    ``Host`` header; the scheme is left out, as a TLS proxy in front makes the page https
    and the app http). Anything else refuses the request (login CSRF: another site's form
    logging the browser in as the attacker's token, or out). A client that sends neither
    (curl, a script) is no browser another site can drive, and is let through."""
    headers = scope.get("headers", [])
    site = _header(headers, b"sec-fetch-site")
    if site is not None:
        return site in ("same-origin", "none")
    origin = _header(headers, b"origin")
    if origin is None:
        return True
    host = _header(headers, b"host")
    scheme, sep, netloc = origin.partition("://")
    return bool(sep) and scheme in ("http", "https") and host is not None and netloc == host


#: The rest (CSP, frame, nosniff, referrer) come from :class:`service.headers.SecurityHeaders`.
_SECURITY_HEADERS = [(b"cache-control", b"no-store")]


async def _redirect(send, location: str) -> None:
    headers = [
        (b"location", location.encode("ascii")),
        (b"content-length", b"0"),
        *_SECURITY_HEADERS,
    ]
    await send({"type": "http.response.start", "status": 303, "headers": headers})
    await send({"type": "http.response.body", "body": b""})


async def _html(send, status: int, html: str, extra: list | None = None) -> None:
    body = html.encode()
    await send(
        {
            "type": "http.response.start",
            "status": status,
            "headers": [
                (b"content-type", b"text/html; charset=utf-8"),
                (b"content-length", str(len(body)).encode()),
                *_SECURITY_HEADERS,
                *(extra or []),
            ],
        }
    )
    await send({"type": "http.response.body", "body": body})


class SessionCookie:
    """Starlette's :class:`SessionMiddleware` (the session a signed, timestamped cookie:
    itsdangerous; HttpOnly, SameSite=Strict, ``max_age`` seconds) with the ``Secure`` flag on
    the requests that came over https (one middleware of each kind, picked per request)."""

    def __init__(self, app, secret_key: str, max_age: int):
        kw = {"session_cookie": COOKIE, "max_age": max_age, "same_site": "strict"}
        self.plain = SessionMiddleware(app, secret_key, https_only=False, **kw)
        self.secure = SessionMiddleware(app, secret_key, https_only=True, **kw)

    async def __call__(self, scope, receive, send) -> None:
        https = scope["type"] == "http" and scope.get("scheme") == "https"
        await (self.secure if https else self.plain)(scope, receive, send)


class BrowserLogin:
    """ASGI middleware in front of :class:`service.guard.Guard` and inside
    :class:`SessionCookie`, for people with a browser.

    ``POST /login`` takes the API token in a form and, if it is an accepted token, starts a
    session that holds the token's fingerprint (the token itself is never in the cookie: a
    stolen cookie is not a token, and it expires); ``POST /logout`` ends it. Both refuse a
    request that another site sent (:func:`same_origin`), and a token never travels in a
    URL: ``GET /login`` only shows the form (a ``token`` in its query is ignored). A GET or
    HEAD request with a live session and no Authorization header is the session's token's
    (``state.session_owner``, which the guard takes on those methods only), if that token is
    still accepted. Only those safe methods: a session never submits, cancels or deletes a
    study, so another site cannot make a logged-in browser do so. A page asked for without a
    session, or with one the guard refuses, is sent to ``/login``.
    """

    max_form_bytes = 4096

    def __init__(self, app, tokens: Tokens, failures=None, max_age: int = 8 * 3600):
        self.app = app
        self.tokens = tokens
        self.failures = failures  # wrong tokens per client address (shared with the guard)
        self.max_age = max_age  # a session's whole life [s], however active

    async def __call__(self, scope, receive, send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        path, method = scope["path"], scope["method"]
        if path == "/login":
            await self._login(scope, receive, send)
            return
        if path == "/logout":
            await self._logout(scope, send)
            return
        headers = scope.get("headers", [])
        page = method in ("GET", "HEAD") and _PAGE.fullmatch(path) is not None
        if method in ("GET", "HEAD") and not any(n == b"authorization" for n, _ in headers):
            owner = self._session_owner(scope)
            if owner is not None:
                scope.setdefault("state", {})["session_owner"] = owner
            elif page:
                await _redirect(send, "/login?" + urlencode({"next": path}))
                return
        if not page:
            await self.app(scope, receive, send)
            return

        refused = False

        async def to_login(message) -> None:
            nonlocal refused
            if message["type"] == "http.response.start" and message["status"] == 401:
                refused = True
                scope.get("session", {}).clear()
                await _redirect(send, "/login?" + urlencode({"next": path, "failed": 1}))
            elif not refused:
                await send(message)

        await self.app(scope, receive, to_login)

    def _session_owner(self, scope) -> str | None:
        """The fingerprint of the session's token, while the session is young enough and its
        token still accepted (tokens are read at start: a revoked one ends its sessions);
        else None, and the session is ended."""
        session = scope.get("session")
        if not session:
            return None
        owner, since = session.get("owner"), session.get("since")
        fresh = isinstance(since, (int, float)) and 0 <= time.time() - since <= self.max_age
        if isinstance(owner, str) and fresh and self.tokens.knows(owner):
            return owner
        session.clear()
        return None

    async def _form(self, receive, send) -> dict | None:
        body = b""
        while True:
            message = await receive()
            body += message.get("body", b"")
            if len(body) > self.max_form_bytes:
                await _html(send, 413, "the login form is too large")
                return None
            if not message.get("more_body"):
                break
        return parse_qs(body.decode("utf-8", "replace"))

    async def _logout(self, scope, send) -> None:
        if scope["method"] != "POST":
            await _html(
                send,
                405,
                "log out with the button of the page (POST /logout)",
                [(b"allow", b"POST")],
            )
            return
        if not same_origin(scope):
            await _html(send, 403, "logging out is only possible from this site's pages")
            return
        scope.get("session", {}).clear()  # the cookie is expired with it
        await _redirect(send, "/login")

    async def _login(self, scope, receive, send) -> None:
        query = parse_qs(scope.get("query_string", b"").decode("latin-1"))
        target = safe_next(query.get("next", [None])[0])
        failed = "failed" in query
        method = scope["method"]
        if method == "POST":
            if not same_origin(scope):
                await _html(send, 403, "logging in is only possible from this site's login page")
                return
            form = await self._form(receive, send)
            if form is None:
                return
            token = form.get("token", [""])[0].strip()
            target = safe_next(form.get("next", [target])[0])
            owner = self.tokens.owner(token.encode("utf-8", "replace")) if token else None
            if owner is not None:
                # the session holds who logged in and when, signed; never the token
                session = scope["session"]
                session.clear()
                session.update({"owner": owner, "since": int(time.time())})
                await _redirect(send, target)
                return
            failed = True  # no cookie for a token the guard would refuse
            wait = failure_wait(self.failures, scope)
            if wait:
                await _html(
                    send,
                    429,
                    TOO_MANY_FAILURES.format(wait),
                    [(b"retry-after", str(wait).encode())],
                )
                return
        elif method not in ("GET", "HEAD"):
            await _html(
                send,
                405,
                "GET shows the login form, POST sends it",
                [(b"allow", b"GET, HEAD, POST")],
            )
            return
        html = templates.get_template("login.html").render(next=target, failed=failed)
        await _html(send, 401 if failed and method == "POST" else 200, html)
