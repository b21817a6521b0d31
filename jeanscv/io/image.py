"""Decode photos and camera RAW files into upright 8-bit RGB(A) arrays.

Photos (JPEG, PNG, WebP, TIFF, BMP, GIF) go through Pillow; camera RAW files (chosen
by extension, see ``RAW_EXTENSIONS``) go through rawpy/LibRaw, imported only when a
RAW file is actually loaded because the import is slow. Every way a file can be bad
(missing, empty, not an image, truncated, too large, too small) ends in a one-line
``JeansError``.
"""

from __future__ import annotations

import contextlib
import os
import struct
import sys
import threading
import warnings
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

import numpy as np
from PIL import Image, ImageFile, UnidentifiedImageError

from jeanscv.errors import JeansError
from jeanscv.io.files import open_regular

RAW_EXTENSIONS: frozenset[str] = frozenset(
    {
        ".dng",
        ".cr2",
        ".cr3",
        ".crw",
        ".nef",
        ".nrw",
        ".arw",
        ".srf",
        ".sr2",
        ".raf",
        ".orf",
        ".rw2",
        ".rwl",
        ".pef",
        ".ptx",
        ".srw",
        ".raw",
        ".3fr",
        ".fff",
        ".erf",
        ".kdc",
        ".dcr",
        ".k25",
        ".mrw",
        ".x3f",
        ".iiq",
        ".mos",
        ".mef",
        ".gpr",
    }
)
"""Lower-case file extensions decoded as camera RAW (with rawpy/LibRaw)."""

IMAGE_EXTENSIONS: frozenset[str] = frozenset(
    {".jpg", ".jpeg", ".jpe", ".jfif", ".png", ".webp", ".tif", ".tiff", ".bmp", ".dib", ".gif"}
)
"""Lower-case file extensions of the ordinary photo formats decoded with Pillow."""

SUPPORTED_EXTENSIONS: frozenset[str] = IMAGE_EXTENSIONS | RAW_EXTENSIONS
"""Every extension ``load_image`` accepts: the candidates when scanning a folder."""

MIN_SIDE = 8
"""Images narrower or shorter than this many pixels are rejected as too small."""

MAX_JPEG_METADATA = 16 << 20
"""Most bytes of JPEG metadata (EXIF, XMP, ICC, comments) read; see :func:`_check_jpeg_metadata`."""

# Only these Pillow plugins may identify a file: the supported formats, and never
# exotic ones (EPS, for one, would start Ghostscript on an untrusted file). The JPEG
# opener also returns "MPO" for the many camera JPEGs with a multi-picture index.
_PILLOW_FORMATS = ("JPEG", "PNG", "WEBP", "TIFF", "BMP", "DIB", "GIF")
_FORMAT_NAMES = {"MPO": "JPEG", "DIB": "BMP"}

# Pillow's decompression-bomb limit and truncated-image switch, and the warning
# filters, are process globals; they are set per call under this lock, so concurrent
# loads cannot see each other's.
_PILLOW_LOCK = threading.Lock()

# Errors Pillow's decoders raise for damaged data (TypeError: a TIFF whose StripOffsets
# are rationals or floats, found by bench/fuzz.py).
_DECODE_ERRORS = (OSError, SyntaxError, ValueError, EOFError, struct.error, zlib.error, IndexError, TypeError)

# LibRaw's ``flip`` code -> EXIF orientation (LibRaw maps EXIF 1..8 to "50132467").
_LIBRAW_FLIP_TO_EXIF = {0: 1, 1: 2, 2: 4, 3: 3, 4: 5, 5: 8, 6: 6, 7: 7}


@dataclass(frozen=True)
class LoadedImage:
    """A decoded image, upright as it is meant to be displayed.

    Attributes:
        pixels: ``(H, W, 3)`` RGB or ``(H, W, 4)`` RGBA ``uint8`` array, EXIF/RAW
            orientation already applied. RGBA whenever the file has an alpha channel
            (or a transparent palette entry / colour key), even an all-opaque one.
        alpha_meaningful: True when ``pixels`` has alpha and some pixel is not opaque.
        source_format: ``"JPEG"``, ``"PNG"``, ``"WEBP"``, ``"TIFF"``, ``"BMP"``,
            ``"GIF"``, or for RAW files the upper-case extension (``"DNG"``, ``"NEF"``...).
        is_raw: True when decoded from a camera RAW file.
        original_size: ``(width, height)`` of the full-resolution image as displayed.
            Equals the size of ``pixels`` except for RAW files decoded at half size
            (``raw_half_size``).
        exif_orientation: the file's EXIF orientation, 1..8 (1 = stored upright).
        icc_profile: the embedded ICC profile, only if it describes RGB (so it is
            still valid for ``pixels``); else None.
        exif: the embedded EXIF block with the orientation tag removed (the pixels
            are already upright), ready to be written into an output; else None.
    """

    pixels: np.ndarray
    alpha_meaningful: bool
    source_format: str
    is_raw: bool
    original_size: tuple[int, int]
    exif_orientation: int = 1
    icc_profile: bytes | None = None
    exif: bytes | None = None


