"""Screenshots of the service's study page and calibration page, as a logged-in browser sees
them, into docs/figures/ (web_study_page.png, web_calibration_page.png):

    .venv/bin/python scripts/page_screenshots.py [--out docs/figures]

A temporary service store gets a small study with resolution controls (the TINY study of
tests/service/conftest.py with two seeds a side) and the calibration of
examples/calibration, each run to its end by a worker in this process (about a minute on 2
cores, kernels cached). The pages, their style sheet and their figures are fetched with a
session (POST /login, then GET with the signed cookie), saved side by side, and rendered by
headless Chromium (Debian's ``chromium``) into PNGs, reduced to 256 colours. The pages'
script (live progress) is left out: both jobs have ended.
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

TOKEN = "screenshot-token-0123456789abcdef"


def chromium() -> str:
    found = shutil.which("chromium") or shutil.which("chromium-browser")
    if found is None:
        raise SystemExit("needs Debian's chromium: apt-get install -y chromium")
    return found


def save_page(client, url: str, folder: Path) -> Path:
    """The page at ``url`` with its style sheet and images saved beside it (links made
    relative), the script left out; returns the HTML file."""
    html = client.get(url).text
    (folder / "demscale.css").write_text(client.get("/static/demscale.css").text)
    html = html.replace('href="/static/demscale.css"', 'href="demscale.css"')
    html = re.sub(r'<script src="[^"]*"[^>]*></script>', "", html)
    for k, src in enumerate(sorted(set(re.findall(r'<img src="(/[^"]+)"', html)))):
        name = f"img{k}.png"
        (folder / name).write_bytes(client.get(src).content)
        html = html.replace(f'src="{src}"', f'src="{name}"')
    html = html.replace(' loading="lazy"', "")
    page = folder / "page.html"
    page.write_text(html)
    return page


def shoot(page: Path, out: Path, width: int, height: int) -> None:
    subprocess.run(
        [
            chromium(),
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-background-networking",
            "--no-first-run",
            "--hide-scrollbars",
            "--allow-file-access-from-files",
            f"--window-size={width},{height}",
            f"--screenshot={out}",
            page.as_uri(),
        ],
        check=True,
        capture_output=True,
        timeout=120,
    )
    import numpy as np
    from PIL import Image  # matplotlib's dependency

    img = Image.open(out).convert("RGB")
    rows = np.asarray(img).std(axis=(1, 2))  # the page's empty bottom cut off
    used = int(np.nonzero(rows > 0)[0].max()) + 24 if (rows > 0).any() else img.height
    img = img.crop((0, 0, img.width, min(used, img.height)))
    img.quantize(colors=256, method=Image.Quantize.MEDIANCUT).save(out, optimize=True)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "figures")
    args = ap.parse_args(argv)
    from fastapi.testclient import TestClient

    from service.app import create_app
    from service.settings import Settings
    from service.worker import Worker
    from tests.service.conftest import TINY

    tmp = Path(tempfile.mkdtemp(prefix="demscale-pages-"))
    settings = Settings(
        data_dir=tmp / "data",
        database_url=f"sqlite:///{tmp / 'db.sqlite'}",
        embedded_worker=False,
        api_token=TOKEN,
    )
    study = {
        **TINY,
        "name": "tiny study with controls",
        "controls": True,
        "seeds": [1, 2],
        "reference_seeds": [1, 2],
    }
    calibration = {
        "name": "examples/calibration",
        "test": json.loads((ROOT / "examples/calibration/test.json").read_text()),
        "targets": json.loads((ROOT / "examples/calibration/lab.json").read_text()),
        "parameters": {"k1": [3e3, 2e4], "k2": [2.5e4, 8e4]},
        "runs": 8,
        "waves": 1,
        "wave_runs": 4,
    }
    auth = {"Authorization": f"Bearer {TOKEN}"}
    with TestClient(create_app(settings), headers=auth) as api:
        sid = api.post("/studies", json=study).json()["id"]
        cid = api.post("/calibrations", json=calibration).json()["id"]
        for _ in range(2):
            Worker(settings, once=True).run()
        assert api.get(f"/studies/{sid}").json()["status"] == "succeeded"
        assert api.get(f"/calibrations/{cid}").json()["status"] == "succeeded"
    args.out.mkdir(parents=True, exist_ok=True)
    with TestClient(create_app(settings), follow_redirects=False) as browser:
        assert browser.post("/login", data={"token": TOKEN}).status_code == 303
        for url, name, height in (
            (f"/studies/{sid}/page", "web_study_page.png", 5000),
            (f"/calibrations/{cid}/page", "web_calibration_page.png", 2600),
        ):
            folder = tmp / name.removesuffix(".png")
            folder.mkdir()
            shoot(save_page(browser, url, folder), args.out / name, 1400, height)
            print(f"wrote {args.out / name}")
    shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
