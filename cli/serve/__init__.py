"""``jeanscv serve``: a local web page to drop a photo, click the subject and take the meme home.

Only click is imported here: the server's modules (Starlette, uvicorn, the library)
load when the command runs. See ``docs/serve.md``.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import click

EPILOG = """\b
Examples:
  jeanscv serve                      a page at http://127.0.0.1:8000/ for one photo at a time
  jeanscv serve photos/ --open       the folder's photos with their jeans; fix one with clicks
  jeanscv serve --port 9000

\b
The server binds to 127.0.0.1 (this machine only) unless --host says otherwise.
In folder mode it reads and writes only inside FOLDER: NAME.jeans.EXT outputs and
NAME.clicks.json clicks files, which a later 'jeanscv FOLDER' run uses.
"""


@click.command(
    "serve",
    context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100},
    epilog=EPILOG,
)
@click.argument("folder", required=False, type=click.Path(exists=True, file_okay=False, path_type=Path))
@click.option("--host", default="127.0.0.1", show_default=True, help="Address to listen on (127.0.0.1: this machine).")
@click.option("--port", type=click.IntRange(0, 65535), default=8000, show_default=True, help="Port to listen on.")
@click.option("--open", "open_browser", is_flag=True, help="Open the page in the web browser.")
@click.option(
    "--max-upload-mb",
    type=click.IntRange(1, 4096),
    default=200,
    show_default=True,
    help="Largest upload accepted, in MB (camera RAW files are large).",
)
@click.option(
    "--max-pixels",
    type=click.IntRange(1),
    default=100_000_000,
    show_default=True,
    help="Refuse images larger than this (decompression bombs).",
)
@click.option(
    "--memory-mb",
    type=click.IntRange(64),
    default=400,
    show_default=True,
    help="Memory for the photos and results kept; the oldest are dropped past it.",
)
@click.option(
    "--workers",
    type=click.IntRange(1, 64),
    default=None,
    help="Photos worked on at once. [default: one per core, at most 4, fewer on a small memory]",
)
@click.option(
    "--queue",
    type=click.IntRange(0, 1024),
    default=32,
    show_default=True,
    help="Requests that may wait for a worker, in arrival order; more are answered 'busy, retry' (503).",
)
@click.option(
    "--job-seconds",
    type=click.FloatRange(1, 3600),
    default=120,
    show_default=True,
    help="Longest a request waits for its photo's work before it is answered 'took too long' (504).",
)
@click.option("--debug", is_flag=True, help="Log the tracebacks of unexpected errors to this terminal.")
def serve(
    folder, host, port, open_browser, max_upload_mb, max_pixels, memory_mb, workers, queue, job_seconds, debug
) -> None:
    """Serve a page to put jeans on a photo: drop it, click the subject, download the meme.

    With FOLDER: a gallery of its photos with their jeans, made on demand and kept there.
    """
    from .run import default_workers, run_server

    code = run_server(
        folder=folder,
        host=host,
        port=port,
        open_browser=open_browser,
        max_upload=max_upload_mb << 20,
        max_pixels=max_pixels,
        store_bytes=memory_mb << 20,
        workers=workers or default_workers(),
        queue=queue,
        job_seconds=job_seconds,
        debug=debug,
    )
    # End here, without the interpreter's tear-down: a worker thread may still be inside
    # OpenCV or numba with a photo the server has given up (see run.py). A folder output
    # it was writing is removed first, and no new one started.
    from jeanscv.io.write import abandon_writes

    abandon_writes()
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


def main(argv: list[str]) -> None:
    """``jeanscv serve ARGS``: called by the ``jeanscv`` command."""
    serve.main(args=argv, prog_name="jeanscv serve")
