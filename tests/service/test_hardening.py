"""Issue 22's findings against the API, each reproduced (no worker runs): non-finite JSON,
the login page's tricks (open redirect, a token in a URL, a cookie for any token, login
CSRF), the security headers and the service's own API description, the token file and data
directory permissions, ``/healthz`` without a token."""

from __future__ import annotations

import base64
import json
import os
import re
import stat
import time
from types import SimpleNamespace

import pytest
from fastapi.testclient import TestClient
from pydantic import SecretStr

from service.app import create_app
from service.headers import CONTENT_SECURITY_POLICY
from service.settings import ConfigError

from .conftest import AUTH, TINY, TOKEN

JSON = {"content-type": "application/json"}


# --- non-finite JSON -------------------------------------------------------------------

NON_FINITE = [
    # (body, loc of the error)
    ('{"name": NaN}', ["body", "name"]),
    ('{"reference": {"radius": Infinity}}', ["body", "reference", "radius"]),
    ('{"reference": {"density": -Infinity}}', ["body", "reference", "density"]),
    ('{"coarse_radii": [NaN]}', ["body", "coarse_radii", 0]),
    ('{"tolerances": {"density": NaN}}', ["body", "tolerances", "density"]),
    (
        '{"reference": {"pair_law": {"k1": Infinity}}}',
        ["body", "reference", "pair_law", "BilinearAdhesive", "k1"],
    ),
    (
        '{"rules": [{"name": "x", "adhesion_exponent": NaN}]}',
        ["body", "rules", 0, "adhesion_exponent"],
    ),
    ('{"reference": NaN}', ["body", "reference"]),
    ('{"seeds": [NaN]}', ["body", "seeds", 0]),
    ("NaN", ["body"]),
]


@pytest.mark.timeout(60)
@pytest.mark.parametrize("body,loc", NON_FINITE, ids=[b for b, _ in NON_FINITE])
def test_non_finite_json_is_422_naming_the_field(settings, body, loc):
    with TestClient(create_app(settings), headers=AUTH, raise_server_exceptions=False) as c:
        r = c.post("/studies", content=body, headers=JSON)
        assert r.status_code == 422, r.text
        errors = r.json()["detail"]  # strict JSON: the echoed input is text
        assert any(e["loc"] == loc for e in errors), errors
        assert "NaN" in r.text or "Infinity" in r.text
        assert c.get("/studies").json()["count"] == 0


@pytest.mark.timeout(60)
def test_a_non_finite_number_anywhere_is_named_even_beside_other_errors(client):
    body = '{"reference": {"radius": -1e-3, "density": NaN}, "colour": Infinity}'
    r = client.post("/studies", content=body, headers=JSON)
    assert r.status_code == 422, r.text
    locs = [e["loc"] for e in r.json()["detail"]]
    assert ["body", "reference", "density"] in locs and ["body", "colour"] in locs


# --- login -----------------------------------------------------------------------------

TRICKS = [
    "//evil.example/",
    "/\\evil.example",
    "/%09/evil.example",
    "/%2F/evil.example",
    "http://evil.example/",
    "https:evil.example",
    "/\t/evil.example",
    "/ /evil.example",
    "/a\r\nSet-Cookie: x=1",
    "/a\nb",
    "/\x00",
    "javascript:alert(1)",
    "/%5Cevil.example",
    "/studies/x/page?next=//evil",
    "\\\\evil.example",
    "/é",
    "/" + "a" * 600,
]


@pytest.fixture
def browser(settings):
    """A TestClient without the token header, not following redirects (a browser)."""
    with TestClient(
        create_app(settings), follow_redirects=False, raise_server_exceptions=False
    ) as c:
        yield c


@pytest.mark.timeout(60)
@pytest.mark.parametrize("target", TRICKS, ids=[repr(t)[:30] for t in TRICKS])
def test_login_next_goes_only_to_a_path_of_this_site(browser, target):
    r = browser.post("/login", data={"token": TOKEN, "next": target})
    assert r.status_code == 303 and r.headers["location"] == "/", r.headers
    # asked for in the query of the form page, it is dropped from the form too
    form = browser.get("/login", params={"next": target})
    assert form.status_code == 200
    assert 'name="next" value="/"' in form.text


@pytest.mark.timeout(60)
def test_login_next_keeps_a_local_page(browser):
    r = browser.post("/login", data={"token": TOKEN, "next": "/studies/ab-12/page"})
    assert r.status_code == 303 and r.headers["location"] == "/studies/ab-12/page"


