"""The studies web page: the HTML of the list and of a study (queued, finished), every link
on a finished study's page answers, logging in with the API token (a cookie that only reads),
and headless Chromium (Debian's ``chromium``) renders both pages without a console message.
Set DEMSCALE_SCREENSHOTS=DIR to keep the screenshots.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import uuid
from pathlib import Path

import httpx
import pytest
from fastapi.testclient import TestClient

from service.app import create_app

from .conftest import (
    AUTH,
    RUN_TIMEOUT,
    SLOW,
    TINIEST,
    TOKEN,
    study_getter,
    wait_for,
    wait_succeeded,
)

PNG = b"\x89PNG\r\n\x1a\n"


def submit(client, body) -> str:
    r = client.post("/studies", json=body)
    assert r.status_code == 202, r.text
    return r.json()["id"]


def test_queued_study_page_and_unknown_ids(client):
    sid = submit(client, SLOW)
    page = client.get(f"/studies/{sid}/page")
    assert page.status_code == 200 and page.headers["content-type"].startswith("text/html")
    html = page.text
    assert "slow" in html and "status-queued" in html and "<progress" in html
    assert "ref-s1" in html and "r3.1mm-paper-s1" in html  # the planned runs
    # live progress: the script (a file, no inline script) polls the study of data-id
    assert f'data-id="{sid}"' in html and 'src="/static/study.js"' in html
    assert '"/studies/" + encodeURIComponent(box.dataset.id)' in client.get("/static/study.js").text
    listing = client.get("/").text
    assert f"/studies/{sid}/page" in listing and "status-queued" in listing
    assert client.get("/studies/not-a-uuid/page").status_code == 422  # as the API answers
    assert client.get(f"/studies/{uuid.uuid4()}/page").status_code == 404
    assert "/" not in client.get("/openapi.json").json()["paths"]  # pages are not API


@pytest.mark.timeout(RUN_TIMEOUT + 60)
def test_finished_study_page_links_all_answer(client, workers):
    sid = submit(client, TINIEST)
    workers.start()
    wait_succeeded(study_getter(client, sid), "the study to finish", workers)
    html = client.get(f"/studies/{sid}/page").text
    assert "Verdicts" in html and "status-succeeded" in html
    assert re.search(r'class="verdict-(equivalent|differs|undecided)"', html)
    assert "ref-s1" in html and "speed-up" in html
    # issue 42 item 2: speed-up in stepping time and in particle-steps, compilation apart
    head = re.search(r"<h2>Runs</h2>.*?<thead>(.*?)</thead>.*?<tbody>(.*?)</tbody>", html, re.S)
    headings = re.findall(r"<th>(.*?)</th>", head[1])
    for h in ("run time [s]", "compile [s]", "speed-up [x]", "speed-up in particle-steps [x]"):
        assert h in headings, headings
    first = re.findall(r"<td[^>]*>(.*?)</td>", head[2])[: len(headings)]
    assert float(first[headings.index("compile [s]")]) >= 0.0, first
    links = set(re.findall(r'(?:href|src)="(/studies/[^"]+)"', html))
    assert {f"/studies/{sid}/results.h5", f"/studies/{sid}/plots/stress_strain.png"} <= links
    for link in links:
        r = client.get(link)
        assert r.status_code == 200, link
        if link.endswith(".png"):
            assert r.content.startswith(PNG)
    listing = client.get("/").text
    assert "tiniest" in listing and "status-succeeded" in listing


def test_login_keeps_the_token_in_a_cookie_that_only_reads(client, settings):
    sid = submit(client, SLOW)  # with the header
    with TestClient(create_app(settings), follow_redirects=False) as browser:
        r = browser.get("/")
        assert r.status_code == 303 and r.headers["location"] == "/login?next=%2F"
        form = browser.get("/login?next=/studies/x/page")
        assert form.status_code == 200 and 'name="token"' in form.text
        assert 'value="/studies/x/page"' in form.text
        r = browser.post("/login", data={"token": TOKEN, "next": f"/studies/{sid}/page"})
        assert r.status_code == 303 and r.headers["location"] == f"/studies/{sid}/page"
        cookie = r.headers["set-cookie"]
        assert "httponly" in cookie.lower() and "samesite=strict" in cookie.lower()
        assert TOKEN not in cookie  # a signed session, not the token
        assert browser.get(f"/studies/{sid}/page").status_code == 200
        assert f"/studies/{sid}/page" in browser.get("/").text
        assert browser.get(f"/studies/{sid}").json()["status"] == "queued"  # JS polling
        # the cookie never changes anything: no submit, cancel or delete without the header
        assert browser.post("/studies", json=SLOW).status_code == 401
        assert browser.post(f"/studies/{sid}/cancel").status_code == 401
        assert browser.delete(f"/studies/{sid}").status_code == 401
        # an open redirect is refused
        r = browser.post("/login", data={"token": TOKEN, "next": "//evil.example/"})
        assert r.headers["location"] == "/"
        r = browser.post("/logout")
        assert r.status_code == 303 and "expires=Thu, 01 Jan 1970" in r.headers["set-cookie"]
        browser.cookies.clear()
        r = browser.post("/login", data={"token": "not-the-token-0123456789"})  # a wrong one
        assert r.status_code == 401 and "set-cookie" not in r.headers
        assert "not accepted" in r.text
        r = browser.get("/")
        assert r.status_code == 303 and r.headers["location"].startswith("/login")
        assert browser.get("/studies").status_code == 401  # the API stays JSON


def chromium() -> str | None:
    return shutil.which("chromium") or shutil.which("chromium-browser")


def screenshot(url: str, path: Path, width: int = 1400, height: int = 1000) -> list[str]:
    """Render ``url`` in headless Chromium into the PNG ``path``; returns the page's console
    messages (errors, warnings and logs alike, failed loads included)."""
    proc = subprocess.run(
        [
            chromium(),
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--hide-scrollbars",
            "--enable-logging=stderr",
            "--v=0",
            "--virtual-time-budget=8000",
            f"--window-size={width},{height}",
            f"--screenshot={path}",
            url,
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert path.is_file() and path.read_bytes().startswith(PNG), proc.stderr[-2000:]
    return [line for line in proc.stderr.splitlines() if ":CONSOLE" in line]


@pytest.mark.skipif(chromium() is None, reason="needs Debian's chromium")
@pytest.mark.timeout(2 * RUN_TIMEOUT + 120)
def test_pages_in_headless_chromium(live_server, workers, tmp_path):
    from matplotlib.image import imread

    with httpx.Client(base_url=live_server, timeout=30, headers=AUTH) as c:
        done = submit(c, TINIEST)
        workers.start()
        wait_succeeded(study_getter(c, done), "the study to finish", workers)
        running = submit(c, SLOW)
        wait_for(
            study_getter(c, running),
            lambda s: s["status"] == "running" and s["progress"] > 0.05,
            RUN_TIMEOUT,
            "the second study to run",
            workers,
        )
        # a token never travels in a URL, so Chromium (which cannot send a header or post
        # a form from the command line) sees the pages anyone may see: the login form and
        # the API description. A console message would name a Content-Security-Policy
        # violation (an inline script or style, an asset from elsewhere).
        shots = {
            "login": (f"{live_server}/login?next=/studies/{done}/page", 1400, 700),
            "docs": (f"{live_server}/docs", 1400, 2600),
        }
        for name, (url, w, h) in shots.items():
            path = tmp_path / f"web_{name}.png"
            console = screenshot(url, path, w, h)
            assert console == [], console
            img = imread(path)
            assert img.shape[:2] == (h, w) and img[..., :3].std() > 0.05
        listing = c.get("/").text
        assert "status-running" in listing and "status-succeeded" in listing
        c.post(f"/studies/{running}/cancel")
    keep = os.environ.get("DEMSCALE_SCREENSHOTS")
    if keep:
        Path(keep).mkdir(parents=True, exist_ok=True)
        for p in tmp_path.glob("web_*.png"):
            shutil.copy(p, Path(keep) / p.name)
