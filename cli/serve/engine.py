"""The server's adapter to the library and the command line's worker for a photo.

Everything the page does to a photo goes through here: decode an upload, the
automatic result, a result from clicks and the full-resolution downloads. The HTTP
layer (:mod:`.app`) never calls :mod:`jeanscv` itself; its clip and folder endpoints
(:mod:`.clips`, :mod:`.folder`) call the command line's own clip maker and worker.

Clicks become silhouettes in :func:`silhouettes_from_clicks`: the photo keeps one
``ClickSession`` (the library's ``extract_silhouettes(clicks=...)`` makes a new one per
call, half a second on a 12-MP photo), made with the hypotheses that the automatic
segmentation cut when the photo was opened (cut once:
:class:`~jeanscv.subject.photo.SharedHypotheses`), and each object is segmented and
framed as the library does it, so the page's result is the command line's.

Coordinates sent to and from the page are pixels of the photo as displayed (x right,
y down, package convention); the interactive preview is a copy whose long side is at
most :data:`PREVIEW_SIDE`, and the full-resolution picture is made on download.
"""

from __future__ import annotations

import io
import json
import threading
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING

import cv2
import numpy as np
from PIL import Image

from jeanscv import api
from jeanscv.errors import JeansError
from jeanscv.options import POSTURES, STYLES, JeansOptions
from jeanscv.run.runner import encode_picture, report_text
from jeanscv.subject.clicks import VERSION as CLICKS_VERSION
from jeanscv.subject.clicks import Clicks
from jeanscv.subject.framing import Framing
from jeanscv.subject.silhouettes import box_of

from .. import worker
from ..discover import Job
from ..extras import optimisation_gif, svg_document
from .found import offered_detections

if TYPE_CHECKING:
    from jeanscv.subject.photo import SharedHypotheses

#: Long side of the interactive preview: clicks on 12-MP photos stay quick.
PREVIEW_SIDE = 1280
#: Trajectory frames sent to the page for the fit's animation.
ANIMATION_FRAMES = 40
#: Contour vertices sent to the page are simplified to this many image pixels (at most).
CONTOUR_TOLERANCE = 1.5
#: Fitted results kept per photo (the latest clicks, and a download's): each holds full-size masks.
FITS_KEPT = 3
#: How the page finds a photo's subject: as the command line does, the shipped detector
#: first (``--detector auto``). A negative click alone edits the subject the page shows
#: (the photo's click session is given it: :meth:`Photo.session`). A clip's first frame
#: too, as the clip itself finds it (:mod:`.clips`).
DETECTOR = "auto"


@dataclass(frozen=True)
class RenderOptions:
    """The options the page offers (everything else is the command line's default)."""

    style: str = "denim"
    garment: str = "jeans"
    posture: str = "upright"
    top: str = ""
    bottom: str = ""
    side_by_side: bool = False

    @classmethod
    def from_json(cls, data) -> RenderOptions:
        """Options from the page's JSON; JeansError naming a bad value."""
        from jeanscv.plugins import available_garments

        if data is None:
            return cls()
        if not isinstance(data, dict):
            raise JeansError("options must be a JSON object")
        options = cls(
            style=str(data.get("style", "denim")),
            garment=str(data.get("garment", "jeans")),
            posture=str(data.get("posture", "upright")),
            top=str(data.get("top") or "")[:200],
            bottom=str(data.get("bottom") or "")[:200],
            side_by_side=bool(data.get("side_by_side", False)),
        )
        if options.style not in STYLES:
            raise JeansError(f"unknown style {options.style!r} (use denim or flat)")
        if options.posture not in POSTURES:
            raise JeansError(f"unknown posture {options.posture!r} (use upright or any)")
        if options.garment not in available_garments():
            raise JeansError(f"unknown garment {options.garment!r}")
        return options

    def fit_key(self) -> tuple:
        """What the fits depend on (captions and layout do not)."""
        return (self.garment, self.posture)

    def jeans_options(self, backend: str | None, max_pixels: int = 100_000_000) -> JeansOptions:
        """The library's options for these (every other one at the command line's default)."""
        return JeansOptions(
            garment=self.garment,
            posture=self.posture,
            style=self.style,
            top=self.top or None,
            bottom=self.bottom or None,
            side_by_side=self.side_by_side,
            backend=backend,
            max_pixels=max_pixels,
            detector=DETECTOR,
        )


