"""The web page's HTTP interface (Starlette). See ``docs/serve.md`` for the endpoints.

Ids in URLs are random keys of the in-memory store or indexes into the folder's list
of photos: no file path is ever built from what a client sends.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
import threading
from contextlib import asynccontextmanager
from dataclasses import dataclass, field, replace
from importlib import resources
from pathlib import Path

from starlette.applications import Starlette
from starlette.concurrency import run_in_threadpool
from starlette.requests import Request
from starlette.responses import JSONResponse, Response
from starlette.routing import Route

from jeanscv.errors import JeansError
from jeanscv.options import SUBJECTS

from . import clips, engine, folder, found
from .answers import Refused, client_text, nothing_found
from .answers import attachment as _attachment
from .answers import error as _error
from .answers import json_object as _json_object
from .guard import UNEXPECTED, BodyRefused, Guard, TooLarge, log_unexpected, own_names
from .store import Busy, FolderCuts, Pool, Stopping, Store, TooSlow

#: Default upload cap: a 60-MP camera RAW file is 60-120 MB.
DEFAULT_MAX_UPLOAD = 200 << 20
DEFAULT_MAX_PIXELS = 100_000_000
#: Default memory for the photos and results kept (a 12-MP photo holds about 60 MB).
DEFAULT_STORE_BYTES = 400 << 20
DOWNLOADS = ("image", "meme", "json", "svg", "gif", "clicks")
_MEDIA = {
    ".png": "image/png",
    ".jpg": "image/jpeg",
    ".webp": "image/webp",
    ".tif": "image/tiff",
    ".json": "application/json",
    ".svg": "image/svg+xml",
    ".gif": "image/gif",
}
#: The page's ES modules: app.js, the entry, imports the others.
_SCRIPTS = (
    "app.js",
    "state.js",
    "server.js",
    "drawing.js",
    "captions.js",
    "editor.js",
    "folder.js",
    "hover.js",
    "boxes.js",
    "zoom.js",
    "cursor.js",
    "clip.js",
    "found.js",
)
_STATIC = (
    {"/": ("index.html", "text/html; charset=utf-8")}
    | {f"/static/{name}": (name, "text/javascript; charset=utf-8") for name in _SCRIPTS}
    | {"/static/style.css": ("style.css", "text/css; charset=utf-8")}
)


@dataclass
class Config:
    """The server's settings (``jeanscv serve`` options)."""

    host: str = "127.0.0.1"
    port: int = 8000
    folder: Path | None = None
    max_upload: int = DEFAULT_MAX_UPLOAD
    max_pixels: int = DEFAULT_MAX_PIXELS
    store_bytes: int = DEFAULT_STORE_BYTES
    workers: int = 1
    queue: int = 32
    #: Longest a request waits for a worker before it is answered 503 (seconds).
    max_wait: float = 30.0
    #: Longest a request waits for its running job before it is answered 504 (seconds).
    job_seconds: float = 120.0
    backend: str | None = None
    warm: bool = True
    #: Longest a request body may stall before it is answered 408 (seconds).
    body_timeout: float = 30.0
    #: Log tracebacks of unexpected errors to the terminal (never to the client).
    debug: bool = False
    #: What the page takes as a clip (frames, seconds, pixels a frame).
    clip_caps: clips.ClipCaps = field(default_factory=clips.ClipCaps)
    #: Clips are made on their own workers, with their own bounded queue: a photo never
    #: waits behind a clip's making (seconds to minutes).
    clip_workers: int = 1
    clip_queue: int = 4
    extra_names: tuple[str, ...] = field(default_factory=tuple)


@dataclass
class Result:
    """One render: what its downloads are made from. The fitted objects stay with the
    photo (a few per photo, see :func:`engine.fitted_objects`), not here: a result holds
    no full-size mask, so many results cost little memory."""

    photo_id: str
    clicks: object | None  # Clicks
    options: engine.RenderOptions
    preview: bytes
    downloads: dict = field(default_factory=dict)  # kind -> (bytes, name), made on demand