@pytest.mark.timeout(60)
def test_login_by_post_only_and_only_for_an_accepted_token(browser):
    # a token in the URL logs nobody in, nor out
    r = browser.get(f"/login?token={TOKEN}&next=/")
    assert r.status_code == 200 and "set-cookie" not in r.headers
    r = browser.get("/login?token=")
    assert "set-cookie" not in r.headers
    # a wrong token sets no cookie
    r = browser.post("/login", data={"token": "not-the-token-0123456789"})
    assert r.status_code == 401 and "set-cookie" not in r.headers
    assert "not accepted" in r.text
    r = browser.post("/login", data={"token": ""})
    assert r.status_code == 401 and "set-cookie" not in r.headers
    # the right one does
    r = browser.post("/login", data={"token": TOKEN})
    cookie = r.headers["set-cookie"]
    assert r.status_code == 303 and cookie.startswith("demscale_session=")
    assert "samesite=strict" in cookie.lower() and "httponly" in cookie.lower()
    # a session, not the token: signed (itsdangerous), expiring, and holding no token
    assert TOKEN not in cookie and f"Max-Age={8 * 3600}" in cookie
    value = cookie.split(";")[0].split("=", 1)[1]
    assert "." in value  # payload.timestamp.signature
    # logging out is a POST as well; a GET link changes nothing
    r = browser.get("/logout")
    assert r.status_code == 405 and "expires=Thu, 01 Jan 1970" not in r.headers.get(
        "set-cookie", ""
    )
    assert browser.put("/login").status_code == 405


@pytest.mark.timeout(60)
@pytest.mark.parametrize(
    "headers",
    [
        {"origin": "http://evil.example"},
        {"origin": "null"},
        {"origin": "http://testserver.evil.example"},
        {"sec-fetch-site": "cross-site"},
        {"sec-fetch-site": "same-site", "origin": "http://testserver"},
    ],
)
def test_login_and_logout_from_another_site_are_refused(browser, headers):
    r = browser.post("/login", data={"token": TOKEN}, headers=headers)
    assert r.status_code == 403 and "set-cookie" not in r.headers
    r = browser.post("/logout", headers=headers)
    assert r.status_code == 403 and "set-cookie" not in r.headers


@pytest.mark.timeout(60)
def test_login_from_its_own_page_is_accepted(browser):
    own = {"origin": "http://testserver", "sec-fetch-site": "same-origin"}
    r = browser.post("/login", data={"token": TOKEN}, headers=own)
    assert r.status_code == 303 and "set-cookie" in r.headers
    r = browser.post("/logout", headers=own)
    assert r.status_code == 303 and "expires=Thu, 01 Jan 1970" in r.headers["set-cookie"]
    # behind a proxy that rewrites Host, the browser's Sec-Fetch-Site still decides
    proxied = {"origin": "https://demscale.example.org", "sec-fetch-site": "same-origin"}
    assert browser.post("/login", data={"token": TOKEN}, headers=proxied).status_code == 303
    # an older browser without Sec-Fetch-Site: its Origin must name this host
    assert (
        browser.post(
            "/login", data={"token": TOKEN}, headers={"origin": "https://testserver"}
        ).status_code
        == 303
    )


def test_no_command_prints_a_login_url_with_the_token():
    import inspect

    import demscale.commands.job
    import demscale.commands.serve

    for module in (demscale.commands.serve, demscale.commands.job):
        assert "login?token" not in inspect.getsource(module), module


# --- headers and the API description ---------------------------------------------------


@pytest.mark.timeout(60)
@pytest.mark.parametrize("path", ["/", "/login", "/docs", "/studies/x/page", "/studies"])
def test_every_answer_has_the_security_headers(client, browser, path):
    for c in (client, browser):  # with the token and without it (redirects, 401s)
        r = c.get(path)
        assert r.headers["content-security-policy"] == CONTENT_SECURITY_POLICY
        assert r.headers["x-frame-options"] == "DENY"
        assert r.headers["x-content-type-options"] == "nosniff"
        assert r.headers["referrer-policy"] == "no-referrer"
    assert "frame-ancestors 'none'" in CONTENT_SECURITY_POLICY
    assert "'unsafe-inline'" not in CONTENT_SECURITY_POLICY


@pytest.mark.timeout(60)
def test_pages_have_no_inline_script_or_style_and_load_nothing_from_elsewhere(client):
    sid = client.post("/studies", json=TINY).json()["id"]
    for path in ("/", f"/studies/{sid}/page", "/login", "/docs"):
        html = client.get(path).text
        assert "<script>" not in html and "<style" not in html and " style=" not in html, path
        assert re.search(r"\son[a-z]+=", html) is None, path  # no inline event handler
        assert "//" not in "".join(a for a in html.split('src="')[1:] for a in [a.split('"')[0]]), (
            path
        )
        assert "cdn" not in html.lower(), path
    for asset in ("/static/demscale.css", "/static/studies.js", "/static/study.js"):
        r = client.get(asset)
        assert r.status_code == 200 and "{{" not in r.text, asset


