"""What a clip file holds, from its first bytes, and how much of it decoded: for
:class:`jeanscv.io.clip.ClipReader`.

A clip is chosen by its name (``.gif``, ``.mp4``...), and FFmpeg then reads whatever the
bytes are. That gave the wrong one-line reasons for files whose content is not what their
name says: a text file named ``.gif`` (FFmpeg took its first bytes for a broken GIF), a
JPEG named ``.mp4`` (a one-frame clip). :func:`check_content` looks at the magic bytes
first and refuses those with a reason that names what the file is.

:class:`ClipStop` says where decoding stopped when it ended before the header's end: a
truncated MP4 whose index comes first decodes up to where the file was cut, and FFmpeg
ends there without an error.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

from jeanscv.errors import JeansError

from .clip_names import CLIP_EXTENSIONS

#: Bytes read from the start of a file to tell what it is.
HEAD_BYTES = 512

#: Still-picture formats: (name in messages, the extension to rename the file to).
_STILLS = {
    "jpeg": ("JPEG", ".jpg"),
    "png": ("PNG", ".png"),
    "webp": ("WebP", ".webp"),
    "bmp": ("BMP", ".bmp"),
    "tiff": ("TIFF", ".tif"),
}
#: ISO base media (MP4, MOV, 3GP) boxes a file may start with: ``ftyp``, or an old
#: QuickTime file's first atom.
_ISO_BOXES = (b"ftyp", b"moov", b"mdat", b"free", b"skip", b"wide", b"pnot")
#: Containers of video that FFmpeg reads by content, whatever the file is named: a
#: ``.gif`` that holds one is a renamed video, not a broken GIF.
VIDEO_KINDS = frozenset({"iso", "matroska", "avi", "mpegts", "mpegps", "flv", "ogg", "asf"})


def sniff(head: bytes) -> str | None:
    """What the bytes ``head`` (a file's first :data:`HEAD_BYTES`) start: ``gif``, a
    still's format (``jpeg``, ``png``, ``webp``, ``bmp``, ``tiff``; PNG and WebP may be
    animated), a video container (:data:`VIDEO_KINDS`), ``text``, or None (unknown)."""
    if head[:6] in (b"GIF87a", b"GIF89a") and not _is_text(head):  # a real GIF's screen size is binary
        return "gif"
    if head[:3] == b"\xff\xd8\xff":
        return "jpeg"
    if head[:8] == b"\x89PNG\r\n\x1a\n":
        return "png"
    if head[:4] == b"RIFF" and head[8:12] == b"WEBP":
        return "webp"
    if head[:4] == b"RIFF" and head[8:12] == b"AVI ":
        return "avi"
    if head[:4] in (b"II*\x00", b"MM\x00*"):
        return "tiff"
    if head[4:8] in _ISO_BOXES:
        return "iso"
    if head[:4] == b"\x1a\x45\xdf\xa3":
        return "matroska"
    if head[:1] == head[188:189] == b"\x47":  # a sync byte every 188-byte packet
        return "mpegts"
    if head[:4] == b"\x00\x00\x01\xba":
        return "mpegps"
    if head[:3] == b"FLV":
        return "flv"
    if head[:4] == b"OggS":
        return "ogg"
    if head[:4] == b"\x30\x26\xb2\x75":
        return "asf"
    if head[:2] == b"BM" and len(head) >= 26 and head[6:10] == b"\x00\x00\x00\x00":
        return "bmp"  # after the containers: "BM" alone is too common a start
    return "text" if _is_text(head) else None


def _is_text(head: bytes) -> bool:
    """Whether ``head`` reads as UTF-8 text (a multi-byte character cut at its end allowed)."""
    try:
        text = head.decode("utf-8")
    except UnicodeDecodeError as exc:
        if exc.start < len(head) - 3:
            return False
        text = head[: exc.start].decode("utf-8")
    return bool(text) and all(ch.isprintable() or ch in "\t\n\r\f" for ch in text)


def gif_screen(head: bytes) -> tuple[int, int]:
    """A GIF's logical screen (width, height) from its header: the size of every frame
    FFmpeg decodes (it gives 0x0 for a screen it will not allocate)."""
    return int.from_bytes(head[6:8], "little"), int.from_bytes(head[8:10], "little")


def check_content(path: Path, kind: str | None, animated: bool) -> None:
    """Raise a one-line ``JeansError`` when ``path``, a clip by its name (``.gif``, a
    video's extension), holds no clip by its content (:func:`sniff`'s ``kind``): a still
    picture (a JPEG named ``.mp4``; ``animated``: a PNG or WebP has several frames), text,
    or, named ``.gif``, neither a GIF nor a video. Other names (``.png``, ``.webp``) are
    clips because Pillow found several frames in them: nothing to check."""
    suffix = path.suffix.lower()
    if suffix not in CLIP_EXTENSIONS:
        return
    what = "a GIF" if suffix == ".gif" else "a video"
    if kind in _STILLS and not (kind in ("png", "webp") and animated):
        label, extension = _STILLS[kind]
        # Its output's name was chosen from this one before anything was read (so that
        # a resumed run finds it without decoding): dressed here, a photo would become a
        # one-frame video. Renamed, it is dressed and written as the photo it is.
        raise JeansError(f"a {label} picture, not {what}: rename it {path.stem}{extension} to dress it as a photo")
    if kind == "text":
        raise JeansError(f"not {what}: the file is text")
    if suffix == ".gif" and kind not in VIDEO_KINDS and kind not in ("gif", "png", "webp"):
        raise JeansError("not a GIF: the file does not start with GIF87a or GIF89a")


def is_animated(file: BinaryIO) -> bool:
    """Whether Pillow finds several frames in ``file`` (read from its start, left there)."""
    from PIL import Image

    try:
        file.seek(0)
        with Image.open(file) as image:
            return bool(getattr(image, "is_animated", False))
    except Exception:  # noqa: BLE001 - unreadable: no animation (the decoder says why)
        return False
    finally:
        file.seek(0)


def gif_loop(file: BinaryIO) -> int | None:
    """A GIF's loop count from its NETSCAPE block (0: forever), None when it plays once."""
    from PIL import Image

    position = file.tell()
    try:
        file.seek(0)
        with Image.open(file) as image:
            return image.info.get("loop")
    except Exception:  # noqa: BLE001 - FFmpeg reads it; looping forever is the common case
        return 0
    finally:
        file.seek(position)