class State:
    """Everything one server holds."""

    def __init__(self, config: Config):
        self.config = config
        self.photos = Store(config.store_bytes)
        self.results = Store(max(config.store_bytes // 4, 64 << 20))
        self.pool = Pool(config.workers, config.queue, max_wait=config.max_wait, job_seconds=config.job_seconds)
        self.clip_pool = Pool(
            config.clip_workers,
            config.clip_queue,
            max_wait=config.max_wait,
            job_seconds=config.job_seconds,
            name="jeanscv-serve-clip",
        )
        self.tmp: Path | None = None  # made when the server starts, removed when it stops
        self.folder_lock = threading.Lock()
        self.backend = config.backend
        self.folder = config.folder.resolve() if config.folder is not None else None
        self.compiling = False  # the fit kernels were not compiled when the server started
        # Folder items (by name) whose subject may be the wrong thing, once known: their
        # output was made, or they were opened, here (True/False; clicks make it False).
        self.unsure: dict[str, bool] = {}
        self.cuts = FolderCuts()  # folder photos' hypotheses, cut once for page and outputs
        self.clip_files = clips.ClipFiles()

    def open(self) -> None:
        self.tmp = Path(tempfile.mkdtemp(prefix="jeanscv-serve-"))

    def stop(self) -> None:
        """Answer every waiting and running request at once (the server is stopping)."""
        self.pool.stop()
        self.clip_pool.stop()

    def close(self) -> None:
        """Stop, and remove the temporary folder; running jobs are not waited for."""
        self.stop()
        if self.tmp is not None:
            shutil.rmtree(self.tmp, ignore_errors=True)


def _safe_name(filename: str | None) -> str:
    """A display name from the client's file name: its last part, printable, short.
    Only ever shown and used to name downloads, never opened."""
    name = (filename or "photo").replace("\\", "/").rsplit("/", 1)[-1]
    name = "".join(c for c in name if c.isprintable() and c not in '"<>|:*?')[-120:].strip(". ")
    return name or "photo"


def _suffix(name: str) -> str:
    """The temporary copy's extension: the client's, if it is one jeanscv reads (RAW
    files are recognised by it), else none (Pillow then tells the format by content)."""
    from jeanscv.io.clip import CLIP_EXTENSIONS
    from jeanscv.io.image import SUPPORTED_EXTENSIONS
    from jeanscv.io.svg import SVG_EXTENSIONS

    suffix = Path(name).suffix.lower()
    return suffix if suffix in SUPPORTED_EXTENSIONS | SVG_EXTENSIONS | CLIP_EXTENSIONS else ".img"


class _Api(clips.ClipEndpoints, folder.FolderEndpoints):
    """The endpoints of one server (a method a route) and the jobs they give its pool,
    over the server's :class:`State`."""

    def __init__(self, config: Config, state: State) -> None:
        self.config, self.state = config, state
        self.pages = {
            path: (resources.files(__package__).joinpath("static", file).read_bytes(), media)
            for path, (file, media) in _STATIC.items()
        }

    async def job(self, name: str, function, *args, pool: Pool | None = None):
        """``function(*args)`` on the photos' pool (or ``pool``): its value, else
        :class:`Refused` with the one-line reason (a bad input 422, busy 503, stopping 503,
        too slow 504, a bug 500)."""
        pool = pool or self.state.pool
        try:
            return await pool.run(function, *args)
        except Busy:
            retry = str(pool.retry_after())
            what = "clips" if pool is self.state.clip_pool else "photos"
            busy = f"the server is busy with other {what}: trying again in a moment"
            raise Refused(503, busy, {"Retry-After": retry}) from None
        except Stopping:
            raise Refused(503, "the server is stopping") from None
        except TooSlow:
            limit = f"{self.config.job_seconds:g}"
            raise Refused(504, f"{name}: took longer than the server's limit of {limit} s") from None
        except Exception as exc:  # noqa: BLE001 - any failure is one line; the terminal has the rest of a bug
            from ..worker import failure_reason

            if not isinstance(exc, JeansError):
                log_unexpected(exc, name, self.config.debug)
            raise Refused(422, f"{name}: {failure_reason(exc)}") from None

    async def static(self, request: Request) -> Response:
        body, media = self.pages[request.url.path]
        return Response(body, media_type=media, headers={"Cache-Control": "no-cache"})

    async def options(self, request: Request) -> Response:
        if self.state.compiling and not engine.kernels_warming():
            self.state.compiling = False  # compiled: said once, never again
        return JSONResponse(
            {
                "garments": engine.garments(),
                "styles": list(engine.STYLES),
                "postures": list(engine.POSTURES),
                "max_upload": self.config.max_upload,
                "folder": self.config.folder is not None,
                "folder_name": self.config.folder.name if self.config.folder is not None else "",
                # A fresh install's first run: the page says the kernels are being compiled.
                "compiling": self.state.compiling,
                "compile_seconds": engine.COMPILE_SECONDS,
            }
        )

    def render(self, photo_id: str, photo: engine.Photo, clicks, render_options) -> dict:
        objects = engine.fitted_objects(photo, clicks, render_options, self.state.backend)
        preview = engine.encode_preview(engine.preview_picture(photo, objects, render_options))
        result = Result(photo_id, clicks, render_options, preview)
        result_id = self.state.results.put(result, _result_bytes(result))
        self.state.photos.resize(photo_id, photo.nbytes)
        detections = found.page_detections(photo, clicks, objects)
        return {
            "result": result_id,
            "preview": f"/api/results/{result_id}/preview",
            "width": photo.size[0],
            "height": photo.size[1],
            "objects": engine.page_objects(photo, objects),
            "summary": engine.report_summary(photo, objects),
            # The detected animals the page offers, and which one wears the jeans.
            "detections": detections,
            # "Name it": the meme that names what wears the jeans (--top auto's).
            "caption": found.caption(photo, detections),
            "clicks": clicks is not None,
            "downloads": {kind: f"/api/results/{result_id}/{kind}" for kind in DOWNLOADS},
        }

    def open_and_render(
        self, path: Path, name: str, clicks_for, subject: str = "auto", photo=None, shared=None
    ) -> dict:
        photo = photo or engine.open_photo(path, name, self.config.max_pixels, subject, shared)
        photo_id = self.state.photos.put(photo, photo.nbytes)
        clicks = clicks_for(photo) if clicks_for else None
        answer = self.render(photo_id, photo, clicks, engine.RenderOptions())
        if clicks is not None:
            answer["saved_clicks"] = [obj.to_json() for obj in clicks.objects]
        if photo.clip is not None:
            answer["clip"] = photo.clip.summary()
        if photo.kind == "photo":
            # The click session (about half a second) is made while the person looks,
            # on a worker that no request is waiting for.
            self.state.pool.submit_background(_prepare_session, photo)
            self.state.pool.submit_background(_prepare_hover, photo)  # a second job: a click can come first
        return {"photo": photo_id, "name": name, "kind": photo.kind, **answer}

    def upload_job(self, upload, name: str, subject: str) -> dict:
        fd, temporary = tempfile.mkstemp(suffix=_suffix(name), dir=self.state.tmp)
        kept = False
        try:
            with os.fdopen(fd, "wb") as copy:
                upload.file.seek(0)
                shutil.copyfileobj(upload.file, copy, 1 << 20)
            # A clip is kept for making; its first frame is the photo clicked on.
            photo = clips.open_clip(Path(temporary), name, self.config.clip_caps, self.config.max_pixels, subject)
            if photo is not None:
                self.state.clip_files.keep(Path(temporary))
                kept = True
            return self.open_and_render(Path(temporary), name, None, subject, photo)
        finally:
            if not kept:
                try:
                    os.unlink(temporary)
                except OSError:
                    pass  # the server stopped and removed its temporary folder

    async def upload(self, request: Request) -> Response:
        try:
            form = await request.form(max_files=1, max_fields=8)
        except (TooLarge, BodyRefused):
            raise  # answered 413, or as the stalled or stopped upload says
        except Exception:  # noqa: BLE001 - malformed multipart: one line, never a traceback
            return _error(400, "expected a multipart form with one file in the field 'file'")
        try:
            file = form.get("file")
            if file is None or isinstance(file, str):
                return _error(400, "expected a multipart form with one file in the field 'file'")
            name = _safe_name(file.filename)
            subject = form.get("subject") or "auto"
            if subject not in SUBJECTS:
                return _error(422, f"unknown subject (use {', '.join(SUBJECTS)})")
            return JSONResponse(await self.job(name, self.upload_job, file, name, subject))
        finally:
            await form.close()

    async def clicked(self, request: Request) -> tuple:
        """``(photo id, photo, clicks, render options)`` of a request on a photo (its URL's
        photo, its JSON body's ``objects`` and ``options``); :class:`Refused` (404, 422)."""
        photo_id = request.path_params["photo"]
        photo = self.state.photos.get(photo_id)
        if photo is None:
            raise Refused(404, "no such photo (it may have expired: drop it again)")
        try:
            data = await _json_object(request)
            render_options = engine.RenderOptions.from_json(data.get("options"))
            clicks = engine.clicks_from_json(data.get("objects"), photo.size)
        except JeansError as exc:
            raise Refused(422, f"{photo.name}: {exc}") from None
        return photo_id, photo, clicks, render_options

    def render_clicked(self, photo_id: str, photo: engine.Photo, clicks, render_options) -> dict:
        """:meth:`render` of a request's clicks, where "nothing clear there" (a click or a
        box on plain background) is an answer, ``{"nothing": reason}``, not a refusal: the
        page shows it and takes the click back, and the browser logs no failed request."""
        try:
            return self.render(photo_id, photo, clicks, render_options)
        except JeansError as exc:
            if not nothing_found(exc):
                raise
            return {"nothing": client_text(f"{photo.name}: {exc}")}

    async def rerender(self, request: Request) -> Response:
        photo_id, photo, clicks, render_options = await self.clicked(request)
        answer = await self.job(photo.name, self.render_clicked, photo_id, photo, clicks, render_options)
        return JSONResponse({"photo": photo_id, "name": photo.name, "kind": photo.kind, **answer})

    async def result_file(self, request: Request) -> Response:
        result = self.state.results.get(request.path_params["result"])
        kind = request.path_params["kind"]
        if not isinstance(result, Result):
            return _error(404, "no such result (it may have expired: render it again)")
        if kind == "preview":
            return Response(result.preview, media_type="image/jpeg", headers={"Cache-Control": "private, max-age=3600"})
        if kind == "captions":  # the meme's captions over the preview (a few tens of ms: not the pool's queue)
            top, bottom = (request.query_params.get(key, "")[:200] for key in ("top", "bottom"))
            layer, fits = await run_in_threadpool(engine.caption_layer, result.preview, top, bottom)
            # How each caption was fitted rides along (ASCII JSON): the page says when one is cut.
            headers = {"Cache-Control": "private, max-age=3600", "X-Caption-Fit": json.dumps(fits)}
            return Response(layer, media_type="image/png", headers=headers)
        if kind not in DOWNLOADS:
            return _error(404, "no such download")
        photo = self.state.photos.get(result.photo_id)
        if photo is None:
            return _error(404, "the photo has expired: drop it again")
        wanted = result.options
        if kind == "meme":
            query = request.query_params
            wanted = replace(
                wanted,
                top=query.get("top", wanted.top)[:200],
                bottom=query.get("bottom", wanted.bottom)[:200],
                side_by_side=query.get("side_by_side", "1" if wanted.side_by_side else "0") == "1",
            )
        key = (kind, wanted)
        made = result.downloads.get(key)
        if made is None:
            made = await self.job(photo.name, self.make_download, photo, result, wanted, kind)
            if len(made[0]) < (32 << 20):
                result.downloads = {k: v for k, v in result.downloads.items() if k[0] != kind}  # the newest of a kind
                result.downloads[key] = made
                self.state.results.resize(request.path_params["result"], _result_bytes(result))
        data, filename = made
        media = _MEDIA.get(Path(filename).suffix.lower(), "application/octet-stream")
        if filename.endswith(".clicks.json"):
            media = "application/json"
        return Response(data, media_type=media, headers={"Content-Disposition": _attachment(filename)})

    async def original(self, request: Request) -> Response:
        photo = self.state.photos.get(request.path_params["photo"])
        if photo is None:
            return _error(404, "no such photo (it may have expired: drop it again)")
        if photo.original_jpeg is None:
            photo.original_jpeg = engine.encode_preview(photo.preview)
        return Response(
            photo.original_jpeg, media_type="image/jpeg", headers={"Cache-Control": "private, max-age=3600"}
        )

    async def hover(self, request: Request) -> Response:
        """The photo's first-click map (:func:`engine.hover_map`): what the page outlines
        under the pointer before a click, looked up there without asking again."""
        photo = self.state.photos.get(request.path_params["photo"])
        if photo is None:
            return _error(404, "no such photo (it may have expired: drop it again)")
        if photo.kind != "photo":
            return _error(404, "a silhouette drawing has nothing to click")
        data = await self.job(photo.name, engine.hover_map, photo)
        self.state.photos.resize(request.path_params["photo"], photo.nbytes)
        return Response(data, media_type="application/json", headers={"Cache-Control": "private, max-age=3600"})

    def make_download(self, photo: engine.Photo, result: Result, wanted: engine.RenderOptions, kind: str):
        objects = engine.fitted_objects(photo, result.clicks, wanted, self.state.backend)
        self.state.photos.resize(result.photo_id, photo.nbytes)
        return engine.download(photo, objects, wanted, kind, result.clicks)

    # ------------------------------------------------------------------ folder mode
    # Folder mode reads and writes only plain files directly in the folder: a photo,
    # output or clicks file that is a symbolic link (from an archive or a clone) is
    # never followed, so nothing outside the folder is read through one.
    @asynccontextmanager
    async def lifespan(self, app):
        self.state.open()
        if self.config.warm:
            # A fresh install compiles the kernels now, in the background (about 25 s):
            # the page says so while it lasts (/api/options "compiling").
            self.state.compiling = engine.kernels_to_compile()
            engine.warm_up()
        try:
            yield
        finally:
            self.state.close()

    async def too_large(self, request: Request, exc: TooLarge) -> Response:
        return _error(413, TooLarge.reason(self.config.max_upload))

    async def refused(self, request: Request, exc: Refused | BodyRefused) -> Response:
        return _error(exc.status, exc.reason, **(getattr(exc, "headers", None) or {}))

    async def unexpected(self, request: Request, exc: Exception) -> Response:
        # Starlette then raises it on to the Guard, which logs one line (never the client).
        return _error(500, UNEXPECTED)


def create_app(config: Config) -> Guard:
    """The ASGI application: Starlette's routes behind the :class:`Guard`."""
    state = State(config)
    api = _Api(config, state)
    routes = [Route(path, api.static) for path in _STATIC] + [
        Route("/api/options", api.options),
        Route("/api/photos", api.upload, methods=["POST"]),
        Route("/api/photos/{photo}/render", api.rerender, methods=["POST"]),
        Route("/api/photos/{photo}/original", api.original),
        Route("/api/photos/{photo}/hover", api.hover),
        Route("/api/photos/{photo}/clip", api.make_clip, methods=["POST"]),
        Route("/api/photos/{photo}/clip/progress", api.clip_progress),
        Route("/api/clips/{clip}", api.clip_file),
        Route("/api/results/{result}/{kind}", api.result_file),
        Route("/api/folder", api.folder_list),
        Route("/api/folder/{item:int}/thumb", api.folder_thumb, methods=["POST"]),
        Route("/api/folder/{item:int}/open", api.folder_open, methods=["POST"]),
        Route("/api/folder/{item:int}/clicks", api.folder_save, methods=["POST"]),
    ]

    app = Starlette(
        routes=routes,
        lifespan=api.lifespan,
        exception_handlers={
            TooLarge: api.too_large,
            Refused: api.refused,
            BodyRefused: api.refused,
            Exception: api.unexpected,
        },
    )
    app.state.jeanscv = state
    names = own_names(config.host) | set(config.extra_names)
    return Guard(
        app,
        names=names,
        port=config.port or None,
        max_body=config.max_upload,
        pages=frozenset(_STATIC),
        stopping=state.pool,
        body_timeout=config.body_timeout,
        debug=config.debug,
    )


def _result_bytes(result: Result) -> int:
    return len(result.preview) + sum(len(data) for data, _ in result.downloads.values()) + 4096


def _prepare_session(photo) -> None:
    try:
        with photo.lock:
            photo.session()
    except Exception:  # noqa: BLE001 - the first click will report it
        pass


def _prepare_hover(photo) -> None:
    try:
        engine.hover_map(photo)
    except Exception:  # noqa: BLE001 - the page's request for it will report it
        pass
