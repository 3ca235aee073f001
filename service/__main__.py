"""``python -m service api`` (uvicorn on DEMSCALE_HOST:DEMSCALE_PORT, default 127.0.0.1:8000)
or ``python -m service worker [--once]`` (the worker process): the container's commands.

The API needs a token (DEMSCALE_API_TOKEN or DEMSCALE_API_TOKEN_FILE) to listen on any
address but the loopback one; on 127.0.0.1 without one it uses (and shows) the token kept in
``<data dir>/api-token``."""

from __future__ import annotations

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

    from .app import create_app
    from .settings import ConfigError, get_settings, with_local_token

    settings = get_settings()
    try:
        settings, token = with_local_token(settings, settings.host)
        app = create_app(settings)
    except ConfigError as e:
        sys.exit(f"demscale api: {e}")
    if token is not None:
        print(
            f"demscale api: API token {token} (kept in {settings.api_token_file}); send "
            "'Authorization: Bearer <token>'",
            file=sys.stderr,
            flush=True,
        )
    uvicorn.run(app, host=settings.host, port=settings.port, proxy_headers=True)


if __name__ == "__main__":
    main(sys.argv[1:])