@pytest.mark.timeout(60)
def test_docs_describe_the_api_offline(browser):
    r = browser.get("/docs")  # no token needed, nothing from a CDN
    assert r.status_code == 200
    for word in ("POST /studies", "StudyCreate", "ReferenceIn", "/openapi.json"):
        assert word in r.text, word
    assert "swagger" not in r.text.lower()
    assert browser.get("/static/../db.sqlite").status_code in (401, 404)
    assert browser.get("/docs/oauth2-redirect").status_code == 401


@pytest.mark.timeout(60)
def test_healthz_says_only_up_without_a_token(client, browser, settings):
    assert browser.get("/healthz").json() == {"status": "ok"}
    client.post("/studies", json=TINY)
    mine = client.get("/healthz").json()
    assert mine["status"] == "ok" and mine["studies"]["queued"] == 1
    # a wrong token is no token here: up or down only
    bad = browser.get("/healthz", headers={"Authorization": "Bearer not-a-token-0123456789"})
    assert bad.json() == {"status": "ok"}


@pytest.mark.timeout(60)
def test_healthz_says_down_when_the_database_does_not_answer(browser, monkeypatch):
    import service.app

    def broken(*a, **k):
        raise OSError("disk gone")

    monkeypatch.setattr(service.app, "Session", broken)
    r = browser.get("/healthz")
    assert r.status_code == 503 and r.json() == {"status": "down"}


# --- files ------------------------------------------------------------------------------


def test_a_world_readable_token_file_is_refused(settings, tmp_path):
    token_file = tmp_path / "tokens"
    token_file.write_text(TOKEN + "\n")
    settings.api_token = None
    settings.api_token_file = token_file
    token_file.chmod(0o644)
    with pytest.raises(ConfigError, match="chmod 600"):
        settings.tokens()
    token_file.chmod(0o600)
    assert settings.tokens() == (TOKEN,)


@pytest.mark.timeout(60)
def test_database_and_data_directory_are_the_services_own(settings, tmp_path):
    settings.data_dir.mkdir(parents=True)
    settings.data_dir.chmod(0o755)
    old = os.umask(0o022)
    try:
        with TestClient(create_app(settings), headers=AUTH) as c:
            assert c.post("/studies", json=TINY).status_code == 202
        mode = lambda p: stat.S_IMODE(p.stat().st_mode)  # noqa: E731
        assert mode(settings.data_dir) == 0o700
        assert mode(settings.studies_dir) == 0o700
        assert mode(tmp_path / "db.sqlite") == 0o600
        # what is written from now on is 0600 too (the umask of the service's process)
        probe = settings.studies_dir / "probe"
        probe.write_text("x")
        assert mode(probe) == 0o600
    finally:
        os.umask(old)


@pytest.mark.timeout(60)
def test_a_session_cookie_is_signed_expires_and_outlives_no_token(settings, browser, monkeypatch):
    r = browser.post("/login", data={"token": TOKEN, "next": "/"})
    assert r.status_code == 303 and browser.get("/").status_code == 200
    value = browser.cookies["demscale_session"]
    # a forged cookie (its payload changed, the signature kept) is no session
    _, stamp, sig = value.split(".")
    forged = base64.b64encode(b'{"owner": "0123456789abcdef", "since": 9999999999}').decode()
    browser.cookies.clear()
    browser.cookies.set("demscale_session", f"{forged}.{stamp}.{sig}")
    assert browser.get("/").status_code == 303
    # a session older than DEMSCALE_SESSION_MAX_AGE is over, however it is signed
    old = settings.model_copy(update={"session_max_age": 60})
    with TestClient(create_app(old), follow_redirects=False) as b:
        assert b.post("/login", data={"token": TOKEN}).status_code == 303
        data = json.loads(base64.b64decode(b.cookies["demscale_session"].split(".")[0]))
        assert data["since"] <= time.time() and set(data) == {"owner", "since"}
        later = time.time() + 120  # the session's clock, two minutes on
        monkeypatch.setattr("service.weblogin.time", SimpleNamespace(time=lambda: later))
        assert b.get("/").status_code == 303
    # a session whose token is revoked (the API restarted without it) is over too
    browser.cookies.clear()
    browser.cookies.set("demscale_session", value)
    other = settings.model_copy(update={"api_token": SecretStr("another-token-0123456789")})
    with TestClient(create_app(other), follow_redirects=False) as b:
        b.cookies.set("demscale_session", value)
        assert b.get("/").status_code == 303


@pytest.mark.timeout(60)
def test_log_out_is_offered_only_to_a_logged_in_browser(client, browser):
    assert 'action="/logout"' not in browser.get("/login").text
    assert 'action="/logout"' not in client.get("/").text  # a bearer token: nothing to end
    browser.post("/login", data={"token": TOKEN})
    assert 'action="/logout"' in browser.get("/").text
