"""Encode images and write output files atomically.

A reader (or a crash, or Ctrl-C) never sees a half-written output: data goes to a
temporary file in the destination folder, is flushed to disk, and is renamed over
the target in one step. Any failure removes the temporary file.
"""

from __future__ import annotations

import contextlib
import io
import os
import re
import secrets
import stat
import threading
from collections.abc import Container, Iterator
from pathlib import Path
from typing import BinaryIO

import numpy as np
from PIL import Image

from jeanscv.errors import JeansError

try:
    import fcntl
except ImportError:  # Windows: no advisory locks; stale temporary files are not swept
    fcntl = None

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
    Its data reaches the disk before the rename, and the rename before this returns,
    so after a power loss the target is the old file or the complete new one. While it
    is written the temporary file is locked, which tells :func:`remove_stale_temporaries`
    that its writer is alive. A replaced file keeps its permission bits. Raises
    ``JeansError`` when the destination cannot be written.
    """
    with atomic_file(path) as f:
        f.write(data)


@contextlib.contextmanager
def atomic_file(path: str | Path) -> Iterator[BinaryIO]:
    """A binary file, open for writing (and seeking), that becomes ``path`` when the
    block ends without an exception; on any exception it is removed and ``path`` is
    untouched. For outputs written piece by piece (a clip's frames, as they are
    encoded); the guarantees are those of :func:`atomic_write_bytes`."""
    path = Path(path)
    folder = path.parent
    # The temporary file's name, known from just before the file exists: an interrupt
    # (Ctrl-C, a worker's SIGTERM) at any point after its creation still removes it.
    made: list[Path] = []
    try:
        tmp, fd = _create_temporary(path, made)
        with os.fdopen(fd, "w+b") as f:
            yield f
            f.flush()
            os.fsync(f.fileno())
            try:
                os.chmod(tmp, stat.S_IMODE(os.stat(path).st_mode))
            except FileNotFoundError:
                pass  # a new file: the umask already chose its mode
            with _writing_lock:
                if _abandoned:
                    raise JeansError("cannot write output: the program is stopping")
                os.replace(tmp, path)  # still locked: a sweeper never takes a file being renamed
                _writing.discard(tmp)
    except BaseException as exc:
        for tmp in made:
            with _writing_lock:
                _writing.discard(tmp)
            try:
                os.unlink(tmp)
            except OSError:
                pass  # already renamed or never created: nothing left behind
        if isinstance(exc, OSError):
            raise JeansError(f"cannot write output: {_reason(exc)}") from exc
        raise
    _fsync_folder(folder)


#: Temporary files being written now (this process), and whether writing has stopped.
_writing: set[Path] = set()
_writing_lock = threading.Lock()
_abandoned = False


def abandon_writes() -> list[Path]:
    """Remove the temporary files that writes in progress in other threads have made,
    and refuse every write from now on; returns what was removed.

    For a process that exits without waiting for its worker threads (``jeanscv serve``
    on Ctrl-C): no half-written file is left behind, and no new one is started.
    """
    global _abandoned
    with _writing_lock:
        _abandoned = True
        removed = sorted(_writing)
        _writing.clear()
    for tmp in removed:
        try:
            os.unlink(tmp)
        except OSError:
            pass  # renamed in the meantime: a complete output
    return removed


def _temporary_name(path: Path) -> Path:
    return path.parent / f".{path.name}.{secrets.token_hex(4)}.tmp"


def _create_temporary(path: Path, made: list[Path] | None = None) -> tuple[Path, int]:
    """Create and lock a new temporary file beside ``path``: ``(its path, descriptor)``.
    Its name is put in ``made`` just before it is created and stays there while it is
    ours, so that whoever catches an interrupt raised in between can remove it."""
    made = [] if made is None else made
    for _ in range(8):
        tmp = _temporary_name(path)
        made.append(tmp)
        try:
            # O_EXCL: never clobber someone else's file; mode 0o666 lets the umask decide.
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0), 0o666)
        except OSError as exc:
            made.remove(tmp)  # not made, or someone else's: never ours to remove
            raise JeansError(f"cannot write output: {_reason(exc)}") from exc
        if _lock(fd, wait=True) and not _still_named(tmp, fd):
            # A sweeper took it for a dead writer's between its creation and the lock.
            os.close(fd)
            made.remove(tmp)
            continue
        with _writing_lock:
            if not _abandoned:
                _writing.add(tmp)
                return tmp, fd
        os.close(fd)
        os.unlink(tmp)
        raise JeansError("cannot write output: the program is stopping")
    raise JeansError("cannot write output: its temporary file keeps being removed")


def _lock(fd: int, wait: bool) -> bool:
    """An exclusive advisory lock on ``fd``; False where locks are not available (or,
    without ``wait``, when another process holds it)."""
    if fcntl is None:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | (0 if wait else fcntl.LOCK_NB))
    except OSError:  # held by a live writer, or a file system without locks
        return False
    return True


def _still_named(tmp: Path, fd: int) -> bool:
    try:
        return os.stat(tmp).st_ino == os.fstat(fd).st_ino
    except OSError:
        return False


#: A temporary file of :func:`atomic_write_bytes`: ``.NAME.8HEX.tmp``.
_TEMPORARY = re.compile(r"\.(?P<name>.+)\.[0-9a-f]{8}\.tmp")


def remove_stale_temporaries(folder: str | Path, names: Container[str] | None = None) -> list[Path]:
    """Remove the temporary files that writers killed mid-write left in ``folder``.

    A killed process (SIGKILL, power loss) cannot remove its temporary file. Only
    those of targets in ``names`` (all when None) are looked at, and only unlocked
    ones are removed: a live writer, in this process or another, holds its lock until
    its rename. Returns the removed paths; where file locks are not available
    nothing is removed.
    """
    if fcntl is None:
        return []
    removed = []
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return []
    for entry in entries:
        match = _TEMPORARY.fullmatch(entry.name)
        if match is None or (names is not None and match.group("name") not in names):
            continue
        try:
            fd = os.open(entry.path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
        except OSError:
            continue  # renamed or removed meanwhile
        try:
            if stat.S_ISREG(os.fstat(fd).st_mode) and _lock(fd, wait=False) and _still_named(Path(entry.path), fd):
                os.unlink(entry.path)
                removed.append(Path(entry.path))
        except OSError:
            pass
        finally:
            os.close(fd)
    return removed


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


def output_extension(input_path: str | os.PathLike, fmt: str | None = None, clips: bool = False) -> str:
    """The extension (with dot) of the picture written for ``input_path``.

    Decided from the name alone, so that a resumed run finds the outputs of the
    previous one without decoding anything: SVG -> ``.png`` (the paper figure),
    RAW -> ``.jpg``, JPEG/PNG/WebP/TIFF keep theirs, other formats -> ``.png``;
    ``fmt`` (``png``/``jpg``/``webp``) overrides all. With ``clips`` (a writer of
    clips, the command line), clips keep theirs: GIF -> ``.gif``, videos -> ``.mp4``,
    and ``fmt`` may be ``gif`` or ``mp4`` too; a clip named as one is never a ``jpg`` (it
    keeps its own format; ``png`` is an animated PNG), and a still with ``gif`` or ``mp4``
    becomes a one-frame clip. Without ``clips`` (a writer of still pictures: the web
    page, the Dask runner), a GIF's first frame becomes a ``.png``.
    """
    from .clip_names import CLIP_EXTENSIONS, clip_format

    suffix = Path(input_path).suffix.lower()
    if clips and suffix in CLIP_EXTENSIONS:
        return "." + clip_format(input_path, fmt)
    if fmt:
        return "." + fmt.lower().lstrip(".")
    from .image import RAW_EXTENSIONS

    if suffix in RAW_EXTENSIONS:
        return ".jpg"
    return _KEEP_EXTENSION.get(suffix, ".png")