def garments() -> list[str]:
    """The garment names the page offers."""
    from jeanscv.plugins import available_garments

    return sorted(available_garments())


def default_backend() -> str:
    """The fitting backend the command line would pick on this machine's CPU."""
    from jeanscv.device import resolve_backend

    return resolve_backend(None, "cpu")


#: About how long a fresh install's first run compiles the fit kernels (two free cores;
#: the command line's first run says the same).
COMPILE_SECONDS = 25


def kernels_to_compile() -> bool:
    """Whether the fit kernels are not compiled for this installation yet (its first run)."""
    from jeanscv.fitting._fast import kernels_cached

    return default_backend() == "fast" and not kernels_cached()


def kernels_warming() -> bool:
    """Whether :func:`warm_up`'s background thread still loads or compiles the kernels."""
    from jeanscv.fitting import _fast

    return _fast.warming()


def warm_up() -> None:
    """Compile or load the fit kernels now, load the detector, and have segmentation's
    colour tables built, so the first photo does not wait for them."""
    from jeanscv.fitting import _fast
    from jeanscv.subject.scene import prepare_lab_tables

    prepare_lab_tables()
    if DETECTOR != "none":
        _warm_detector()
    if default_backend() == "fast":
        _fast.warm_up()


_detector_warming: threading.Thread | None = None


def _warm_detector() -> None:
    """Import torch, load the detector's model and run it once in the background, once per
    process (about 2 s that the first photo would otherwise wait); a failure is the first
    photo's to report (:func:`jeanscv.subject.detected.find`: classical finding, one line)."""
    global _detector_warming

    def load() -> None:
        from jeanscv.detect import detect

        try:
            # One run on a small grey picture: torch's first call on a graph costs more
            # than a second beyond the model's loading, which the first photo or clip
            # would otherwise wait for.
            detect(np.full((64, 64, 3), 128, np.uint8))
        except Exception:  # noqa: BLE001 - reported where the photo needs the detector
            pass

    if _detector_warming is None:
        _detector_warming = threading.Thread(target=load, name="jeanscv-warm-up-detector", daemon=True)
        _detector_warming.start()


@dataclass
class Photo:
    """A decoded photo or silhouette, held while the page works on it.

    ``pixels``: the decoded image at full size (None for an SVG); ``size``: (width,
    height) as displayed, the frame of every coordinate; ``preview``: the picture the
    page shows, long side at most :data:`PREVIEW_SIDE`; ``auto``: the automatic
    silhouettes at full size; ``shared``: the automatic segmentation's hypotheses, held
    for the click session (which lets them go).
    """

    name: str
    kind: str  # "photo" or "silhouette"
    pixels: np.ndarray | None
    loaded: object | None  # LoadedImage
    size: tuple[int, int]
    preview: np.ndarray
    auto: list
    auto_error: str = ""
    original_jpeg: bytes | None = None
    shared: SharedHypotheses | None = None
    _session: object | None = None
    hover: bytes | None = None  # the hover preview's map (hover_map), made once
    lock: threading.Lock = field(default_factory=threading.Lock)
    hover_lock: threading.Lock = field(default_factory=threading.Lock)  # one hover map made at a time
    fits: dict = field(default_factory=dict)  # (fit key, clicks key) -> [(silhouette, fit)]
    clip: object | None = None  # a clip's ClipSource (cli/serve/clips.py): this is its first frame
    #: The detected animals the page offers ({"class", "score", "box"}, photo pixels, most
    #: prominent first; the person or animal dressed by automatic finding among them).
    detections: list = field(default_factory=list)

    @property
    def scale(self) -> float:
        """Preview pixels per photo pixel."""
        return self.preview.shape[1] / self.size[0]

    @property
    def nbytes(self) -> int:
        """Memory this photo holds (what the store's byte cap counts)."""
        total = self.preview.nbytes + (0 if self.pixels is None else self.pixels.nbytes)
        masks = {id(s.mask): s.mask.nbytes for s in self.auto}
        fits = tuple(self.fits.values())  # a snapshot: another thread may add one
        masks |= {id(o.silhouette.mask): o.silhouette.mask.nbytes for fit in fits for o in fit}
        total += sum(masks.values())
        if self._session is not None:
            total += self.pixels.nbytes // 8  # working copies and cached masks
        total += len(self.hover or b"")
        if self.shared is not None:
            total += self.shared.nbytes
        return total

    def session(self):
        """The click session (made on first use: a few tenths of a second with the
        automatic segmentation's hypotheses). Negative clicks alone edit the automatic
        subject the page shows (the detector's animal, or classical finding's subject),
        which the session is given. Hold ``lock``."""
        if self._session is None:
            from jeanscv.subject.interactive import ClickSession

            shown = np.asarray(self.auto[0].mask) >= 0.5 if self.auto else None
            self._session = ClickSession(self.pixels, shared=self.shared, automatic=shown, detector=DETECTOR)
            self.shared = None  # the session holds what it needs
        return self._session


