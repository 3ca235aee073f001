"""Logging a browser in to the studies web page (:mod:`service.web`): the API token in an
HttpOnly, SameSite=Strict cookie, handed to :class:`service.guard.Guard` as a bearer token on
safe requests only. See :class:`BrowserLogin`."""

from __future__ import annotations

import re
from urllib.parse import parse_qs, quote, unquote, urlencode

from .web import templates

#: Name of the cookie that keeps a browser's API token.
COOKIE = "demscale_token"
#: Paths of the pages: asked for without a token, or with a bad one, they go to /login.
_PAGE = re.compile(r"/|/studies/[^/]+/page")


def _cookie(headers) -> str | None:
    for name, value in headers:
        if name == b"cookie":
            for part in value.decode("latin-1").split(";"):
                key, _, val = part.strip().partition("=")
                if key == COOKIE and val:
                    return unquote(val)
    return None


def _next(target: str | None) -> str:
    """Where to go after logging in: a local path only (no open redirect)."""
    if target and target.startswith("/") and not target.startswith("//") and "\\" not in target:
        return target
    return "/"


async def _redirect(send, location: str, cookie: str | None = None) -> None:
    headers = [(b"location", location.encode()), (b"content-length", b"0"),
               (b"cache-control", b"no-store")]
    if cookie is not None:
        headers.append((b"set-cookie", cookie.encode()))
    await send({"type": "http.response.start", "status": 303, "headers": headers})
    await send({"type": "http.response.body", "body": b""})


async def _html(send, status: int, html: str) -> None:
    body = html.encode()
    await send({"type": "http.response.start", "status": status, "headers": [
        (b"content-type", b"text/html; charset=utf-8"),
        (b"content-length", str(len(body)).encode()), (b"cache-control", b"no-store")]})
    await send({"type": "http.response.body", "body": body})


class BrowserLogin:
    """ASGI middleware in front of :class:`service.guard.Guard`, for people with a browser.

    ``/login`` takes the API token in a form (or as ``?token=`` in a link, as a local server
    prints it) and keeps it in an HttpOnly, SameSite=Strict cookie; ``/logout`` drops it. A
    GET or HEAD request that carries the cookie and no Authorization header is given the
    cookie's token as its bearer token, and the guard checks it like any other. Only those
    safe methods: a cookie never submits, cancels or deletes a study, so another site cannot
    make a logged-in browser do so. A page asked for without a token, or with one the guard
    refuses, is sent to ``/login``.
    """

    max_form_bytes = 4096

    def __init__(self, app):
        self.app = app

    async def __call__(self, scope, receive, send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        path, method = scope["path"], scope["method"]
        if path == "/login":
            await self._login(scope, receive, send)
            return
        if path == "/logout":
            await _redirect(send, "/login", self._set_cookie(scope, ""))
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
                await _redirect(send, "/login?" + urlencode({"next": path, "failed": 1}),
                                self._set_cookie(scope, ""))
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

    async def _login(self, scope, receive, send) -> None:
        query = parse_qs(scope.get("query_string", b"").decode("latin-1"))
        target = _next(query.get("next", [None])[0])
        token = query.get("token", [None])[0]
        if scope["method"] == "POST":
            body = b""
            while True:
                message = await receive()
                body += message.get("body", b"")
                if len(body) > self.max_form_bytes:
                    await _html(send, 413, "the login form is too large")
                    return
                if not message.get("more_body"):
                    break
            form = parse_qs(body.decode("utf-8", "replace"))
            token = form.get("token", [""])[0].strip()
            target = _next(form.get("next", [target])[0])
        if token:
            await _redirect(send, target, self._set_cookie(scope, token))
            return
        html = templates.get_template("login.html").render(
            next=target, failed="failed" in query)
        await _html(send, 200, html)
