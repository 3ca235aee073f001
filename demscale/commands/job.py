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

from ..report import summary_text

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


#: Statuses of a run that has its outcome.
_RUN_DONE = {"succeeded", "failed"}


def _state(s: dict):
    """The progress display's state of a study as the API answers it (GET /studies/{id})."""
    from ..progress import State

    running = s["status"] == "running"
    return State(
        fraction=s["progress"],
        runs_done=s.get("runs_done"),
        n_runs=s["n_runs"],
        added=s.get("runs_added", 0),
        run=s["current_run"] if running else None,
        stage=s["current_stage"] if running else None,
        eta=s.get("eta"),
        status=s["status"],
    )


def _follow(client: httpx.Client, study_id: str, console=None, poll: float = 1.0) -> dict:
    """Show the study's progress until it ends (demscale.progress.StudyDisplay: a live bar
    on a terminal, else a line per event): each run's outcome as it comes, the runs a
    ``decide`` round adds when they are added (before they run); returns its final state."""
    from rich.console import Console

    from ..progress import StudyDisplay

    console = console or Console(highlight=False)
    known: set[str] | None = None  # run keys seen so far
    told: set[str] = set()  # runs whose outcome was said
    with StudyDisplay(console) as display:
        while True:
            s = client.get(f"/studies/{study_id}").raise_for_status().json()
            state = _state(s)
            runs = s.get("runs", [])
            keys = [r["key"] for r in runs]
            new = [k for k in keys if known is not None and k not in known]
            if new:
                display.event(
                    state, f"+ {len(new)} runs added until decided (not yet run): {', '.join(new)}"
                )
            known = set(keys)
            for r in runs:
                if r["status"] in _RUN_DONE and r["key"] not in told:
                    told.add(r["key"])
                    if r["status"] == "failed":
                        display.event(state, f"{r['key']} failed: {r['error']}", "red")
                    else:
                        took = "" if r["wall_time"] is None else f" in {r['wall_time']:.1f} s"
                        display.event(state, f"{r['key']} done{took}")
            display.update(state)
            if s["status"] in _TERMINAL:
                return s
            time.sleep(poll)


def _plans(base: str, auth: dict) -> list[str]:
    """The answer lines of the main job's plans (demscale.commands.plan.main_job_processes), asked
    of the service; a line saying why where it cannot answer."""
    from .plan import main_job_processes, plan_line

    out = []
    try:
        with httpx.Client(base_url=base, timeout=60.0, headers=auth) as client:
            for body in main_job_processes():
                r = client.post("/plans", json=body)
                if r.status_code != 200:
                    out.append(f"how coarse: the plan was refused ({r.status_code}): {r.text}")
                    continue
                out.append("How coarse: " + plan_line(r.json()))
    except httpx.HTTPError as e:
        out.append(f"how coarse: the plan could not be asked ({e})")
    return out


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
    ap.add_argument(
        "--details", action="store_true", help="print each verdict's reason in the report"
    )
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
    auth = {"Authorization": f"Bearer {token}"}
    # the answer first: how coarse the default powder may go, from the stored size series
    # (POST /plans: nothing to run), before anything about the service or the study
    plans = _plans(base, auth)
    for line in plans:
        print(line)
    print(f"demscale API at {base} (docs: {base}/docs), data in {settings.data_dir.resolve()}")
    where = f" (kept in {settings.api_token_file})" if settings.api_token_file else ""
    print(
        f"API token{where}: {token}\n  e.g. curl -H 'Authorization: Bearer {token}' {base}/studies"
    )
    if settings.worker_log_path is not None:
        print(f"the worker's log: {settings.worker_log_path.resolve()}")
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
                summary = client.get(links["summary"]).raise_for_status().json()
                # the report: the answer first (the plans, then the study's), the verdicts,
                # then the tables and where everything is served
                print("")
                for line in plans:
                    print(line)
                print(summary_text(summary, details=args.details))
                print("\nresults:")
                for name in ("self", "summary", "curves", "results"):
                    print(f"  {name:<24} {base}{links[name]}")
                for name, url in links.items():
                    if name.startswith("plot_"):
                        print(f"  {name:<24} {base}{url}")
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