def _downscale(pixels: np.ndarray, side: int) -> np.ndarray:
    height, width = pixels.shape[:2]
    scale = min(1.0, side / max(width, height))
    if scale >= 1.0:
        return np.ascontiguousarray(pixels)
    size = (max(1, round(width * scale)), max(1, round(height * scale)))
    return cv2.resize(pixels, size, interpolation=cv2.INTER_AREA)


def _figure_preview(picture: np.ndarray, silhouette) -> np.ndarray:
    """A silhouette figure at preview size; an SVG's figure is drawn on the 256 canvas,
    which its framing places on the drawing's own width and height."""
    width, height = (int(v) for v in silhouette.framing.image_size)
    scale = min(1.0, PREVIEW_SIDE / max(width, height))
    target = (max(1, round(width * scale)), max(1, round(height * scale)))
    if silhouette.mask_is_canvas:
        forward = silhouette.framing.canvas_to_image * scale
        return cv2.warpAffine(picture, forward, target, flags=cv2.INTER_AREA, borderValue=(255, 255, 255))
    if picture.shape[1::-1] == target:
        return picture
    return cv2.resize(picture, target, interpolation=cv2.INTER_AREA)


def open_photo(
    path: Path | np.ndarray,
    name: str,
    max_pixels: int,
    subject: str = "auto",
    shared: SharedHypotheses | None = None,
    detector: str = DETECTOR,
) -> Photo:
    """Decode and segment a file (an upload's temporary copy, or a folder's photo) or
    decoded pixels (a clip's first frame); ``subject``: what automatic finding looks for
    (``--subject``); ``shared``: the photo's hypotheses when they may be cut already
    (a folder photo's, see :class:`.store.FolderCuts`); ``detector``: ``auto`` (the
    shipped detector first, as the command line and a clip's frame 0) or ``none`` (classical finding).

    Raises JeansError with the command line's one-line reason for a bad file.
    """
    from jeanscv.subject.photo import SharedHypotheses

    shared = shared or SharedHypotheses()  # auto's hypotheses, cut once for the click session too
    silhouettes, kind, pixels, loaded = api.prepare_input(
        path, max_pixels=max_pixels, shared=shared, subject=subject, detector=detector
    )
    if kind == "silhouette":
        first = silhouettes[0]
        size = tuple(int(v) for v in first.framing.image_size)
        preview = _figure_preview(api.figure(first), first)
        return Photo(name, kind, None, None, size, preview, silhouettes)
    height, width = pixels.shape[:2]
    auto = [_compact(s) for s in silhouettes]
    preview = _downscale(pixels, PREVIEW_SIDE)
    photo = Photo(name, kind, pixels, loaded, (width, height), preview, auto, shared=shared)
    photo.detections = offered_detections(pixels, auto, photo.size, detector)
    return photo


def _compact(silhouette):
    """A photo's silhouette with a bool mask when its mask holds only 0 and 1 (a 12-MP
    float mask is 48 MB); a soft one (a cut-out's alpha) is kept as it is."""
    mask = np.asarray(silhouette.mask)
    if mask.dtype != bool and np.count_nonzero((mask != 0) & (mask != 1)) == 0:
        silhouette = replace(silhouette, mask=mask >= 0.5)
    return silhouette


