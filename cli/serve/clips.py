"""Clips on the page: a GIF or a short video uploaded, clicked on its first frame, made
with the jeans following the subject (:func:`jeanscv.run.clips.write_jeans_clip`, the
command line's own), played in the page and downloaded.

An upload that is a clip of several frames is kept in the server's temporary folder
(the newest :data:`CLIPS_KEPT`; an older one's photo says it has expired) and its first
frame becomes the page's photo: the clicks, the box and the automatic subject are those
of the still flow, and they refer to frame 0, as ``--point`` does for the command. Caps
(:class:`ClipCaps`) on frames, seconds and pixels per frame are checked from the header
on upload and again while the clip is made; a clip's making stops at the server's job
time limit. Every refusal is one line, without paths.

A clip is made on the server's clip pool (its own worker and bounded queue: a photo never
waits behind a clip), and only while someone waits for it: when the client that asked
closes its connection (the page left, or made the clip again) the making stops at its
next frame, its half-written file removed.
"""

from __future__ import annotations

import asyncio
import os
import tempfile
import threading
import time
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path

from starlette.requests import Request
from starlette.responses import JSONResponse, Response

from jeanscv.errors import JeansError
from jeanscv.io.clip import ClipLimits, ClipReader, clip_format, is_clip
from jeanscv.io.write import on_white

from . import engine
from .answers import Refused, attachment, error
from .guard import BodyRefused
from .store import TooSlow

#: Uploaded clips kept on disk for making (the oldest is removed for a newer one).
CLIPS_KEPT = 4
#: Media types of the clips made.
CLIP_MEDIA = {"gif": "image/gif", "mp4": "video/mp4", "webp": "image/webp", "png": "image/apng"}


@dataclass(frozen=True)
class ClipCaps:
    """What the page takes as a clip: at most ``frames`` frames, ``seconds`` long, and
    ``pixels`` a frame (a short clip: the making runs while the person waits)."""

    frames: int = 300
    seconds: float = 30.0
    pixels: int = 1920 * 1080

    def limits(self) -> ClipLimits:
        return ClipLimits(max_frames=self.frames, max_seconds=self.seconds, max_frame_pixels=self.pixels)


@dataclass
class ClipSource:
    """An uploaded clip held for making: its file, its header's ``frames`` (None when
    unknown), ``seconds`` and ``fps``, the ``fmt`` it is made in, and the progress of the
    making running (``done`` frames)."""

    path: Path
    frames: int | None
    seconds: float | None
    fps: float | None
    fmt: str
    done: int = 0

    def summary(self) -> dict:
        """What the page is told about the clip."""
        return {
            "frames": self.frames,
            "seconds": None if self.seconds is None else round(self.seconds, 2),
            "format": self.fmt,
            "media": CLIP_MEDIA[self.fmt],
        }


@dataclass
class ClipFiles:
    """The uploaded clips on disk: the newest :data:`CLIPS_KEPT`, the others removed."""

    kept: deque = field(default_factory=deque)
    lock: threading.Lock = field(default_factory=threading.Lock)

    def keep(self, path: Path) -> None:
        with self.lock:
            self.kept.append(path)
            while len(self.kept) > CLIPS_KEPT:
                _remove(self.kept.popleft())


def _remove(path: Path) -> None:
    try:
        os.unlink(path)
    except OSError:
        pass  # the server stopped and removed its temporary folder


def _page_reason(exc: JeansError) -> str:
    """The reader's one line as the page says it (the command's option is no use there)."""
    return str(exc).replace(" (--max-frames)", " (this server's limit)")


def open_clip(path: Path, name: str, caps: ClipCaps, max_pixels: int, subject: str) -> engine.Photo | None:
    """The upload at ``path`` as a clip: its first frame opened as the page's photo, with
    the clip's :class:`ClipSource`; None when it is no clip (a still, a one-frame GIF).
    JeansError with one line when it is over a cap or cannot be read."""
    if not is_clip(path):
        return None
    try:
        with ClipReader(path, caps.limits()) as reader:
            info = reader.info
            if info.frames == 1:
                return None
            first = next(reader.frames())
    except JeansError as exc:
        raise JeansError(_page_reason(exc)) from None
    # The page shows frame 0 as a photo (a transparent clip's clear pixels on white, as the
    # clips' follower sees them); the clip itself is made from the file.
    # Found as the clip's own frame 0 is: the detector first (the page shows what the clip dresses).
    photo = engine.open_photo(on_white(first.pixels), name, max_pixels, subject)
    photo.clip = ClipSource(path, info.frames, info.seconds, info.fps, clip_format(name))
    return photo


class Cancelled(Exception):
    """Nobody waits for this clip any more: raised from the making's per-frame callback,
    it stops :func:`~jeanscv.run.clips.write_jeans_clip` there (which writes nothing)."""