def load_image(path: str | Path, max_pixels: int = 100_000_000, raw_half_size: bool = False) -> LoadedImage:
    """Decode a photo or camera RAW file into an upright 8-bit RGB(A) ``LoadedImage``.

    ``max_pixels`` caps width x height, checked from the file header before any
    pixel memory is allocated. RAW files are decoded at the camera's full resolution,
    or with ``raw_half_size`` at half (each 2x2 Bayer block becomes one pixel: faster,
    and plenty for fitting). Raises ``JeansError`` for every unreadable or
    unsuitable file.
    """
    if max_pixels < 1:
        raise JeansError("--max-pixels must be at least 1")
    path = Path(path)
    file = _open_nonempty(path)
    if path.suffix.lower() in RAW_EXTENSIONS:
        file.close()  # LibRaw opens the file itself
        return _load_raw(path, max_pixels, half_size=raw_half_size)
    # Damaged files make Pillow warn ("Corrupt EXIF data") and libtiff, libpng and
    # OpenCV print to file descriptor 2; the reason reaches the user once, as a
    # JeansError, so none of that gets through. The lock keeps the warning filters
    # (process-wide) from being swapped under another thread's load.
    with file, _PILLOW_LOCK, warnings.catch_warnings(), _c_stderr_silenced():
        warnings.simplefilter("ignore")
        return _load_pillow(file, max_pixels)


def _open_nonempty(path: Path) -> BinaryIO:
    """Open ``path`` for reading, raising for missing, unreadable, zero-byte and
    non-regular files (a FIFO would block the read forever, a device never end)."""
    try:
        file = open_regular(path)
    except FileNotFoundError:
        raise JeansError("file not found") from None
    except IsADirectoryError:
        raise JeansError("is a folder, not an image file") from None
    except OSError as exc:
        raise JeansError(f"cannot read file: {_os_reason(exc)}") from exc
    try:
        empty = not file.read(1)
        file.seek(0)
    except OSError as exc:
        file.close()
        raise JeansError(f"cannot read file: {_os_reason(exc)}") from exc
    if empty:
        file.close()
        raise JeansError("empty file")
    return file


def _os_reason(exc: OSError) -> str:
    """Lower-case OS error text, e.g. ``permission denied``."""
    return (exc.strerror or str(exc)).lower()


def _check_dimensions(width: int, height: int, max_pixels: int) -> None:
    """Reject images over ``max_pixels`` or under ``MIN_SIDE`` on a side."""
    if width * height > max_pixels:
        raise JeansError(
            f"image is {width}x{height} = {_megapixels(width * height)} MP, "
            f"over the --max-pixels limit of {_megapixels(max_pixels)} MP"
        )
    if width < MIN_SIDE or height < MIN_SIDE:
        raise JeansError(f"image too small: {width}x{height} pixels (need at least {MIN_SIDE}x{MIN_SIDE})")


def _megapixels(pixels: int) -> str:
    """Pixel count in MP to 4 significant digits, never in scientific notation."""
    return np.format_float_positional(pixels / 1e6, precision=4, unique=False, fractional=False, trim="-")


