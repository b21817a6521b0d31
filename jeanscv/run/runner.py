"""One input to its files: what the command's workers (``jeanscv_cli.worker``) and the
Dask tasks (:mod:`jeanscv.run.distributed`) share. Each runs
:func:`jeanscv.pipeline.apply_jeans` with a :class:`jeanscv.options.JeansOptions`, encodes
the picture with :func:`encode_picture` and the report with :func:`report_text`, writes
them atomically, and turns any failure into one line with :func:`failure_reason`.
"""

from __future__ import annotations

import json
import os
from typing import TYPE_CHECKING

import numpy as np

from ..errors import JeansError

if TYPE_CHECKING:
    from ..report import JeansResult


def one_line(text: object) -> str:
    """Collapse whitespace (newlines included) so a message fits ``jeanscv: FILE: reason``."""
    return " ".join(str(text).split())


def failure_reason(exc: BaseException) -> str:
    """The user-facing reason for an exception raised while processing an input: a
    :class:`JeansError`'s message, else the exception's type and text."""
    if isinstance(exc, JeansError):
        return one_line(exc) or "failed"
    if isinstance(exc, MemoryError):
        return "out of memory"
    detail = one_line(exc)
    return f"unexpected error ({type(exc).__name__}{': ' + detail if detail else ''})"


def encode_picture(path: str | os.PathLike, pixels: np.ndarray, result: JeansResult) -> bytes:
    """Bytes of the picture for ``path``: its extension picks the format; photos keep
    their EXIF (orientation removed) and colour profile."""
    from ..io.write import encode_image, format_for_path, on_white

    fmt = format_for_path(path)
    if fmt == "JPEG":
        pixels = on_white(pixels)  # JPEG has no alpha: show transparency as white, not as raw colour
    meta = {}
    source = result.source
    if result.kind == "photo" and source is not None:
        meta = {"exif": source.exif, "icc_profile": source.icc_profile}
    return encode_image(pixels, fmt, quality=95, **meta)


def report_text(result: JeansResult, input_name: str, output_name: str) -> str:
    """The JSON report (the ``--json`` sidecar): sorted keys, indent 2, newline at the end."""
    return json.dumps(result.report(input_name, output_name), sort_keys=True, indent=2) + "\n"


__all__ = ["encode_picture", "failure_reason", "one_line", "report_text"]
