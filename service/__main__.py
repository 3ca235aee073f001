"""``python -m service api`` (uvicorn on DEMSCALE_HOST:DEMSCALE_PORT, default 0.0.0.0:8000)
or ``python -m service worker [--once]`` (the worker process): the container's commands."""

from __future__ import annotations

import os
import sys


def main(argv: list[str]) -> None:
    """Dispatch to the API or the worker."""
    if not argv or argv[0] not in ("api", "worker"):
        sys.exit("usage: python -m service api | worker [worker options]")
    if argv[0] == "worker":
        from .worker import main as worker_main

        worker_main(argv[1:])
        return
    import uvicorn

    uvicorn.run(
        "service.app:create_app",
        factory=True,
        host=os.environ.get("DEMSCALE_HOST", "0.0.0.0"),
        port=int(os.environ.get("DEMSCALE_PORT", "8000")),
        proxy_headers=True,
    )


if __name__ == "__main__":
    main(sys.argv[1:])
