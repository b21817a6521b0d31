"""Start the server: warn when it is reachable from other machines, open the page, stop on Ctrl-C."""

from __future__ import annotations

import sys
import threading
import webbrowser
from pathlib import Path

from .guard import is_loopback


def _say(message: str) -> None:
    print(f"jeanscv serve: {message}", file=sys.stderr, flush=True)


def run_server(
    *,
    folder: Path | None,
    host: str,
    port: int,
    open_browser: bool,
    max_upload: int,
    max_pixels: int,
    store_bytes: int,
    workers: int,
    queue: int,
) -> int:
    """Serve until Ctrl-C (or SIGTERM); returns the exit status."""
    import uvicorn

    from . import engine
    from .app import Config, create_app

    if not is_loopback(host):
        _say(
            f"WARNING: listening on {host}: other machines on the network can reach this page and "
            "upload files to it. Use the default (127.0.0.1) unless you mean that."
        )
    config = Config(
        host=host,
        port=port,
        folder=folder,
        max_upload=max_upload,
        max_pixels=max_pixels,
        store_bytes=store_bytes,
        workers=workers,
        queue=queue,
        backend=engine.default_backend(),
    )
    app = create_app(config)
    shown = f"[{host}]" if ":" in host else host
    url = f"http://{'127.0.0.1' if host in ('0.0.0.0', '::') else shown}:{port}/"
    what = f"the photos of {folder}" if folder is not None else "a page to drop photos on"
    _say(f"{what} at {url} (Ctrl-C stops)")
    if open_browser:
        threading.Timer(1.0, webbrowser.open, (url,)).start()
    server = uvicorn.Server(
        uvicorn.Config(
            app,
            host=host,
            port=port,
            log_level="warning",
            access_log=False,
            timeout_graceful_shutdown=5,
            server_header=False,
            lifespan="on",
        )
    )
    try:
        server.run()  # uvicorn stops on Ctrl-C and SIGTERM; it exits with 1 when it cannot listen
    except KeyboardInterrupt:
        pass
    _say("stopped")
    return 0
