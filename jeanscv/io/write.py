"""Encode images and write output files atomically.

A reader (or a crash, or Ctrl-C) never sees a half-written output: data goes to a
temporary file in the destination folder, is flushed to disk, and is renamed over
the target in one step. Any failure removes the temporary file.
"""

from __future__ import annotations

import io
import os
import secrets
import stat
from pathlib import Path

import numpy as np
from PIL import Image

from jeanscv.errors import JeansError

_FORMAT_BY_EXTENSION = {
    ".png": "PNG",
    ".jpg": "JPEG",
    ".jpeg": "JPEG",
    ".webp": "WEBP",
    ".tif": "TIFF",
    ".tiff": "TIFF",
}
_FORMAT_ALIASES = {"JPG": "JPEG", "TIF": "TIFF"}


def atomic_write_bytes(path: str | Path, data: bytes) -> None:
    """Write ``data`` to ``path`` so that the target is either untouched or complete.

    The temporary file lives in the destination folder (so the final rename stays
    on one file system) and is removed on any failure, KeyboardInterrupt included.
    A replaced file keeps its permission bits. Raises ``JeansError`` when the
    destination cannot be written.
    """
    path = Path(path)
    folder = path.parent
    tmp = folder / f".{path.name}.{secrets.token_hex(4)}.tmp"
    try:
        # O_EXCL: never clobber someone else's file; mode 0o666 lets the umask decide.
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0), 0o666)
    except OSError as exc:
        raise JeansError(f"cannot write output: {_reason(exc)}") from exc
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        try:
            os.chmod(tmp, stat.S_IMODE(os.stat(path).st_mode))
        except FileNotFoundError:
            pass  # a new file: the umask already chose its mode
        os.replace(tmp, path)
    except BaseException as exc:
        try:
            os.unlink(tmp)
        except OSError:
            pass  # already renamed or never created: nothing left behind
        if isinstance(exc, OSError):
            raise JeansError(f"cannot write output: {_reason(exc)}") from exc
        raise
    _fsync_folder(folder)


def _fsync_folder(folder: Path) -> None:
    """Persist the rename itself (POSIX); not possible on every OS, so best effort."""
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def _reason(exc: OSError) -> str:
    """Lower-case OS error text, e.g. ``permission denied``."""
    return (exc.strerror or str(exc) or type(exc).__name__).lower()


def write_text(path: str | Path, text: str) -> None:
    """Atomically write ``text`` as UTF-8 (newlines written as given)."""
    atomic_write_bytes(path, text.encode("utf-8"))


def format_for_path(path: str | Path) -> str:
    """Pillow format name from the file extension (``.jpg`` -> ``"JPEG"``)."""
    suffix = Path(path).suffix.lower()
    try:
        return _FORMAT_BY_EXTENSION[suffix]
    except KeyError:
        raise JeansError(
            f"cannot tell the output format from the extension '{suffix}' (use .png, .jpg, .webp or .tif)"
        ) from None


def on_white(image: np.ndarray) -> np.ndarray:
    """RGB(A) -> RGB, transparent parts over white (for JPEG and GIF frames)."""
    if image.ndim == 3 and image.shape[2] == 4:
        alpha = image[..., 3:].astype(np.float32) / 255.0
        rgb = image[..., :3].astype(np.float32) * alpha + 255.0 * (1.0 - alpha)
        return np.clip(np.rint(rgb), 0, 255).astype(np.uint8)
    return image


def encode_image(
    pixels: np.ndarray,
    fmt: str,
    quality: int = 95,
    exif: bytes | None = None,
    icc_profile: bytes | None = None,
) -> bytes:
    """Encode ``(H, W)`` grey, ``(H, W, 3)`` RGB or ``(H, W, 4)`` RGBA ``uint8`` pixels.

    ``fmt`` is ``"PNG"``, ``"JPEG"``/``"JPG"``, ``"WEBP"`` or ``"TIFF"``/``"TIF"``
    (any case). PNG, WebP and TIFF keep alpha; JPEG drops it (the colour channels are
    written as they are). ``quality`` (1..100) applies to JPEG and WebP. ``exif`` and
    ``icc_profile`` are embedded when given, so an output keeps the input's metadata.
    """
    pixels = np.asarray(pixels)
    if pixels.dtype != np.uint8 or not (pixels.ndim == 2 or (pixels.ndim == 3 and pixels.shape[2] in (3, 4))):
        raise JeansError(f"cannot encode an array of shape {pixels.shape} and dtype {pixels.dtype}")
    name = _FORMAT_ALIASES.get(fmt.upper(), fmt.upper())
    if name not in ("PNG", "JPEG", "WEBP", "TIFF"):
        raise JeansError(f"unsupported output format '{fmt}' (use png, jpg, webp or tif)")
    if not 1 <= quality <= 100:
        raise JeansError(f"quality must be 1..100, got {quality}")
    if name == "JPEG" and pixels.ndim == 3 and pixels.shape[2] == 4:
        pixels = pixels[..., :3]
    image = Image.fromarray(np.ascontiguousarray(pixels))
    options: dict[str, object] = {}
    if exif:
        options["exif"] = exif
    if icc_profile:
        options["icc_profile"] = icc_profile
    if name == "JPEG":
        # 4:4:4: the denim's sharp colour edges would bleed with halved chroma.
        options.update(quality=quality, subsampling=0)
    elif name == "WEBP":
        options.update(quality=quality)
    elif name == "TIFF":
        options.update(compression="tiff_adobe_deflate")
    buf = io.BytesIO()
    image.save(buf, name, **options)
    return buf.getvalue()


def write_image(
    path: str | Path,
    pixels: np.ndarray,
    fmt: str | None = None,
    quality: int = 95,
    **kw: bytes | None,
) -> None:
    """Encode ``pixels`` (see ``encode_image``) and write them atomically to ``path``.

    ``fmt`` defaults to the one named by the extension. ``kw`` passes ``exif`` and
    ``icc_profile`` on to ``encode_image``.
    """
    data = encode_image(pixels, fmt or format_for_path(path), quality=quality, **kw)
    atomic_write_bytes(path, data)


#: Picture formats an output keeps from its input; everything else becomes PNG.
_KEEP_EXTENSION = {
    ".jpg": ".jpg",
    ".jpeg": ".jpeg",
    ".jpe": ".jpg",
    ".jfif": ".jpg",
    ".png": ".png",
    ".webp": ".webp",
    ".tif": ".tif",
    ".tiff": ".tiff",
}


def output_extension(input_path: str | os.PathLike, fmt: str | None = None) -> str:
    """The extension (with dot) of the picture written for ``input_path``.

    Decided from the name alone, so that a resumed run finds the outputs of the
    previous one without decoding anything: SVG -> ``.png`` (the paper figure),
    RAW -> ``.jpg``, JPEG/PNG/WebP/TIFF keep theirs, other formats -> ``.png``;
    ``fmt`` (``png``/``jpg``/``webp``) overrides all.
    """
    if fmt:
        return "." + fmt.lower().lstrip(".")
    from .image import RAW_EXTENSIONS

    suffix = Path(input_path).suffix.lower()
    if suffix in RAW_EXTENSIONS:
        return ".jpg"
    return _KEEP_EXTENSION.get(suffix, ".png")
