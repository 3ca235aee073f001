"""The studies web page: the HTML of the list and of a study (queued, finished), every link
on a finished study's page answers, and headless Chromium (Debian's ``chromium``) renders
both pages without a console message. Set DEMSCALE_SCREENSHOTS=DIR to keep the screenshots.
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

from .conftest import SLOW, TINIEST, study_getter, wait_for

RUN_TIMEOUT = 240
PNG = b"\x89PNG\r\n\x1a\n"


def submit(client, body) -> str:
    r = client.post("/studies", json=body)
    assert r.status_code == 202, r.text
    return r.json()["id"]


def finished(client, sid, workers) -> dict:
    done = wait_for(study_getter(client, sid), lambda s: s["status"] in ("succeeded", "failed"),
                    RUN_TIMEOUT, "the study to finish", workers)
    assert done["status"] == "succeeded", done["error"]
    return done


def test_queued_study_page_and_unknown_ids(client):
    sid = submit(client, SLOW)
    page = client.get(f"/studies/{sid}/page")
    assert page.status_code == 200 and page.headers["content-type"].startswith("text/html")
    html = page.text
    assert "slow" in html and "status-queued" in html and "<progress" in html
    assert "ref-s1" in html and "r3.1mm-paper-s1" in html  # the planned runs
    assert f'fetch("/studies/{sid}"' in html  # live progress
    listing = client.get("/").text
    assert f"/studies/{sid}/page" in listing and "status-queued" in listing
    assert client.get("/studies/not-a-uuid/page").status_code == 404
    assert client.get(f"/studies/{uuid.uuid4()}/page").status_code == 404
    assert "/" not in client.get("/openapi.json").json()["paths"]  # pages are not API


@pytest.mark.timeout(RUN_TIMEOUT + 60)
def test_finished_study_page_links_all_answer(client, workers):
    sid = submit(client, TINIEST)
    workers.start()
    finished(client, sid, workers)
    html = client.get(f"/studies/{sid}/page").text
    assert "Verdicts" in html and "status-succeeded" in html
    assert re.search(r'class="verdict-(equivalent|differs|undecided)"', html)
    assert "ref-s1" in html and "speed-up" in html
    links = set(re.findall(r'(?:href|src)="(/studies/[^"]+)"', html))
    assert {f"/studies/{sid}/results.h5", f"/studies/{sid}/plots/stress_strain.png"} <= links
    for link in links:
        r = client.get(link)
        assert r.status_code == 200, link
        if link.endswith(".png"):
            assert r.content.startswith(PNG)
    listing = client.get("/").text
    assert "tiniest" in listing and "status-succeeded" in listing


def chromium() -> str | None:
    return shutil.which("chromium") or shutil.which("chromium-browser")


def screenshot(url: str, path: Path, width: int = 1400, height: int = 1000) -> list[str]:
    """Render ``url`` in headless Chromium into the PNG ``path``; returns the page's console
    messages (errors, warnings and logs alike, failed loads included)."""
    proc = subprocess.run(
        [chromium(), "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
         "--enable-logging=stderr", "--v=0", "--virtual-time-budget=8000",
         f"--window-size={width},{height}", f"--screenshot={path}", url],
        capture_output=True, text=True, timeout=120)
    assert path.is_file() and path.read_bytes().startswith(PNG), proc.stderr[-2000:]
    return [line for line in proc.stderr.splitlines() if ":CONSOLE" in line]


@pytest.mark.skipif(chromium() is None, reason="needs Debian's chromium")
@pytest.mark.timeout(2 * RUN_TIMEOUT + 120)
def test_pages_in_headless_chromium(live_server, workers, tmp_path):
    from matplotlib.image import imread

    with httpx.Client(base_url=live_server, timeout=30) as c:
        done = submit(c, TINIEST)
        workers.start()
        finished(c, done, workers)
        running = submit(c, SLOW)
        wait_for(study_getter(c, running),
                 lambda s: s["status"] == "running" and s["progress"] > 0.05,
                 RUN_TIMEOUT, "the second study to run", workers)
        shots = {"studies": (f"{live_server}/", 1400, 700),
                 "study": (f"{live_server}/studies/{done}/page", 1400, 2600)}
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
