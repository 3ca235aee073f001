"""``demscale serve``, ``demscale job`` and ``demscale worker``: the job service's HTTP API,
the main job over it (demscale/commands/job.py) and a worker of its queue. They delegate to
``service`` (the ``service`` extra); their settings are DEMSCALE_* environment variables."""

from __future__ import annotations

import os
import sys
from pathlib import Path

from ..options import add_data_dir, command, lacks_extra

SERVE_HELP = """\
Start the job service's HTTP API (uvicorn; the same as `python -m service api`). By default
it also starts one worker process that runs the submitted studies. The studies page (status,
live progress, verdicts, plots) is at http://HOST:PORT/ and the API documentation at
http://HOST:PORT/docs.

Every request needs an API token: DEMSCALE_API_TOKEN (one token) or DEMSCALE_API_TOKEN_FILE
(one per line). On 127.0.0.1 without either, the server makes one, keeps it in
DIR/api-token and prints it, to paste into the studies page's login form (a token is never
put in a URL, where access logs and browser histories would keep it).
Settings come from DEMSCALE_* environment variables (docs/SERVICE.md); the options below set
the common ones."""

WORKER_HELP = """\
Start a worker of the job service (the same as `python -m service.worker`): it claims queued
studies from the service's database one at a time and runs them. Use it with
`demscale serve --no-worker` to run the API and the workers as separate processes; they
must share DEMSCALE_DATA_DIR (and DEMSCALE_DATABASE_URL, if set)."""


#: What ``serve`` and ``worker`` need: the ``service`` extra.
SERVICE_EXTRA = ("fastapi", "uvicorn", "sqlmodel", "pydantic_settings", "h5py")


def add_commands(sub) -> None:
    """``serve``, ``job`` and ``worker`` on the ``demscale`` parser's subparsers ``sub``."""
    p = command(sub, "serve", "start the job service's HTTP API (and a worker)", SERVE_HELP, serve)
    p.add_argument(
        "--host",
        default=os.environ.get("DEMSCALE_HOST", "127.0.0.1"),
        help="address to listen on (default 127.0.0.1, this machine only; "
        "0.0.0.0 for every interface)",
    )
    p.add_argument(
        "--port",
        type=int,
        default=int(os.environ.get("DEMSCALE_PORT", "8000")),
        help="port to listen on (default 8000)",
    )
    add_data_dir(
        p, "where the database and result files live (default: DEMSCALE_DATA_DIR, else ./var)"
    )
    p.add_argument(
        "--no-worker",
        action="store_true",
        help="do not start the embedded worker (run `demscale worker` instead)",
    )

    # parsed by demscale.commands.job itself (main() hands it the arguments after "job")
    sub.add_parser(
        "job",
        help="the main job: serve, submit a study (default: the default "
        "study), follow it, print its results",
        add_help=False,
    )

    p = command(
        sub, "worker", "start a worker that runs the service's queued studies", WORKER_HELP, worker
    )
    p.add_argument("--once", action="store_true", help="exit after one study")
    add_data_dir(p, "the API's data folder (default: DEMSCALE_DATA_DIR, else ./var)")


def _service_env(args) -> int:
    if lacks_extra(args.command, SERVICE_EXTRA, "service"):
        return 2
    if args.data_dir is not None:
        os.environ["DEMSCALE_DATA_DIR"] = str(args.data_dir)
    return 0


def serve(args) -> int:
    """``demscale serve``: the API (``python -m service api``)."""
    if _service_env(args):
        return 2
    os.environ["DEMSCALE_HOST"] = args.host
    os.environ["DEMSCALE_PORT"] = str(args.port)
    if args.no_worker:
        os.environ["DEMSCALE_EMBEDDED_WORKER"] = "false"
    from service.__main__ import main as service_main
    from service.settings import ConfigError, get_settings, with_local_token

    try:  # the token the server will use: configured, or the local one it keeps
        _, token = with_local_token(get_settings(), args.host)
    except ConfigError as e:
        print(f"demscale serve: {e}", file=sys.stderr)
        return 2
    host = "127.0.0.1" if args.host in ("0.0.0.0", "::", "") else args.host
    url = f"http://{host}:{args.port}/"
    if token is not None:
        # the token apart from the URL: a login link would leave it in logs and histories
        print(
            f"demscale serve: the studies page: {url} (log in with the API token {token}, "
            f"kept in {Path(get_settings().data_dir) / 'api-token'})",
            file=sys.stderr,
        )
    else:
        print(
            f"demscale serve: the studies page: {url} (log in with your API token)", file=sys.stderr
        )
    service_main(["api"])
    return 0


def job(argv: list[str]) -> int:
    """The main job over the service (``demscale job --help`` lists its options)."""
    if lacks_extra("job", ("fastapi", "sqlmodel", "uvicorn", "httpx"), "service"):
        return 2
    from .job import main as job_main

    return job_main(argv)


def worker(args) -> int:
    """``demscale worker``: a worker process (``python -m service.worker``)."""
    if _service_env(args):
        return 2
    from service.worker import main as worker_main

    worker_main(["--once"] if args.once else [])
    return 0