def _load_pillow(file: BinaryIO, max_pixels: int) -> LoadedImage:
    """Decode an open photo file with Pillow (which reads it lazily: header first).

    Called under ``_PILLOW_LOCK``: Pillow's decompression-bomb limit and
    truncated-image switch are module globals, set here per call.
    """
    saved = Image.MAX_IMAGE_PIXELS, ImageFile.LOAD_TRUNCATED_IMAGES
    ImageFile.LOAD_TRUNCATED_IMAGES = False
    try:
        # Opening reads only the header; with Pillow's own check off, the size
        # check below can name the dimensions.
        Image.MAX_IMAGE_PIXELS = None
        _check_jpeg_metadata(file)
        try:
            img = Image.open(file, formats=_PILLOW_FORMATS)
        except UnidentifiedImageError as exc:
            raise JeansError("not an image file (or an unsupported image format)") from exc
        except _DECODE_ERRORS as exc:
            raise JeansError("truncated or corrupt image") from exc
        _check_dimensions(img.width, img.height, max_pixels)
        # Pillow raises DecompressionBombError above twice its limit, so this
        # also guards frames and tiles decoded later (TIFF checks at load).
        Image.MAX_IMAGE_PIXELS = (max_pixels + 1) // 2
        rawmode = _tile_rawmode(img)
        orientation = _exif_orientation(img)  # as stored in the file
        try:
            img.load()
        except Image.DecompressionBombError as exc:
            raise JeansError(f"image frame is over the --max-pixels limit of {_megapixels(max_pixels)} MP") from exc
        except _DECODE_ERRORS as exc:
            raise JeansError("truncated or corrupt image") from exc
    finally:
        Image.MAX_IMAGE_PIXELS, ImageFile.LOAD_TRUNCATED_IMAGES = saved

    # Pillow orients some formats itself while loading (TIFF) and then drops the
    # tag, so only the orientation it still reports is left to apply.
    pixels = _orient(_to_rgb8(img), _exif_orientation(img))
    if img.mode in ("RGB", "RGBA", "LA") and ";16" in rawmode:
        # Pillow keeps only the high byte of 16-bit colour samples (65280 -> 255
        # instead of 254); decode again at full depth to round properly.
        # OpenCV applies the orientation for some formats and not others, so take
        # the layout that agrees with Pillow's decode to within that last bit.
        deep = _decode_16bit(file)
        for candidate in [] if deep is None else [deep, _orient(deep, orientation)]:
            if candidate.shape == pixels.shape and _max_difference(candidate, pixels) <= 1:
                pixels = candidate
                break
    height, width = pixels.shape[:2]
    return LoadedImage(
        pixels=pixels,
        alpha_meaningful=_alpha_meaningful(pixels),
        source_format=_FORMAT_NAMES.get(img.format or "", img.format or "unknown"),
        is_raw=False,
        original_size=(width, height),
        exif_orientation=orientation,
        icc_profile=_rgb_icc_profile(img.info.get("icc_profile")),
        exif=_exif_without_orientation(img.info.get("exif")),
    )


def _check_jpeg_metadata(file: BinaryIO) -> None:
    """Refuse a JPEG whose metadata segments (APPn, COM) before the image data hold more
    than :data:`MAX_JPEG_METADATA` bytes; other files pass untouched.

    Pillow joins EXIF segments by appending each to the last, so its time grows with
    the square of their number: 1,500 segments (98 MB) took 43 s and 400 MB. A camera's
    metadata is well under a megabyte; this walk reads only the segments' headers.
    """
    start = file.tell()
    try:
        if file.read(2) != b"\xff\xd8":
            return
        total = 0
        while True:
            marker = file.read(2)
            if len(marker) < 2 or marker[0] != 0xFF:
                return  # damaged or unusual: Pillow says what is wrong with it
            kind = marker[1]
            while kind == 0xFF:  # fill bytes before a marker
                byte = file.read(1)
                if not byte:
                    return
                kind = byte[0]
            if kind == 0xD8 or kind == 0x01 or 0xD0 <= kind <= 0xD7:
                continue  # markers without a length
            if kind in (0xDA, 0xD9):  # the image data (or the end) begins
                return
            header = file.read(2)
            if len(header) < 2:
                return
            length = struct.unpack(">H", header)[0]
            if 0xE0 <= kind <= 0xEF or kind == 0xFE:
                total += length
                if total > MAX_JPEG_METADATA:
                    raise JeansError(
                        f"JPEG metadata is over {MAX_JPEG_METADATA >> 20} MB (a photo's is well under 1 MB): refused"
                    )
            file.seek(max(length - 2, 0), os.SEEK_CUR)
    finally:
        file.seek(start)


def _exif_orientation(img: Image.Image) -> int:
    """EXIF orientation 1..8 (from EXIF, TIFF tags or XMP); 1 when absent or invalid."""
    try:
        orientation = int(img.getexif().get(0x0112, 1))
    except _DECODE_ERRORS:
        return 1  # unreadable metadata: show the pixels as stored
    return orientation if 1 <= orientation <= 8 else 1