def silhouettes_from_clicks(photo: Photo, clicks: Clicks) -> list:
    """One full-size silhouette per clicked object, in order, as
    :func:`jeanscv.subject.extraction.extract_silhouettes` makes them, from the photo's own session."""
    from jeanscv.subject.extraction import clicked_silhouettes

    clicks.check(photo.size)
    with photo.lock:
        return clicked_silhouettes(photo.session(), clicks.objects)


def _clicks_key(clicks: Clicks | None) -> tuple:
    if clicks is None:
        return ()
    return tuple((obj.positive, obj.negative, obj.box) for obj in clicks.objects)


def fitted_objects(photo: Photo, clicks: Clicks | None, options: RenderOptions, backend: str | None) -> list:
    """``[FittedObject]``: the clicked objects (or the automatic ones), each fitted.

    Fits are remembered per photo by clicks and options, so a caption change or a
    download does not fit again.
    """
    key = (options.fit_key(), _clicks_key(clicks))
    with photo.lock:
        cached = photo.fits.pop(key, None)
        if cached is not None:
            photo.fits[key] = cached  # the most recently used last
            return cached
    if clicks is None:
        if not photo.auto:
            raise JeansError(photo.auto_error or "no object found to segment")
        silhouettes = photo.auto
    else:
        if photo.kind != "photo":
            raise JeansError("a silhouette drawing has nothing to click: its shape is the subject")
        silhouettes = silhouettes_from_clicks(photo, clicks)
    objects = [
        api.FittedObject(s, api.fit(s, options.garment, posture=options.posture, backend=backend)) for s in silhouettes
    ]
    with photo.lock:
        while len(photo.fits) >= FITS_KEPT:  # each holds full-size masks: keep a few
            photo.fits.pop(next(iter(photo.fits)))
        photo.fits[key] = objects
    return objects


def _scaled(silhouette, scale: float, shape: tuple[int, int]):
    """The silhouette on a copy of its photo scaled by ``scale`` (shape (h, w))."""
    mask = silhouette.mask
    if mask.dtype == bool:  # area-averaged as 8 bits: a quarter of a float copy's memory traffic
        plane = cv2.resize(mask.view(np.uint8) * np.uint8(255), (shape[1], shape[0]), interpolation=cv2.INTER_AREA)
        small = plane.astype(np.float32) / 255.0
    else:
        small = cv2.resize(mask.astype(np.float32), (shape[1], shape[0]), interpolation=cv2.INTER_AREA)
    framing = silhouette.framing
    scaled = Framing((framing.origin[0] * scale, framing.origin[1] * scale), framing.side * scale, (shape[1], shape[0]))
    return replace(silhouette, mask=small, framing=framing if silhouette.mask_is_canvas else scaled)


def preview_picture(photo: Photo, objects: list, options: RenderOptions) -> np.ndarray:
    """The jeans on the preview copy (no captions: the page draws them live)."""
    if photo.kind == "silhouette":
        first = objects[0]
        return _figure_preview(api.figure(first.silhouette, first.fit), first.silhouette)
    image = photo.preview
    scale = photo.scale
    for index, obj in enumerate(objects):
        small = _scaled(obj.silhouette, scale, image.shape[:2])
        image = api.composite(image, obj.fit, small, style=options.style, seed=index)
    return image


def full_result(photo: Photo, objects: list, options: RenderOptions):
    """A :class:`jeanscv.api.JeansResult` at full resolution, as the command line makes it."""
    if photo.kind == "silhouette":
        first = objects[0]
        image = api.figure(first.silhouette, first.fit)
        return api.JeansResult(image, first.silhouette, first.fit, "silhouette", None, objects)
    image = photo.pixels
    for index, obj in enumerate(objects):
        image = api.composite(image, obj.fit, obj.silhouette, style=options.style, seed=index)
    return api.JeansResult(image, objects[0].silhouette, objects[0].fit, "photo", photo.loaded, objects)


def _simplified(points: np.ndarray) -> list:
    contour = np.asarray(points, dtype=np.float32).reshape(-1, 1, 2)
    if len(contour) > 8:
        contour = cv2.approxPolyDP(contour, CONTOUR_TOLERANCE, True)
    return np.round(contour.reshape(-1, 2).astype(np.float64), 1).tolist()


