"""Which files are clips and what format a clip is written in, from names alone (no
decoding): for :mod:`jeanscv.io.clip` and for :func:`jeanscv.io.write.output_extension`,
which decides an output's name before anything is read."""

from __future__ import annotations

import os
from pathlib import Path

#: Extensions that are always clips (a GIF, even of one frame, is written back as a GIF).
CLIP_EXTENSIONS: frozenset[str] = frozenset({".gif", ".mp4", ".m4v", ".mov", ".webm", ".mkv"})
#: Extensions that are clips when the file holds several frames (animated PNG and WebP).
MAYBE_ANIMATED_EXTENSIONS: frozenset[str] = frozenset({".png", ".apng", ".webp"})
#: Formats a clip can be written in (``png`` is an animated PNG).
CLIP_FORMATS = ("gif", "mp4", "webp", "png")
#: The format a clip is written in by default, from its extension: videos become MP4.
_DEFAULT_FORMAT = {".gif": "gif", ".webp": "webp", ".png": "png", ".apng": "png"}


def is_clip_path(path: str | os.PathLike) -> bool:
    """Whether ``path`` names a clip by its extension alone (``.gif``, videos)."""
    return Path(path).suffix.lower() in CLIP_EXTENSIONS


def clip_format(path: str | os.PathLike, fmt: str | None = None) -> str:
    """The format a clip from ``path`` is written in: ``fmt`` when it is a clip format,
    else the input's own (GIF, WebP, PNG), MP4 for videos."""
    if fmt and fmt.lower() in CLIP_FORMATS:
        return fmt.lower()
    return _DEFAULT_FORMAT.get(Path(path).suffix.lower(), "mp4")


__all__ = ["CLIP_EXTENSIONS", "CLIP_FORMATS", "MAYBE_ANIMATED_EXTENSIONS", "clip_format", "is_clip_path"]