def _tile_rawmode(img: Image.Image) -> str:
    """The first tile's raw sample layout, e.g. ``"RGB;16B"`` for 16-bit RGB PNG."""
    if not img.tile:
        return ""
    args = img.tile[0].args
    if isinstance(args, tuple):
        args = args[0] if args else ""
    return args if isinstance(args, str) else ""


def _to_rgb8(img: Image.Image) -> np.ndarray:
    """Loaded Pillow image -> ``(H, W, 3|4) uint8``, rounding 16-bit grey to 8 bits."""
    mode = img.mode
    if mode in ("I;16", "I;16L", "I;16B", "I;16N", "I"):
        grey = np.clip(np.asarray(img, dtype=np.int64), 0, 65535)
        return np.repeat(_scale_16_to_8(grey)[..., None], 3, axis=2)
    if mode == "F":
        grey = np.clip(np.nan_to_num(np.asarray(img, dtype=np.float64)), 0.0, 1.0)
        return np.repeat(np.round(grey * 255.0).astype(np.uint8)[..., None], 3, axis=2)
    has_alpha = mode in ("RGBA", "LA", "PA", "RGBa", "La") or "transparency" in img.info
    target = "RGBA" if has_alpha else "RGB"
    try:
        # convert() copies even to the same mode: 36 MB more for a 12-MP photo.
        converted = img if mode == target else img.convert(target)
    except ValueError as exc:
        raise JeansError(f"unsupported colour mode {mode}") from exc
    return np.array(converted, dtype=np.uint8)


def _scale_16_to_8(values: np.ndarray) -> np.ndarray:
    """Map 0..65535 to 0..255 by rounding (v * 255 / 65535), e.g. 32768 -> 128."""
    values = values.astype(np.int64)
    return ((values * 255 + 32767) // 65535).astype(np.uint8)


def _decode_16bit(file: BinaryIO) -> np.ndarray | None:
    """16-bit colour PNG or TIFF -> rounded ``(H, W, 3|4) uint8`` as stored; None if OpenCV can't."""
    import cv2  # only needed for this rare case; cv2's import is not free

    file.seek(0)
    data = file.read()
    if data.startswith(_PNG_SIGNATURE) and not _png_chunks_inside(data):
        return None
    deep = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), cv2.IMREAD_UNCHANGED)
    if deep is None or deep.dtype != np.uint16 or deep.ndim != 3:
        return None
    if deep.shape[2] == 3:
        deep = deep[..., ::-1]  # BGR -> RGB
    elif deep.shape[2] == 4:
        deep = deep[..., [2, 1, 0, 3]]  # BGRA -> RGBA
    else:
        return None
    return np.ascontiguousarray(_scale_16_to_8(deep))


_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _png_chunks_inside(data: bytes) -> bool:
    """Whether every chunk of a PNG ends inside the file.

    OpenCV's PNG reader allocates what a chunk's length field claims: a 640-byte
    16-bit PNG whose IDAT claimed 1 GiB took 1 GiB of memory and 3 to 14 seconds.
    Pillow decodes such a file from the bytes actually there.
    """
    pos = len(_PNG_SIGNATURE)
    while pos + 8 <= len(data):
        (length,) = struct.unpack(">I", data[pos : pos + 4])
        pos += 12 + length  # length, type, data, CRC
    return pos <= len(data)


def _max_difference(a: np.ndarray, b: np.ndarray) -> int:
    return int(np.abs(a.astype(np.int16) - b.astype(np.int16)).max())


def _orient(pixels: np.ndarray, orientation: int) -> np.ndarray:
    """Apply EXIF orientation 1..8 to an ``(H, W, C)`` array, giving the displayed image."""
    if orientation == 2:
        out = pixels[:, ::-1]  # mirrored left-right
    elif orientation == 3:
        out = pixels[::-1, ::-1]  # rotated 180
    elif orientation == 4:
        out = pixels[::-1]  # mirrored top-bottom
    elif orientation == 5:
        out = pixels.transpose(1, 0, 2)  # mirrored about the main diagonal
    elif orientation == 6:
        out = np.rot90(pixels, k=-1)  # rotate 90 clockwise to display
    elif orientation == 7:
        out = pixels[::-1, ::-1].transpose(1, 0, 2)  # mirrored about the anti-diagonal
    elif orientation == 8:
        out = np.rot90(pixels, k=1)  # rotate 90 counter-clockwise to display
    else:
        out = pixels
    return np.ascontiguousarray(out)