def page_objects(photo: Photo, objects: list) -> list[dict]:
    """What the page draws over the photo, in photo pixels: outline, jeans, the fit's path."""
    entries = []
    for obj in objects:
        silhouette, fit = obj.silhouette, obj.fit
        if silhouette.mask_is_canvas:
            contours = api.silhouette_contours(silhouette)
        elif silhouette.contour is not None and len(silhouette.contour) >= 3:
            contours = [silhouette.contour]
        else:
            contours = api.silhouette_contours(silhouette)
        trajectory = np.asarray(fit.trajectory, dtype=np.float64)
        steps = np.unique(np.round(np.linspace(0, len(trajectory) - 1, ANIMATION_FRAMES)).astype(int))
        entries.append(
            {
                "outline": [_simplified(c) for c in contours if len(c) >= 3],
                "jeans": np.round(silhouette.framing.to_image(fit.vertices), 1).tolist(),
                "trajectory": np.round(silhouette.framing.to_image(trajectory[steps]), 1).tolist(),
                "method": silhouette.method,
                "box": [int(v) for v in box_of(silhouette)],
            }
        )
    return entries


def encode_preview(pixels: np.ndarray) -> bytes:
    """The preview as a JPEG (quality 88: small and quick to send)."""
    image = Image.fromarray(np.ascontiguousarray(pixels[..., :3]) if pixels.ndim == 3 else pixels)
    buffer = io.BytesIO()
    image.save(buffer, "JPEG", quality=88)
    return buffer.getvalue()


def caption_layer(preview: bytes, top: str, bottom: str) -> tuple[bytes, dict]:
    """The meme's captions alone, as a PNG the size of the preview, transparent elsewhere:
    drawn by the Meme download's own code (same font, wrapping and fitting), so what
    the page lays over its picture is what the download holds; and how each caption was
    fitted (``{"top": {"lines", "size", "cut"}, ...}``: the page says when one is cut)."""
    from ..extras import caption_fits, draw_captions

    with Image.open(io.BytesIO(preview)) as image:
        width, height = image.size
    fits = caption_fits(width, height, top, bottom)
    layer = draw_captions(np.zeros((height, width, 4), np.uint8), fits)
    buffer = io.BytesIO()
    Image.fromarray(layer, "RGBA").save(buffer, "PNG", compress_level=1)
    return buffer.getvalue(), {key: fit.summary() for key, fit in fits.items()}


def output_name(photo: Photo, suffix: str) -> str:
    """A download's file name: ``NAME.jeans.EXT`` like the command line's outputs (the
    meme is ``NAME.meme.EXT``: saved beside the image, neither replaces the other)."""
    return Path(photo.name).stem + ".jeans" + suffix


def download(
    photo: Photo, objects: list, options: RenderOptions, kind: str, clicks: Clicks | None
) -> tuple[bytes, str]:
    """``(bytes, file name)`` of one download: ``image``, ``meme``, ``json``, ``svg``, ``gif`` or ``clicks``."""
    from jeanscv.io.write import output_extension

    if kind == "clicks":
        if clicks is None:
            raise JeansError("no clicks yet: click the photo first")
        return clicks.dumps().encode("utf-8"), Path(photo.name).stem + ".clicks.json"
    result = full_result(photo, objects, options)
    picture_suffix = output_extension(photo.name) if photo.kind == "photo" else ".png"
    job = Job(0, Path(photo.name), photo.name, {"image": Path(output_name(photo, picture_suffix))})
    if kind in ("image", "meme"):
        wanted = options if kind == "meme" else replace(options, top="", bottom="", side_by_side=False)
        pixels = worker.picture(result, wanted.jeans_options(None))
        target = Path(output_name(photo, picture_suffix))
        name = Path(photo.name).stem + ".meme" + picture_suffix if kind == "meme" else target.name
        return encode_picture(target, pixels, result), name
    if kind == "json":
        return report_text(result, job.display, str(job.outputs["image"])).encode("utf-8"), output_name(photo, ".json")
    if kind == "svg":
        polygons = [obj.silhouette.framing.to_image(obj.fit.vertices) for obj in objects]
        contours = [c for obj in objects for c in api.silhouette_contours(obj.silhouette)]
        text = svg_document(polygons, contours, tuple(int(v) for v in photo.size), f"jeanscv: {photo.name}")
        return text.encode("utf-8"), output_name(photo, ".svg")
    if kind == "gif":
        return optimisation_gif(result, 50, max_side=PREVIEW_SIDE), output_name(photo, ".gif")  # the preview's size
    raise JeansError(f"unknown download {kind!r}")


