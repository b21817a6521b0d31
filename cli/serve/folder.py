"""Folder mode (``jeanscv serve FOLDER``): the folder's photos listed with thumbnails of
their outputs, opened on the page, their clicks saved beside them and their outputs made
again, or reverted to automatic.

The outputs are made by the command line's own worker, so they are ``jeanscv FOLDER``'s
bytes (saved clicks included); auto's hypotheses are cut once per photo and shared
between its thumbnail, the page and its saved clicks (:class:`.store.FolderCuts`). Only
the folder's own regular files are read or written, never through a symbolic link, and
no path comes from the client: items are indexes into the folder's list.
"""

from __future__ import annotations

import io
import os
import stat
from pathlib import Path
from typing import TYPE_CHECKING

from PIL import Image
from starlette.requests import Request
from starlette.responses import JSONResponse, Response

from jeanscv.errors import JeansError
from jeanscv.options import JeansOptions
from jeanscv.subject.clicks import Clicks, read_clicks, sidecar_path, write_clicks

from .. import worker
from ..discover import Job
from . import engine
from .answers import error as _error
from .answers import json_object

if TYPE_CHECKING:
    from jeanscv.subject.photo import SharedHypotheses

#: Long side of a folder item's thumbnail.
_THUMB_SIDE = 480


def folder_jobs(folder: Path) -> list[Job]:
    """The folder's photos as the command line finds them (``jeanscv FOLDER``), in order;
    not its videos, which the page cannot show (a GIF opens on its first frame)."""
    from jeanscv.io.clip_names import CLIP_EXTENSIONS

    from ..discover import collect

    videos = CLIP_EXTENSIONS - {".gif"}
    return [
        job for job in collect([str(folder)]).jobs if isinstance(job, Job) and job.path.suffix.lower() not in videos
    ]


def saved_clicks(job: Job) -> Clicks | None:
    """The photo's clicks sidecar, when it has a usable one (the command line's rule for
    which file that is: :func:`jeanscv_cli.worker.saved_clicks`); never one that is a
    symbolic link (folder mode reads only the folder's own files)."""
    path = worker.saved_clicks(job, JeansOptions())
    if path is None or path.is_symlink():
        return None
    try:
        return read_clicks(path)
    except JeansError:
        return None


def output_stale(job: Job) -> bool:
    """Whether the folder photo's output is missing, or older than its clicks sidecar
    (the command line's rule: it would redo it)."""
    return "image" in worker.wanted_outputs(job, JeansOptions(), overwrite=False)


def write_folder_outputs(
    job: Job, backend: str | None, max_pixels: int, shared: SharedHypotheses | None = None
) -> bool | None:
    """Make the folder photo's output as ``jeanscv FOLDER`` does (its saved clicks
    included), with auto's hypotheses from ``shared`` where they are cut already (the
    same bytes); JeansError with the failure's one-line reason. Returns whether its
    subject may be the wrong thing (None where that does not apply: clicks or a drawing)."""
    options = JeansOptions(backend=backend, max_pixels=max_pixels, detector=engine.DETECTOR)
    outcome = worker.process(job, options, overwrite=True, shared=shared)
    if outcome.status == "failed":
        raise JeansError(outcome.error)
    return outcome.info.get("uncertain")


def save_clicks(
    job: Job, clicks: Clicks | None, backend: str | None, max_pixels: int, shared: SharedHypotheses | None = None
) -> bool:
    """Save the folder photo's clicks beside it, then make its output from them as the
    command line does; JeansError with the reason when that fails. ``clicks`` None
    reverts the photo to automatic: its clicks file is removed and the output made again.
    Returns whether the photo may have the wrong subject (never, with clicks)."""
    sidecar = sidecar_path(job.path)
    if clicks is not None:
        write_clicks(sidecar, clicks)
    else:
        try:
            sidecar.unlink()
        except FileNotFoundError:
            pass
    uncertain = write_folder_outputs(job, backend, max_pixels, shared)
    return clicks is None and bool(uncertain)


#: Largest output file a thumbnail is made from (a 100-MP PNG is about 300 MB).
MAX_THUMB_SOURCE = 512 << 20


def output_thumbnail(path: Path, side: int) -> bytes:
    """A JPEG of an output picture with its long side at most ``side`` (for the gallery).

    The file is opened without following a symbolic link and must be a regular file;
    JeansError (naming only the file) when it cannot be read or decoded.
    """
    from jeanscv.io.files import open_regular

    try:
        file = open_regular(path, follow_links=False)
    except OSError as exc:
        raise JeansError(f"cannot read {path.name} ({(exc.strerror or 'error').lower()})") from None
    with file:
        if os.fstat(file.fileno()).st_size > MAX_THUMB_SOURCE:
            raise JeansError(f"cannot read {path.name} (not a picture file of a usable size)")
        data = file.read()
    try:
        with Image.open(io.BytesIO(data), formats=("JPEG", "PNG", "WEBP", "TIFF")) as image:
            image.draft("RGB", (side, side))
            image = image.convert("RGBA") if image.mode in ("RGBA", "LA", "P") else image.convert("RGB")
            image.thumbnail((side, side))
            if image.mode == "RGBA":
                white = Image.new("RGB", image.size, (255, 255, 255))
                white.paste(image, mask=image.getchannel("A"))
                image = white
            buffer = io.BytesIO()
            image.save(buffer, "JPEG", quality=85)
    except (OSError, SyntaxError, ValueError, EOFError, Image.DecompressionBombError):
        raise JeansError(f"{path.name} is damaged") from None
    return buffer.getvalue()