def make_clip(
    photo: engine.Photo,
    clicks,
    options: engine.RenderOptions,
    backend: str | None,
    caps: ClipCaps,
    seconds: float,
    folder: Path,
    cancel: threading.Event | None = None,
) -> tuple[bytes, str, dict]:
    """``(bytes, file name, summary)`` of the clip with its jeans: ``clicks`` (None:
    automatic) on frame 0, the page's options (captions and side by side on every
    frame). Stops with :class:`~.store.TooSlow` past ``seconds`` (answered 504, as the
    pool answers a job it stops waiting for), with JeansError at a cap, and with
    :class:`Cancelled` at the first frame that ends after ``cancel`` is set."""
    from jeanscv.run.clips import write_jeans_clip

    from ..worker import clip_decorate

    source: ClipSource | None = photo.clip
    if source is None:
        raise JeansError("not a clip")
    if not source.path.exists():
        raise JeansError("the clip has expired: drop it again")
    wanted = options.jeans_options(backend).replace(clicks=clicks)
    deadline = time.monotonic() + seconds
    source.done = 0

    def on_frame(result) -> None:
        if cancel is not None and cancel.is_set():
            # Before the count: a making stopped says nothing more to the progress that a
            # newer making of the same clip now reports.
            raise Cancelled(f"stopped at frame {result.index}")
        source.done = result.index + 1
        if time.monotonic() > deadline:
            # The pool's own wait for this job starts a little later (when the server's
            # loop hears that it began): on a busy machine this deadline passes first, and
            # must give the same answer.
            raise TooSlow(f"{seconds:g} s")

    fd, made = tempfile.mkstemp(suffix=f".{source.fmt}", dir=folder)
    os.close(fd)
    try:
        report = write_jeans_clip(
            source.path,
            made,
            wanted,
            fmt=source.fmt,
            limits=caps.limits(),
            on_frame=on_frame,
            decorate=clip_decorate(wanted),
        )
        data = Path(made).read_bytes()
    except JeansError as exc:
        raise JeansError(_page_reason(exc)) from None
    finally:
        _remove(Path(made))
    frames = report["frames"]
    summary = {
        "frames": report["frames_written"],
        "seconds": report["seconds"],
        "format": source.fmt,
        "media": CLIP_MEDIA[source.fmt],
        "frames_without_jeans": sum(all(obj is None for obj in frame["objects"]) for frame in frames),
    }
    if "stopped" in report:
        summary["stopped"] = report["stopped"]
    return data, engine.output_name(photo, f".{source.fmt}"), summary


@dataclass
class MadeClip:
    """A clip made with its jeans: its bytes, download name and media type."""

    data: bytes
    name: str
    media: str


class ClipEndpoints:
    """The clip endpoints of the server's API (:class:`cli.serve.app._Api` has them):
    ``POST /api/photos/ID/clip`` makes it, ``GET /api/photos/ID/clip/progress`` says how
    far, ``GET /api/clips/ID`` is the clip (``?download=1``: as a download)."""

    async def make_clip(self, request: Request) -> Response:
        """The photo's clip with its jeans (clicks and options as for a render): made on the
        clip pool while the client waits, kept as a result; its address plays in the page
        and downloads. A client that leaves stops the making at its next frame."""
        _, photo, clicks, render_options = await self.clicked(request)
        if photo.clip is None:
            raise Refused(422, f"{photo.name}: not a clip")
        config = self.config
        cancel = threading.Event()
        photo.clip.done = 0  # while it waits for the clip worker too
        making = asyncio.ensure_future(
            self.job(
                photo.name,
                make_clip,
                photo,
                clicks,
                render_options,
                self.state.backend,
                config.clip_caps,
                config.job_seconds,
                self.state.tmp,
                cancel,
                pool=self.state.clip_pool,
            )
        )
        gone = asyncio.ensure_future(client_gone(request))
        try:
            await asyncio.wait({making, gone}, return_when=asyncio.FIRST_COMPLETED)
            if not making.done():
                # The client left: a waiting job gives its place up, a running one stops below.
                making.cancel()
                await asyncio.gather(making, return_exceptions=True)
                return error(499, f"{photo.name}: the page left before its clip was made")  # read by nobody
            made, name, summary = making.result()
        finally:
            # Whatever ended this request (made, refused, too slow, the server stopping, the
            # client gone), nobody waits for this making any more: it stops at its next frame.
            cancel.set()
            gone.cancel()
        clip_id = self.state.results.put(MadeClip(made, name, summary["media"]), len(made) + 4096)
        return JSONResponse({"clip": f"/api/clips/{clip_id}", "name": name, **summary})

    async def clip_progress(self, request: Request) -> Response:
        photo = self.state.photos.get(request.path_params["photo"])
        if photo is None or photo.clip is None:
            return error(404, "no such clip (it may have expired: drop it again)")
        return JSONResponse(progress(photo))

    async def clip_file(self, request: Request) -> Response:
        made = self.state.results.get(request.path_params["clip"])
        if not isinstance(made, MadeClip):
            return error(404, "no such clip (it may have expired: make it again)")
        headers = {"Cache-Control": "private, max-age=3600"}
        if request.query_params.get("download") == "1":
            headers["Content-Disposition"] = attachment(made.name)
        return Response(made.data, media_type=made.media, headers=headers)


async def client_gone(request: Request) -> None:
    """Return when the client has closed its connection, never while it waits. The body
    has been read, so the next message the server gets for the request is its
    ``http.disconnect`` (uvicorn sends it when the connection closes, or once the answer
    is sent)."""
    while True:
        try:
            message = await request.receive()
        except BodyRefused:
            continue  # the Guard's limit for a stalled body: no body is expected any more
        if message["type"] == "http.disconnect":
            return


def progress(photo: engine.Photo) -> dict:
    """How far the making of the photo's clip is: ``done`` and ``frames`` (None: unknown)."""
    source: ClipSource | None = photo.clip
    if source is None:
        raise JeansError("not a clip")
    return {"done": source.done, "frames": source.frames}


__all__ = [
    "CLIPS_KEPT",
    "CLIP_MEDIA",
    "Cancelled",
    "ClipCaps",
    "ClipEndpoints",
    "ClipFiles",
    "ClipSource",
    "MadeClip",
    "client_gone",
    "make_clip",
    "open_clip",
    "progress",
]