def _alpha_meaningful(pixels: np.ndarray) -> bool:
    return pixels.shape[2] == 4 and int(pixels[..., 3].min()) < 255


def _rgb_icc_profile(profile: bytes | None) -> bytes | None:
    """Keep an ICC profile only if it describes RGB data (bytes 16..20 of its header)."""
    if profile and len(profile) >= 20 and profile[16:20] == b"RGB ":
        return bytes(profile)
    return None


def _exif_without_orientation(exif: bytes | None) -> bytes | None:
    """EXIF block with the orientation tag dropped, since the pixels are now upright."""
    if not exif:
        return None
    parsed = Image.Exif()
    try:
        parsed.load(exif)
        if 0x0112 not in parsed:
            return bytes(exif)
        del parsed[0x0112]
        return parsed.tobytes() if len(parsed) else None
    except _DECODE_ERRORS:
        return None  # damaged EXIF is not worth copying into an output


_SILENCE_LOCK = threading.Lock()
_silenced = {"depth": 0, "saved": -1}


@contextlib.contextmanager
def _c_stderr_silenced():
    """C decoders print their own complaints to file descriptor 2 (LibRaw's "Unexpected
    end of file", libtiff's, libpng's, OpenCV's warnings); the reason reaches the user
    once, as our JeansError, so their lines are dropped.

    Nested and concurrent uses share one redirection (counted under a lock), so a thread
    leaving cannot restore descriptor 2 to another's devnull.
    """
    with _SILENCE_LOCK:
        if _silenced["depth"] == 0:
            try:
                sys.stderr.flush()
                saved = os.dup(2)
            except (OSError, ValueError):  # no usable file descriptor 2: nothing to silence
                saved = -1
            if saved >= 0:
                with open(os.devnull, "wb") as devnull:
                    os.dup2(devnull.fileno(), 2)
            _silenced["saved"] = saved
        _silenced["depth"] += 1
    try:
        yield
    finally:
        with _SILENCE_LOCK:
            _silenced["depth"] -= 1
            if _silenced["depth"] == 0 and _silenced["saved"] >= 0:
                os.dup2(_silenced["saved"], 2)
                os.close(_silenced["saved"])
                _silenced["saved"] = -1


def _load_raw(path: Path, max_pixels: int, half_size: bool) -> LoadedImage:
    """Demosaic a camera RAW file with LibRaw: camera white balance, sRGB, 8 bits."""
    import rawpy  # heavy; only loaded when a RAW file is opened

    raw = rawpy.RawPy()
    try:
        try:
            with _c_stderr_silenced():
                raw.open_file(str(path))
        except rawpy.LibRawError as exc:
            raise JeansError("not a readable RAW file: unsupported camera or not a RAW file") from exc
        except OSError as exc:
            raise JeansError(f"cannot read file: {_os_reason(exc)}") from exc
        sizes = raw.sizes
        flip = sizes.flip if sizes.flip in _LIBRAW_FLIP_TO_EXIF else 0
        # LibRaw flip bit 4 means the axes are swapped for display.
        width, height = (sizes.height, sizes.width) if flip & 4 else (sizes.width, sizes.height)
        _check_dimensions(width, height, max_pixels)
        try:
            with _c_stderr_silenced():
                raw.unpack()
                rgb = raw.postprocess(
                    use_camera_wb=True,
                    output_color=rawpy.ColorSpace.sRGB,
                    output_bps=8,
                    half_size=half_size,
                    gamma=(2.4, 12.92),  # the sRGB curve (LibRaw's default is BT.709)
                )
        except rawpy.LibRawError as exc:
            raise JeansError("not a readable RAW file: raw data truncated or corrupt") from exc
    finally:
        raw.close()
    pixels = np.asarray(rgb, dtype=np.uint8)
    if pixels.ndim == 2:
        pixels = pixels[..., None]
    if pixels.ndim != 3 or pixels.shape[2] not in (1, 3):
        raise JeansError("not a readable RAW file: unsupported colour layout")
    if pixels.shape[2] == 1:  # a damaged DNG can demosaic to one channel (found by bench/fuzz.py)
        pixels = np.repeat(pixels, 3, axis=2)
    pixels = np.ascontiguousarray(pixels)
    return LoadedImage(
        pixels=pixels,
        alpha_meaningful=False,
        source_format=path.suffix[1:].upper(),
        is_raw=True,
        original_size=(width, height),
        exif_orientation=_LIBRAW_FLIP_TO_EXIF[flip],
    )