class FolderEndpoints:
    """The folder's endpoints, a part of the server's ``_Api`` (its ``config``, ``state``,
    ``job`` and ``open_and_render``)."""

    def folder_items(self) -> list:
        return [job for job in folder_jobs(self.config.folder) if _plain_file_in(job.path, self.state.folder)]

    def folder_job(self, request: Request):
        if self.config.folder is None:
            return None
        index = request.path_params["item"]
        jobs = self.folder_items()
        return jobs[index] if 0 <= index < len(jobs) else None

    def item_entry(self, index: int, job) -> dict:
        return {
            "item": index,
            "name": str(job.path.relative_to(self.config.folder)),
            "output": _plain_file_in(job.outputs["image"], self.state.folder),
            "clicks": saved_clicks(job) is not None,
            "thumb": f"/api/folder/{index}/thumb",
            # Whether its subject may be the wrong thing: None until known (its output
            # made or the photo opened by this server), False once clicked.
            "uncertain": self.state.unsure.get(job.path.name),
        }

    async def folder_list(self, request: Request) -> Response:
        if self.config.folder is None:
            return _error(404, "not serving a folder (start with: jeanscv serve FOLDER)")
        jobs = self.folder_items()
        return JSONResponse(
            {"folder": self.config.folder.name, "items": [self.item_entry(i, j) for i, j in enumerate(jobs)]}
        )

    def thumbnail(self, job) -> bytes:
        """The item's output as a thumbnail, made first when missing or stale, and made
        again when the file there cannot be read (a damaged output is not kept)."""
        output = job.outputs["image"]
        with self.state.folder_lock:
            _refuse_links(job, self.state.folder)
            if output_stale(job):
                self._write_outputs(job)
            try:
                return output_thumbnail(output, _THUMB_SIDE)
            except JeansError:
                self._write_outputs(job)
                return output_thumbnail(output, _THUMB_SIDE)

    def _write_outputs(self, job) -> None:
        shared = self.state.cuts.of(job.path.name)
        self._remember(job, write_folder_outputs(job, self.state.backend, self.config.max_pixels, shared))

    def _remember(self, job, uncertain: bool | None) -> None:
        """Keep a folder item's ``uncertain`` for the listing (clicks count as sure)."""
        self.state.unsure[job.path.name] = bool(uncertain)

    async def folder_thumb(self, request: Request) -> Response:
        job = self.folder_job(request)
        if job is None:
            return _error(404, "no such photo in the folder")
        made = await self.job(job.path.name, self.thumbnail, job)
        # Whether its subject may be the wrong thing, as the listing's ``uncertain`` says it
        # now (known once this server made the output): the page marks the tile at once.
        uncertain = self.state.unsure.get(job.path.name)
        headers = {
            "Cache-Control": "no-cache",
            "X-Uncertain": "unknown" if uncertain is None else str(uncertain).lower(),
        }
        return Response(made, media_type="image/jpeg", headers=headers)

    async def folder_open(self, request: Request) -> Response:
        job = self.folder_job(request)
        if job is None:
            return _error(404, "no such photo in the folder")

        def saved(photo):
            clicks = saved_clicks(job)
            if clicks is None or photo.kind != "photo":
                return None
            try:
                clicks.check(photo.size)
            except JeansError:
                return None
            return clicks

        shared = self.state.cuts.of(job.path.name)  # cut already for its thumbnail, or now for its outputs too
        answer = await self.job(
            job.path.name, self.open_and_render, job.path, job.path.name, saved, "auto", None, shared
        )
        answer["item"] = request.path_params["item"]
        self._remember(job, not answer.get("clicks") and answer.get("summary", {}).get("uncertain"))
        return JSONResponse(answer)

    async def folder_save(self, request: Request) -> Response:
        job = self.folder_job(request)
        if job is None:
            return _error(404, "no such photo in the folder")
        try:
            data = await json_object(request)
        except JeansError as exc:
            return _error(422, str(exc))
        photo = self.state.photos.get(str(data.get("photo", "")))
        if photo is None:
            return _error(404, "no such photo (it may have expired: open it again)")
        if photo.name != job.path.name:
            return _error(422, "this photo is not that folder item")
        try:
            clicks = engine.clicks_from_json(data.get("objects"), photo.size)
            if clicks is None and data.get("revert") is not True:  # reverting to automatic is said outright
                raise JeansError("no clicks to save: click the subject first")
        except JeansError as exc:
            return _error(422, f"{photo.name}: {exc}")

        def save() -> None:
            with self.state.folder_lock:
                _refuse_links(job, self.state.folder)
                # Clicks say what the subject is; reverted, automatic finding's doubt is back.
                shared = self.state.cuts.of(job.path.name)
                self._remember(job, save_clicks(job, clicks, self.state.backend, self.config.max_pixels, shared))

        await self.job(photo.name, save)
        return JSONResponse(self.item_entry(request.path_params["item"], job))


def _plain_file_in(path: Path, folder: Path) -> bool:
    """Whether ``path`` is a regular file, not a symbolic link, directly in ``folder``."""
    try:
        info = os.lstat(path)
    except OSError:
        return False
    return stat.S_ISREG(info.st_mode) and path.parent.resolve() == folder


def _refuse_links(job, folder: Path) -> None:
    """JeansError when the photo, its output or its clicks file is a symbolic link (or
    not in the folder): folder mode reads and writes only the folder's own files."""
    for path in (job.path, job.outputs["image"], sidecar_path(job.path)):
        if path.is_symlink():
            raise JeansError(
                f"{path.name} is a symbolic link: not followed (folder mode reads only the folder's files)"
            )
    if not _plain_file_in(job.path, folder):
        raise JeansError("not a file of the folder")
