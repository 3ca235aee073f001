"""The main job: ``demscale job [--port 8000] [--exit] [--study FILE]``.

Starts the API (uvicorn, 127.0.0.1) with its embedded worker, submits the default study
(``engine.default_study()``, or the JSON spec in ``--study``), prints its progress until it
ends, then the URLs of its results and a short summary table. It keeps serving until Ctrl-C
unless ``--exit`` is given. Data go to ``DEMSCALE_DATA_DIR`` (default ``./var``).

The API needs a bearer token: the configured one (DEMSCALE_API_TOKEN or
DEMSCALE_API_TOKEN_FILE), else the one kept in ``<data dir>/api-token`` (made on the first
start), which is printed with the URLs.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import threading
import time
from pathlib import Path

import httpx
import uvicorn

import engine
from service.app import create_app
from service.settings import ConfigError, Settings, with_local_token

from .report import summary_text

_TERMINAL = {"succeeded", "failed", "cancelled"}


def _serve(settings: Settings, host: str, port: int) -> tuple[uvicorn.Server, threading.Thread]:
    server = uvicorn.Server(
        uvicorn.Config(create_app(settings), host=host, port=port, log_level="warning")
    )
    thread = threading.Thread(target=server.run, name="uvicorn", daemon=True)
    thread.start()
    while not server.started:
        if not thread.is_alive():
            sys.exit(f"the API could not start on {host}:{port} (port in use?)")
        time.sleep(0.05)
    return server, thread


def _follow(client: httpx.Client, study_id: str) -> dict:
    """Print a progress line whenever the status, run or stage changes or another 2 % is
    done, until the study ends; returns its final state."""
    last_key, last_fraction = None, -1.0
    while True:
        s = client.get(f"/studies/{study_id}").raise_for_status().json()
        run = (
            f"run {s['run_index'] + 1}/{s['n_runs']} {s['current_run']}"
            if s["run_index"] is not None
            else f"{s['n_runs']} runs"
        )
        key = (s["status"], run, s["current_stage"])
        if key != last_key or s["progress"] - last_fraction >= 0.02:
            print(
                f"[{100 * s['progress']:5.1f} %] {s['status']:<9} {run}  "
                f"stage {s['current_stage'] or '-'}",
                flush=True,
            )
            last_key, last_fraction = key, s["progress"]
        if s["status"] in _TERMINAL:
            return s
        time.sleep(1.0)


def main(argv: list[str] | None = None) -> int:
    """Run the main job; returns the exit status (0 when the study succeeded)."""
    ap = argparse.ArgumentParser(
        prog="demscale job",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    ap.add_argument("--host", default="127.0.0.1")
    ap.add_argument("--port", type=int, default=int(os.environ.get("DEMSCALE_PORT", 8000)))
    ap.add_argument("--study", type=Path, help="JSON study spec (default: engine.default_study)")
    ap.add_argument("--exit", action="store_true", help="exit when the study has ended")
    args = ap.parse_args(argv)
    try:
        # the study's runs side by side, one per core, unless DEMSCALE_RUN_WORKERS says else
        pool = {} if "DEMSCALE_RUN_WORKERS" in os.environ else {"run_workers": 0}
        settings, token = with_local_token(Settings(embedded_worker=True, **pool), args.host)
    except ConfigError as e:
        print(f"main job: {e}", file=sys.stderr)
        return 2
    token = token or settings.tokens()[0]
    spec = json.loads(args.study.read_text()) if args.study else engine.default_study().to_dict()
    server, thread = _serve(settings, args.host, args.port)
    base = f"http://{args.host}:{args.port}"
    print(f"demscale API at {base} (docs: {base}/docs), data in {settings.data_dir.resolve()}")
    where = f" (kept in {settings.api_token_file})" if settings.api_token_file else ""
    print(
        f"API token{where}: {token}\n  e.g. curl -H 'Authorization: Bearer {token}' {base}/studies"
    )
    auth = {"Authorization": f"Bearer {token}"}
    try:
        with httpx.Client(base_url=base, timeout=60.0, headers=auth) as client:
            r = client.post("/studies", json=spec)
            if r.status_code != 202:
                print(f"study refused ({r.status_code}): {r.text}", file=sys.stderr)
                return 2
            study_id = r.json()["id"]
            print(f"submitted study {study_id}")
            final = _follow(client, study_id)
            links = final["links"]
            if final["status"] == "succeeded":
                print("\nresults:")
                for name in ("self", "summary", "curves", "results"):
                    print(f"  {name:<24} {base}{links[name]}")
                for name, url in links.items():
                    if name.startswith("plot_"):
                        print(f"  {name:<24} {base}{url}")
                summary = client.get(links["summary"]).raise_for_status().json()
                print("\n" + summary_text(summary))
            else:
                print(f"study {final['status']}: {final['error']}", file=sys.stderr)
        code = 0 if final["status"] == "succeeded" else 1
        if not args.exit:
            print(f"\nserving at {base}; Ctrl-C to stop", flush=True)
            while thread.is_alive():
                thread.join(0.5)
        return code
    except KeyboardInterrupt:
        print("\nstopping", file=sys.stderr)
        return 130
    finally:
        server.should_exit = True
        thread.join()


if __name__ == "__main__":
    sys.exit(main())