_TAG_DURATION = re.compile(r"^(\d+):(\d{2}):(\d{2}(?:\.\d+)?)$")


def video_seconds(container, stream, fmt: str) -> float | None:
    """How long the video stream lasts by the header, in seconds, where the header says
    so: an MP4's (or MOV's) track duration, a Matroska's (WebM's) video track's
    ``DURATION`` tag, or its segment's duration when the video is its only stream. None
    elsewhere: other formats' durations are estimates (MPEG-TS, from the bit rate) that
    a complete file need not reach."""
    if fmt == "mov" and stream.duration and stream.time_base:
        return float(stream.duration * stream.time_base)
    if fmt != "matroska":
        return None
    match = _TAG_DURATION.match(str(stream.metadata.get("DURATION", "")).strip())
    if match:
        hours, minutes, seconds = match.groups()
        return int(hours) * 3600 + int(minutes) * 60 + float(seconds)
    if len(container.streams) == 1 and container.duration:
        return container.duration / 1_000_000
    return None


@dataclass(frozen=True)
class ClipStop:
    """Where decoding ended before the clip's end: ``after`` frames decoded, of the
    header's ``of`` (when it counts them); where it has no count but a duration, at
    ``at_seconds`` of its ``of_seconds``; ``reason``: the decoder's error, when one
    ended it. ``str()`` is the sentence of the command's note."""

    after: int
    of: int | None = None
    at_seconds: float | None = None
    of_seconds: float | None = None
    reason: str | None = None

    def __str__(self) -> str:
        text = f"decoding stopped after frame {self.after}"
        if self.of is not None:
            text += f" of {self.of}"
        elif self.at_seconds is not None and self.of_seconds is not None:
            text += f", at {self.at_seconds:.2f} s of {self.of_seconds:.2f} s"
        return text + (f" ({self.reason})" if self.reason else "")

    def to_json(self) -> dict:
        """The report's ``stopped``: its fields that are known."""
        fields = {"after": self.after, "of": self.of, "at_seconds": self.at_seconds}
        fields.update(of_seconds=self.of_seconds, reason=self.reason)
        return {key: value for key, value in fields.items() if value is not None}


def stop_of(
    count: int,
    end: float,
    reason: str | None,
    frames: int | None,
    seconds: float | None,
    fps: float | None,
) -> ClipStop | None:
    """Whether decoding stopped early: ``count`` frames decoded ending ``end`` seconds
    after the first began, ``reason`` the error that ended it (None: the file just ended),
    against the header's ``frames`` and the video's ``seconds`` (None: unknown) at
    ``fps``. None when the clip decoded to its end, or when nothing says it did not."""
    # Half a frame to spare: the decoded frames of every whole file tried (MP4, MOV, MKV,
    # WebM, at constant and variable rates) end within a millisecond of the header's
    # duration, and losing only the last frame is still said.
    spare = 0.5 / fps if fps else 0.05
    ended_short = seconds is not None and end < seconds - spare
    if frames:
        # A stream copied from a cut (``ffmpeg -ss T -c copy``) keeps the frames before
        # the cut back to a key frame, counted in the header but hidden by its edit list:
        # fewer frames decode than it counts, yet they reach the track's end. Frames are
        # lost only when the decoded ones also end short of it.
        short = count < frames and (seconds is None or ended_short)
        return ClipStop(count, frames, reason=reason) if short or reason else None
    if seconds is not None and (reason or ended_short):
        # No count (Matroska, a fragmented MP4): the track's duration says it. Not
        # duration x rate: at a variable frame rate that counts frames that never were.
        return ClipStop(count, at_seconds=round(end, 2), of_seconds=round(seconds, 2), reason=reason)
    return ClipStop(count, reason=reason) if reason else None


__all__ = [
    "HEAD_BYTES",
    "VIDEO_KINDS",
    "ClipStop",
    "check_content",
    "gif_loop",
    "gif_screen",
    "is_animated",
    "sniff",
    "stop_of",
    "video_seconds",
]
