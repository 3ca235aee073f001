"""Logging a browser in to the studies web page (:mod:`service.web`): the API token in an
HttpOnly, SameSite=Strict cookie, handed to :class:`service.guard.Guard` as a bearer token on
safe requests only. See :class:`BrowserLogin`."""

from __future__ import annotations

import re
from urllib.parse import parse_qs, quote, unquote, urlencode

from .guard import TOO_MANY_FAILURES, Tokens, failure_wait
from .web import templates

#: Name of the cookie that keeps a browser's API token.
COOKIE = "demscale_token"
#: Paths of the pages: asked for without a token, or with a bad one, they go to /login.
_PAGE = re.compile(r"/|/studies/[^/]+/page")
#: What ``next`` may be: a path of this site made of unreserved characters only, one slash
#: between segments. No scheme, host, query, percent sign (so no encoded tab, CR/LF or
#: slash), backslash, whitespace or control character can pass.
_LOCAL_PATH = re.compile(r"/(?:[A-Za-z0-9._~-]+/)*[A-Za-z0-9._~-]*")


def _cookie(headers) -> str | None:
    for name, value in headers:
        if name == b"cookie":
            for part in value.decode("latin-1").split(";"):
                key, _, val = part.strip().partition("=")
                if key == COOKIE and val:
                    return unquote(val)
    return None


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


async def _redirect(send, location: str, cookie: str | None = None) -> None:
    headers = [
        (b"location", location.encode("ascii")),
        (b"content-length", b"0"),
        *_SECURITY_HEADERS,
    ]
    if cookie is not None:
        headers.append((b"set-cookie", cookie.encode()))
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


class BrowserLogin:
    """ASGI middleware in front of :class:`service.guard.Guard`, for people with a browser.

    ``POST /login`` takes the API token in a form and, if it is an accepted token, keeps it in
    an HttpOnly, SameSite=Strict cookie; ``POST /logout`` drops it. Both refuse a request
    that another site sent (:func:`same_origin`), and a token never travels in a URL:
    ``GET /login`` only shows the form (a ``token`` in its query is ignored). A GET or HEAD
    request that carries the cookie and no Authorization header is given the cookie's token
    as its bearer token, and the guard checks it like any other. Only those safe methods: a
    cookie never submits, cancels or deletes a study, so another site cannot make a
    logged-in browser do so. A page asked for without a token, or with one the guard
    refuses, is sent to ``/login``.
    """

    max_form_bytes = 4096

    def __init__(self, app, tokens: Tokens, failures=None):
        self.app = app
        self.tokens = tokens
        self.failures = failures  # wrong tokens per client address (shared with the guard)

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
            token = _cookie(headers)
            if token is not None:
                bearer = b"Bearer " + token.encode("latin-1", "replace")
                scope = {**scope, "headers": [*headers, (b"authorization", bearer)]}
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
                await _redirect(
                    send,
                    "/login?" + urlencode({"next": path, "failed": 1}),
                    self._set_cookie(scope, ""),
                )
            elif not refused:
                await send(message)

        await self.app(scope, receive, to_login)

    @staticmethod
    def _set_cookie(scope, token: str) -> str:
        attrs = "Path=/; HttpOnly; SameSite=Strict"
        if scope.get("scheme") == "https":
            attrs += "; Secure"
        if not token:
            return f"{COOKIE}=; {attrs}; Max-Age=0"
        return f"{COOKIE}={quote(token, safe='')}; {attrs}"

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
        await _redirect(send, "/login", self._set_cookie(scope, ""))

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
            if token and self.tokens.owner(token.encode("utf-8", "replace")) is not None:
                await _redirect(send, target, self._set_cookie(scope, token))
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