def report_summary(photo: Photo, objects: list) -> dict:
    """The few report fields the page shows."""
    first = objects[0]
    details = first.silhouette.details
    summary = {
        "objects": len(objects),
        "method": first.silhouette.method,
        "objective": round(float(first.fit.objective), 4),
        "uncertain": bool(details.get("uncertain", False)),
        "kind": details.get("kind", ""),  # what automatic finding took it for (animal, person, object)
        # What the detector said the automatic subject is ({"class", "score"}), or None.
        "detection": _named(details.get("detection")) if details.get("chosen") == "detector" else None,
    }
    return summary


def _named(detection: dict | None) -> dict | None:
    return None if not detection else {"class": detection["class"], "score": detection["score"]}


# ------------------------------------------------------------------------- page clicks


def clicks_from_json(data, size: tuple[int, int]) -> Clicks | None:
    """The page's clicks (``[{"positive": [[x, y]...], "negative": [...], "box": [x0, y0, x1, y1]}...]``,
    ``box`` optional; negative clicks alone: the automatic subject minus them), or None
    for none."""
    from jeanscv.subject.clicks import parse_clicks

    if data is None or data == []:
        return None
    if not isinstance(data, list):
        raise JeansError('"objects" must be a list of {"positive": [[x, y], ...], "negative": [...]}')
    objects = [
        obj for obj in data if isinstance(obj, dict) and (obj.get("positive") or obj.get("negative") or obj.get("box"))
    ]
    if not objects:
        return None
    document = {"format": "jeanscv-clicks", "version": CLICKS_VERSION, "objects": objects}
    clicks = parse_clicks(json.loads(json.dumps(document)))
    return Clicks(clicks.objects, (int(size[0]), int(size[1])))


# ------------------------------------------------------------------------- hover preview


def hover_map(photo: Photo) -> bytes:
    """The photo's first-click map for the page's hover preview, encoded
    (:func:`encode_hover_map`), made once per photo from its click session."""
    from jeanscv.subject.hover import first_click_map

    # Made once: a second caller (the page's request while the background job makes it)
    # waits for the first; clicks do not (the map only reads the session: photo.lock is
    # held just to get it).
    with photo.hover_lock:
        if photo.hover is None:
            with photo.lock:
                session = photo.session()
            photo.hover = encode_hover_map(first_click_map(session), photo.size)
        return photo.hover


def encode_hover_map(found, size: tuple[int, int]) -> bytes:
    """A :class:`~jeanscv.subject.hover.FirstClickMap` as the page reads it: JSON with the
    working copy's ``width`` and ``height``, the photo's ``size``, the superpixels'
    ``count``, ``labels`` (the superpixel of each working pixel, row by row, as
    little-endian uint16), ``choice`` (per superpixel, the region a click there takes,
    -1 none, as little-endian int16) and ``regions`` (a bit per superpixel per region,
    most significant bit first, each region's row padded to whole bytes); the three
    arrays deflated (zlib) and base64-encoded: 20-60 KB in all."""
    import base64
    import zlib

    def packed(data: bytes) -> str:
        return base64.b64encode(zlib.compress(data, 6)).decode("ascii")

    height, width = found.labels.shape
    count = len(found.choice)
    bits = np.zeros((max(len(found.regions), 1), count), bool)
    for row, nodes in enumerate(found.regions):
        bits[row, nodes] = True
    document = {
        "width": width,
        "height": height,
        "size": [int(size[0]), int(size[1])],
        "count": count,
        "labels": packed(found.labels.astype("<u2").tobytes()),
        "choice": packed(found.choice.astype("<i2").tobytes()),
        "regions": packed(np.packbits(bits, axis=1).tobytes()),
    }
    return json.dumps(document, separators=(",", ":")).encode("utf-8")
