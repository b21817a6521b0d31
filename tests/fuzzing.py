"""Fuzz targets: generated and mutated inputs for every parser and entry point of jeanscv.

Each :class:`Target` makes one case from a random source (``generate(rng)``) and feeds
it to one entry point (``run(case)``). The contract, checked by :func:`violation`: the
entry point returns a result or raises :class:`JeansError` with a one-line reason;
any other exception is a failure. The generators take ``random.Random``-like sources,
so the same code serves the suite (Hypothesis' ``st.randoms()``, derandomized, which
shrinks a failing case) and ``bench/fuzz.py`` (``random.Random(seed)`` per case,
fast and reproducible from the case number alone).

Seeds are made here, small (16..48 px), in every format and mode the decoders take:
PNG (RGB, RGBA, palette with transparency, 16-bit grey and RGB, iCCP, eXIf), JPEG
(EXIF orientation, ICC profile, progressive, CMYK, grey), TIFF (orientation tag,
16-bit, palette, LZW/deflate/packbits), WebP (lossy, lossless with alpha), GIF
(animated), BMP and a Bayer DNG. Mutations are byte-level (bit flips, interesting
integers in 2- and 4-byte fields, slices deleted, repeated, spliced, truncated) and
format-aware (PNG chunk CRCs repaired so the decoder reads past them; TIFF/EXIF IFD
entries rewritten: tag type, count, offset).
"""

from __future__ import annotations

import functools
import gzip
import io
import json
import os
import random
import struct
import sys
import tempfile
import warnings
import zlib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from jeanscv.errors import JeansError

ROOT = Path(__file__).resolve().parents[1]

#: The pixel cap the decoders get while fuzzing: the bound is part of what is tested,
#: and a mutated header claiming 100 MP would make each case slow, not interesting.
FUZZ_MAX_PIXELS = 2_000_000


class ContractViolation(Exception):
    """An entry point broke the contract without raising (a CLI exit code, a traceback)."""


@dataclass(frozen=True)
class Target:
    """One entry point under fuzz: ``generate(rng) -> case``, ``run(case)``."""

    name: str
    generate: Callable[[random.Random], Any]
    run: Callable[[Any], object]


def violation(target: Target, case: Any) -> str | None:
    """None when ``target.run(case)`` keeps the contract, else what went wrong (one line).

    Besides the exception, a warning or anything a C library writes to file descriptor
    2 breaks it: on the command line that would be a second line for one bad file.
    """
    with _Stderr() as stderr, warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        problem = _call(target, case)
    if problem is None and caught:
        problem = f"warned {caught[0].category.__name__}: {' '.join(str(caught[0].message).split())[:200]}"
    if problem is None and stderr.text.strip():
        problem = f"wrote to stderr: {stderr.text.strip()[:200]!r}"
    return problem


def _call(target: Target, case: Any) -> str | None:
    try:
        target.run(case)
    except JeansError as exc:
        message = str(exc)
        if not message.strip() or "\n" in message or "\r" in message or len(message) > 1000:
            return f"JeansError reason is not one short line: {message[:300]!r}"
    except RecursionError as exc:
        return f"RecursionError: {str(exc)[:200]}"
    except Exception as exc:  # noqa: BLE001 - any other exception is what the fuzzer looks for
        return f"{type(exc).__name__}: {' '.join(str(exc).split())[:300]}"
    return None


class _Stderr:
    """Captures what is written to file descriptor 2 (by C code too) inside ``with``."""

    def __enter__(self) -> _Stderr:
        sys.stderr.flush()
        self._file = tempfile.TemporaryFile()
        self._saved = os.dup(2)
        os.dup2(self._file.fileno(), 2)
        self.text = ""
        return self

    def __exit__(self, *exc: object) -> None:
        sys.stderr.flush()
        os.dup2(self._saved, 2)
        os.close(self._saved)
        self._file.seek(0)
        self.text = self._file.read().decode("utf-8", "replace")
        self._file.close()


# ------------------------------------------------------------------ byte mutation

_INTERESTING = (0, 1, 2, 7, 8, 16, 127, 128, 255, 256, 0x7FFF, 0x8000, 0xFFFF, 0x10000, 0x7FFFFFFF, 0x80000000)
_INTERESTING += (0xFFFFFFFF, 50000, 65500, 3, 4, 5, 6, 9)


def _interesting_int(rng: random.Random) -> int:
    if rng.random() < 0.7:
        return rng.choice(_INTERESTING)
    return rng.getrandbits(rng.choice((8, 16, 32)))


def mutate_bytes(data: bytes, rng: random.Random, others: tuple[bytes, ...] = ()) -> bytes:
    """1..4 random byte-level mutations of ``data`` (``others``: material to splice in)."""
    out = bytearray(data)
    for _ in range(rng.randint(1, 4)):
        kind = rng.randrange(9)
        n = len(out)
        if n == 0:
            out += bytes(rng.getrandbits(8) for _ in range(rng.randint(1, 16)))
            continue
        pos = rng.randrange(n)
        if kind == 0:  # flip a few bits
            for _ in range(rng.randint(1, 8)):
                p = rng.randrange(n)
                out[p] ^= 1 << rng.randrange(8)
        elif kind == 1:  # a byte set to an edge value
            out[pos] = rng.choice((0, 1, 0x7F, 0x80, 0xFF, rng.getrandbits(8)))
        elif kind in (2, 3):  # a 2- or 4-byte field set to an interesting integer
            size = 2 if kind == 2 else 4
            value = _interesting_int(rng) & ((1 << (8 * size)) - 1)
            order = rng.choice("<>")
            out[pos : pos + size] = struct.pack(order + ("H" if size == 2 else "I"), value)
        elif kind == 4:  # delete a slice
            del out[pos : pos + rng.randint(1, max(1, min(64, n // 4)))]
        elif kind == 5:  # repeat a slice
            length = rng.randint(1, max(1, min(256, n - pos)))
            out[pos:pos] = out[pos : pos + length] * rng.randint(1, 4)
        elif kind == 6:  # insert random bytes
            out[pos:pos] = bytes(rng.getrandbits(8) for _ in range(rng.randint(1, 32)))
        elif kind == 7:  # truncate
            del out[rng.randrange(max(1, n // 8), n + 1) :]
        else:  # splice in a piece of another seed
            if others:
                other = rng.choice(others)
                if other:
                    start = rng.randrange(len(other))
                    out[pos : pos + rng.randint(0, 64)] = other[start : start + rng.randint(1, 256)]
    return bytes(out)


def fix_png_crcs(data: bytes) -> bytes:
    """Recompute every PNG chunk's CRC (so a mutated chunk reaches its decoder)."""
    if not data.startswith(b"\x89PNG\r\n\x1a\n"):
        return data
    out = bytearray(data[:8])
    pos = 8
    while pos + 8 <= len(data):
        (length,) = struct.unpack(">I", data[pos : pos + 4])
        end = pos + 8 + length
        if end + 4 > len(data):
            out += data[pos:]
            break
        kind_and_body = data[pos + 4 : end]
        out += data[pos : pos + 4] + kind_and_body + struct.pack(">I", zlib.crc32(kind_and_body) & 0xFFFFFFFF)
        pos = end + 4
    else:
        out += data[pos:]
    return bytes(out)


_TIFF_TYPES = (1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 16, 17, 18, 0, 19, 0xFFFF)


def mutate_tiff_ifd(data: bytes, rng: random.Random) -> bytes:
    """Rewrite one entry of a TIFF's (or a TIFF-based EXIF block's) first IFD."""
    start = data.find(b"II*\x00")
    order = "<"
    if start < 0 or (rng.random() < 0.5 and data.find(b"MM\x00*") >= 0):
        start = data.find(b"MM\x00*")
        order = ">"
    if start < 0 or start + 8 > len(data):
        return data
    (ifd,) = struct.unpack(order + "I", data[start + 4 : start + 8])
    ifd += start
    if ifd + 2 > len(data):
        return data
    (count,) = struct.unpack(order + "H", data[ifd : ifd + 2])
    count = min(count, (len(data) - ifd - 2) // 12)
    if count == 0:
        return data
    entry = ifd + 2 + 12 * rng.randrange(count)
    out = bytearray(data)
    field = rng.randrange(4)
    if field == 0:  # the tag itself: make it another known one
        tag = rng.choice((0x0100, 0x0101, 0x0102, 0x0103, 0x0106, 0x0111, 0x0112, 0x0115, 0x0116, 0x0117, 0x0140))
        out[entry : entry + 2] = struct.pack(order + "H", tag)
    elif field == 1:
        out[entry + 2 : entry + 4] = struct.pack(order + "H", rng.choice(_TIFF_TYPES))
    elif field == 2:
        out[entry + 4 : entry + 8] = struct.pack(order + "I", _interesting_int(rng) & 0xFFFFFFFF)
    else:
        out[entry + 8 : entry + 12] = struct.pack(order + "I", _interesting_int(rng) & 0xFFFFFFFF)
    return bytes(out)


# ------------------------------------------------------------------ image seeds


def _pil_bytes(image, fmt: str, **options) -> bytes:
    buffer = io.BytesIO()
    image.save(buffer, fmt, **options)
    return buffer.getvalue()


def _picture(height: int, width: int, seed: int = 0) -> np.ndarray:
    """A small photo-like RGB picture: a dark blob on a gradient, a little noise."""
    yy, xx = np.mgrid[:height, :width]
    rng = np.random.default_rng(seed)
    base = np.stack([xx * 255 // max(width - 1, 1), yy * 255 // max(height - 1, 1), np.full_like(xx, 120)], -1)
    blob = (xx - width / 2) ** 2 + (yy - height / 2) ** 2 < (min(width, height) / 3) ** 2
    base[blob] = (30, 20, 200)
    return np.clip(base + rng.integers(-8, 9, base.shape), 0, 255).astype(np.uint8)


@functools.lru_cache(maxsize=1)
def image_seeds() -> dict[str, bytes]:
    """Small valid files, by name (the extension says how ``load_image`` reads them)."""
    import cv2
    from PIL import Image, ImageCms

    rgb = _picture(24, 32)
    rgba = np.dstack([rgb, np.where(_picture(24, 32, 1)[..., 2] > 150, 255, 0).astype(np.uint8)])
    exif = Image.Exif()
    exif[0x0112] = 6
    exif[0x010F] = "FuzzCam"
    exif_bytes = exif.tobytes()
    icc = ImageCms.ImageCmsProfile(ImageCms.createProfile("sRGB")).tobytes()
    image = Image.fromarray(rgb)
    palette = image.convert("P", palette=Image.ADAPTIVE, colors=16)
    palette.info["transparency"] = 3
    grey16 = Image.fromarray(_picture(24, 32)[..., 0].astype(np.uint16) * 257)
    deep = (rgb.astype(np.uint16) * 257)[..., ::-1]
    frames = [Image.fromarray(_picture(16, 16, s)).convert("P") for s in range(2)]
    gif = io.BytesIO()
    frames[0].save(gif, "GIF", save_all=True, append_images=frames[1:], duration=50, loop=0)
    seeds = {
        "rgb.png": _pil_bytes(image, "PNG"),
        "rgba.png": _pil_bytes(Image.fromarray(rgba), "PNG"),
        "palette.png": _pil_bytes(palette, "PNG", transparency=3),
        "grey16.png": _pil_bytes(grey16, "PNG"),
        "rgb16.png": cv2.imencode(".png", deep)[1].tobytes(),
        "meta.png": _pil_bytes(image, "PNG", exif=exif_bytes, icc_profile=icc),
        "exif6.jpg": _pil_bytes(image, "JPEG", exif=exif_bytes, icc_profile=icc, quality=80),
        "progressive.jpg": _pil_bytes(image, "JPEG", progressive=True, quality=70),
        "cmyk.jpg": _pil_bytes(image.convert("CMYK"), "JPEG"),
        "grey.jpg": _pil_bytes(image.convert("L"), "JPEG"),
        "rgb.tif": _pil_bytes(image, "TIFF", exif=exif_bytes),
        "lzw.tif": _pil_bytes(Image.fromarray(rgba), "TIFF", compression="tiff_lzw"),
        "deflate.tif": _pil_bytes(image, "TIFF", compression="tiff_adobe_deflate"),
        "packbits.tif": _pil_bytes(palette, "TIFF", compression="packbits"),
        "rgb16.tif": cv2.imencode(".tif", deep)[1].tobytes(),
        "lossy.webp": _pil_bytes(image, "WEBP", quality=60, exif=exif_bytes, icc_profile=icc),
        "lossless.webp": _pil_bytes(Image.fromarray(rgba), "WEBP", lossless=True),
        "anim.gif": gif.getvalue(),
        "palette.bmp": _pil_bytes(palette.convert("RGB").convert("P"), "BMP"),
        "rgb.bmp": _pil_bytes(image, "BMP"),
        "bayer.dng": _tiny_dng(),
    }
    return seeds


def _tiny_dng() -> bytes:
    """A 32x48 Bayer DNG made by the sample images' own writer."""
    sys.path.insert(0, str(ROOT / "sample_images"))
    try:
        from make_samples import write_dng
    finally:
        sys.path.remove(str(ROOT / "sample_images"))
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "tiny.dng"
        write_dng(_picture(32, 48), path)
        return path.read_bytes()


def generate_image_case(rng: random.Random) -> tuple[str, bytes]:
    """``(name, bytes)``: a seed, mutated; sometimes renamed to another format's extension."""
    seeds = image_seeds()
    name = rng.choice(sorted(seeds))
    data = seeds[name]
    choice = rng.random()
    if choice < 0.2 and (b"II*\x00" in data or b"MM\x00*" in data):
        data = mutate_tiff_ifd(data, rng)
        if rng.random() < 0.5:
            data = mutate_bytes(data, rng)
    elif choice < 0.97:
        data = mutate_bytes(data, rng, tuple(seeds.values()))
    if data.startswith(b"\x89PNG") and rng.random() < 0.8:
        data = fix_png_crcs(data)
    if rng.random() < 0.05:
        name = "renamed" + rng.choice((".png", ".jpg", ".tif", ".webp", ".gif", ".bmp", ".dng", ".nef"))
    return name, data


class _Scratch:
    """A private folder for the files the file-reading targets need."""

    def __init__(self) -> None:
        self._folder: tempfile.TemporaryDirectory | None = None

    def path(self, name: str) -> Path:
        if self._folder is None:
            self._folder = tempfile.TemporaryDirectory(prefix="jeanscv-fuzz-")
        return Path(self._folder.name) / name

    def write(self, name: str, data: bytes) -> Path:
        path = self.path("case" + Path(name).suffix)
        path.write_bytes(data)
        return path


_SCRATCH = _Scratch()


def run_load_image(case: tuple[str, bytes]) -> object:
    from jeanscv.io.image import load_image

    name, data = case
    loaded = load_image(_SCRATCH.write(name, data), max_pixels=FUZZ_MAX_PIXELS, raw_half_size=True)
    pixels = loaded.pixels
    if pixels.dtype != np.uint8 or pixels.ndim != 3 or pixels.shape[2] not in (3, 4):
        raise ContractViolation(f"decoded to {pixels.dtype} {pixels.shape}")
    return loaded


def run_load_mask(case: tuple[str, bytes]) -> object:
    from jeanscv.subject.silhouettes import load_mask

    name, data = case
    mask = load_mask(_SCRATCH.write(name, data), max_pixels=FUZZ_MAX_PIXELS)
    if mask.dtype != bool or mask.ndim != 2:
        raise ContractViolation(f"mask is {mask.dtype} {mask.shape}")
    return mask


# ------------------------------------------------------------------------ clips


def clip_seeds() -> dict[str, bytes]:
    """Four-frame clips in every format jeanscv writes (and reads)."""
    from jeanscv.io.clip import write_clip

    frames = [_picture(24, 32, seed) for seed in range(4)]
    seeds = {}
    with tempfile.TemporaryDirectory() as folder:
        for fmt in ("gif", "mp4", "webp", "png"):
            path = Path(folder) / f"clip.{fmt}"
            write_clip(path, frames, fmt, fps=10.0)
            seeds[path.name] = path.read_bytes()
    return seeds


_CLIP_SEEDS: dict[str, bytes] = {}


def generate_clip_case(rng: random.Random) -> tuple[str, bytes]:
    """``(name, bytes)``: a clip seed, mutated."""
    if not _CLIP_SEEDS:
        _CLIP_SEEDS.update(clip_seeds())
    name = rng.choice(sorted(_CLIP_SEEDS))
    return name, mutate_bytes(_CLIP_SEEDS[name], rng, tuple(_CLIP_SEEDS.values()))


def run_clip(case: tuple[str, bytes]) -> object:
    from jeanscv.io.clip import ClipLimits, ClipReader

    name, data = case
    limits = ClipLimits(max_frames=50, max_seconds=60, max_frame_pixels=FUZZ_MAX_PIXELS)
    with ClipReader(_SCRATCH.write(name, data), limits) as reader:
        for frame in reader.frames():
            if frame.pixels.dtype != np.uint8 or frame.pixels.ndim != 3 or frame.pixels.shape[2] != 3:
                raise ContractViolation(f"decoded to {frame.pixels.dtype} {frame.pixels.shape}")
    return reader


# ------------------------------------------------------------------------ SVG

_NUMBER_TEXTS = ("0", "-0", "1e309", "-1e309", "1e-400", "nan", "inf", ".5.5", "1e", "--1", "1e38", "9" * 40, "+.e1")


def _number(rng: random.Random) -> str:
    r = rng.random()
    if r < 0.03:
        return rng.choice(_NUMBER_TEXTS)
    if r < 0.08:
        return repr(rng.choice((1e300, -1e300, 1e9, 3e8, 1e-300, 5e-324)))
    value = rng.uniform(-40, 300)
    return rng.choice((f"{value:.0f}", f"{value:.3f}", f"{value:.2e}", f"{value:g}"))


def _path_data(rng: random.Random) -> str:
    parts = [rng.choice(("M", "m", "M", "M", "M", "M", "L", ""))]
    parts.append(f"{_number(rng)} {_number(rng)}")
    for _ in range(rng.randint(0, 14)):
        cmd = rng.choice("MmLlHhVvCcSsQqTtAaZz")
        arity = {"M": 2, "L": 2, "H": 1, "V": 1, "C": 6, "S": 4, "Q": 4, "T": 2, "A": 7, "Z": 0}[cmd.upper()]
        if rng.random() < 0.03:
            arity += rng.choice((-1, 1, 2))
        values = [_number(rng) for _ in range(max(0, arity))]
        if cmd in "Aa" and len(values) >= 5 and rng.random() < 0.8:
            values[3], values[4] = rng.choice("01"), rng.choice(("0", "1", "2", "01"))
            if rng.random() < 0.3:  # flags glued together and to the next number
                values[3:6] = ["".join(values[3:6])]
        separator = rng.choice((" ", ",", "", "\n", " , "))
        parts.append(cmd + separator.join(values))
    if rng.random() < 0.05:
        parts.append(rng.choice(("#", "\x00", "é", "1.2.3", "e5", "Zx")))
    if rng.random() < 0.7:
        parts.append("Z")
    return " ".join(parts)


def _transform(rng: random.Random) -> str:
    items = []
    for _ in range(rng.randint(1, 3)):
        name = rng.choice(("matrix", "translate", "scale", "rotate", "skewX", "skewY", "bogus"))
        arities = {"matrix": (6,), "translate": (1, 2), "scale": (1, 2), "rotate": (1, 3), "bogus": (2,)}
        count = rng.choice(arities.get(name, (1,))) if rng.random() < 0.9 else rng.choice((0, 4, 7))
        items.append(f"{name}({', '.join(_number(rng) for _ in range(count))})")
    return rng.choice((" ", ",", "")).join(items)


def _attributes(rng: random.Random, tag: str, ids: list[str]) -> str:
    attrs = {}
    if tag == "path":
        attrs["d"] = _path_data(rng)
    elif tag == "rect":
        for key in ("x", "y", "width", "height", "rx", "ry"):
            if rng.random() < 0.8:
                attrs[key] = _number(rng) + rng.choice(("", "", "px", "%", "mm", "em"))
    elif tag in ("circle", "ellipse"):
        for key in ("cx", "cy", "r", "rx", "ry"):
            if rng.random() < 0.8:
                attrs[key] = _number(rng) + rng.choice(("", "", "%", "in"))
    elif tag in ("polygon", "polyline"):
        attrs["points"] = " ".join(_number(rng) for _ in range(rng.randint(0, 12)))
    elif tag == "use":
        attrs["href" if rng.random() < 0.5 else "xlink:href"] = "#" + rng.choice(ids + ["nope", ""])
        attrs["x"] = _number(rng)
    elif tag == "svg":
        attrs["viewBox"] = " ".join(_number(rng) for _ in range(rng.choice((4, 4, 3))))
        attrs["width"] = _number(rng) + rng.choice(("", "%"))
        attrs["height"] = _number(rng)
    if rng.random() < 0.3:
        attrs["transform"] = _transform(rng)
    if rng.random() < 0.3:
        attrs["fill"] = rng.choice(("none", "white", "#fff", "#000", "red", "rgb(255, 255, 255)", "rgb(1,2", "url(#g)"))
    if rng.random() < 0.15:
        attrs["fill-rule"] = rng.choice(("evenodd", "nonzero", "inherit", ""))
    if rng.random() < 0.15:
        attrs["style"] = rng.choice(
            ("display:none", "fill:none;", "opacity:0", "fill:#000 !important", "visibility:hidden;;:")
        )
    if rng.random() < 0.1:
        attrs[rng.choice(("opacity", "fill-opacity", "display", "visibility"))] = rng.choice(
            ("0", "0%", "none", "1", "x")
        )
    if rng.random() < 0.3:
        ident = f"i{rng.randrange(5)}"
        attrs["id"] = ident
        ids.append(ident)
    return "".join(f' {k}="{_xml_escape(v)}"' for k, v in attrs.items())


def _xml_escape(text: str) -> str:
    return text.replace("&", "&amp;").replace("<", "&lt;").replace('"', "&quot;")


_TAGS = ("path", "path", "rect", "circle", "ellipse", "polygon", "polyline", "g", "g", "a", "switch", "svg", "symbol")
_TAGS += ("use", "defs", "text", "clipPath", "foo:bar")


def _element(rng: random.Random, depth: int, ids: list[str]) -> str:
    tag = rng.choice(_TAGS)
    if depth == 0 and rng.random() < 0.5:
        tag = "path"
    attrs = _attributes(rng, tag, ids)
    children = ""
    if tag in ("g", "a", "switch", "svg", "symbol", "defs", "clipPath", "foo:bar") and depth < 6:
        children = "".join(_element(rng, depth + 1, ids) for _ in range(rng.randint(0, 3)))
    if rng.random() < 0.05:
        children += "text &amp; <![CDATA[ ]]> <!-- c -->"
    return f"<{tag}{attrs}>{children}</{tag}>"


def generate_svg_case(rng: random.Random) -> tuple[bytes, int, int]:
    """``(file bytes, canvas size, supersample)``: a generated SVG, sometimes mutated,
    re-encoded or gzipped."""
    ids: list[str] = []
    body = "".join(_element(rng, 0, ids) for _ in range(rng.randint(1, 4)))
    root_attrs = ' xmlns="http://www.w3.org/2000/svg" xmlns:xlink="http://www.w3.org/1999/xlink"'
    if rng.random() < 0.95:
        root_attrs += ' xmlns:foo="urn:foo"'
    view = rng.random()
    if view < 0.7:
        root_attrs += ' viewBox="0 0 256 256"'
    elif view < 0.9:
        root_attrs += f' viewBox="{" ".join(_number(rng) for _ in range(4))}"'
    else:
        root_attrs += f' width="{_number(rng)}" height="{_number(rng)}{rng.choice(("", "mm", "%", "em"))}"'
    prolog = ""
    encoding = rng.choice(("utf-8",) * 8 + ("utf-16", "utf-16-le", "utf-16-be", "latin-1", "bogus"))
    if rng.random() < 0.6:
        declared = encoding if encoding != "utf-16-le" else "utf-16"
        prolog = f'<?xml version="1.0" encoding="{declared}"?>'
    if rng.random() < 0.08:
        prolog += rng.choice(
            (
                '<!DOCTYPE svg PUBLIC "-//W3C//DTD SVG 1.1//EN" "http://www.w3.org/Graphics/SVG/1.1/DTD/svg11.dtd">',
                '<!DOCTYPE svg [<!ENTITY a "b">]>',
                "<!DOCTYPE svg [ ]>",
                '<?xml-stylesheet href="x.css"?>',
            )
        )
    text = f"{prolog}<svg{root_attrs}>{body}</svg>"
    try:
        data = text.encode("utf-8" if encoding == "bogus" else encoding)
    except UnicodeEncodeError:
        data = text.encode("utf-8")
    if encoding == "utf-16" and rng.random() < 0.3:
        data = data[2:]  # no byte-order mark
    if rng.random() < 0.2:
        data = mutate_bytes(data, rng)
    if rng.random() < 0.1:
        data = gzip.compress(data, mtime=0)
        if rng.random() < 0.3:
            data = mutate_bytes(data, rng)
    return data, rng.choice((16, 32, 64, 64, 256)), rng.choice((1, 2, 4))


def run_svg(case: tuple[bytes, int, int]) -> object:
    from jeanscv.io.svg import read_svg_silhouette_from_bytes

    data, canvas, supersample = case
    svg = read_svg_silhouette_from_bytes(data, canvas_size=canvas, supersample=supersample)
    alpha = svg.alpha
    if alpha.shape != (canvas, canvas) or not (np.all(alpha >= 0) and np.all(alpha <= 1)):
        raise ContractViolation(f"alpha {alpha.shape} outside [0, 1]")
    if not np.all(np.isfinite(svg.canvas_to_image)):
        raise ContractViolation("non-finite canvas_to_image")
    return svg


def generate_path_case(rng: random.Random) -> str:
    d = _path_data(rng)
    if rng.random() < 0.3:
        d = mutate_bytes(d.encode(), rng).decode("latin-1")
    return d


def run_flatten(case: str) -> object:
    from jeanscv.io.svg import flatten_path_data

    for polyline in flatten_path_data(case):
        if polyline.ndim != 2 or polyline.shape[1] != 2 or not np.all(np.isfinite(polyline)):
            raise ContractViolation(f"bad polyline {polyline.shape}")


# --------------------------------------------------------------------- clicks


def _json_junk(rng: random.Random, depth: int = 0) -> Any:
    r = rng.random()
    if r < 0.15 and depth < 4:
        return [_json_junk(rng, depth + 1) for _ in range(rng.randint(0, 3))]
    if r < 0.25 and depth < 4:
        return {rng.choice(("x", "positive", "width", "")): _json_junk(rng, depth + 1)}
    return rng.choice(
        (None, True, False, 0, -1, 1.5, 10**40, -(10**30), 1e308, float("nan"), float("inf"), "", "12", "é", [1, 2])
    )


def _click(rng: random.Random) -> Any:
    if rng.random() < 0.8:
        return [rng.uniform(-5, 300), rng.uniform(-5, 300)]
    return rng.choice(([1], [1, 2, 3], "1,2", [True, 2], [None, 1], {"x": 1}, [float("nan"), 1], [1e309, 2], []))


def generate_clicks_case(rng: random.Random) -> tuple[bytes, tuple[int, int]]:
    """``(file bytes, photo size)``: a clicks file, valid-looking or damaged."""
    data: dict[str, Any] = {"format": "jeanscv-clicks", "version": 1}
    if rng.random() < 0.1:
        data["format"] = _json_junk(rng)
    if rng.random() < 0.1:
        data["version"] = _json_junk(rng)
    if rng.random() < 0.7:
        data["image"] = {"width": rng.choice((256, 100, 0, -3, 2.5, True)), "height": rng.choice((256, 80, "1"))}
        if rng.random() < 0.1:
            data["image"] = _json_junk(rng)
    objects = []
    for _ in range(rng.choice((0, 1, 1, 2, 3, 70))):
        obj: dict[str, Any] = {
            "positive": [_click(rng) for _ in range(rng.choice((0, 1, 1, 2, 300)))],
            "negative": [_click(rng) for _ in range(rng.choice((0, 0, 1, 2)))],
        }
        if rng.random() < 0.1:
            obj[rng.choice(("positive", "negative"))] = _json_junk(rng)
        objects.append(obj if rng.random() > 0.05 else _json_junk(rng))
    data["objects"] = objects if rng.random() > 0.05 else _json_junk(rng)
    if rng.random() < 0.1:
        data["extra"] = _json_junk(rng)
    text = json.dumps(data).encode()
    r = rng.random()
    if r < 0.25:
        text = mutate_bytes(text, rng)
    elif r < 0.3:
        text = b"[" * rng.choice((10, 1000, 100_000)) + b"]" * rng.randrange(3)
    elif r < 0.35:
        text = rng.choice((b"\xef\xbb\xbf", b"\xff\xfe", b"")) + text.decode().encode(rng.choice(("utf-16", "utf-8")))
    size = rng.choice(((256, 256), (100, 80), (1, 1), (4032, 3024)))
    return text, size


def run_clicks(case: tuple[bytes, tuple[int, int]]) -> object:
    from jeanscv.subject.clicks import loads_clicks

    text, size = case
    clicks = loads_clicks(text)
    again = loads_clicks(clicks.dumps())  # what the web page writes, it reads back
    if again != clicks:
        raise ContractViolation("a clicks file does not read back equal after dumps()")
    clicks.check(size)
    if clicks.image_size is not None:
        clicks.scaled((max(1, size[0] // 2), max(1, size[1] // 2)))
    return clicks


def run_read_clicks(case: tuple[bytes, tuple[int, int]]) -> object:
    from jeanscv.subject.clicks import read_clicks

    return read_clicks(_SCRATCH.write("case.clicks.json", case[0]))


# -------------------------------------------------------------- garment TOML


def generate_garment_case(rng: random.Random) -> bytes:
    """A garment ``.toml`` file: the built-in jeans' text, its values varied or damaged."""
    vertices = [[rng.uniform(-2, 2), rng.uniform(-2, 2)] for _ in range(rng.choice((8, 8, 3, 0, 70)))]
    lines = [
        f'name = "{rng.choice(("fuzz", "", "a b", "é", "x" * 300, "-x"))}"',
        f'description = "{rng.choice(("d", ""))}"',
        f"vertices = {json.dumps(vertices)}",
        f"open_edges = {json.dumps(rng.choice(([0, 4], [], [99], [-1], [0, 0], [1.5])))}",
        f"waist = {json.dumps(rng.choice(([0, 1], [1, 0], [0, 99], [0], [0, 1, 2], ['a', 'b'])))}",
    ]
    if rng.random() < 0.3:
        lines += ["[draw]", rng.choice(('style = "flat"', 'style = "x"', "colour = [0, 0, 255]", "colour = [300, -1]"))]
    text = "\n".join(lines).encode()
    if rng.random() < 0.3:
        text = mutate_bytes(text, rng)
    return text


def run_garment(case: bytes) -> object:
    from jeanscv.fitting.garments import Garment

    return Garment.from_toml(_SCRATCH.write("case.toml", case))


# ------------------------------------------------------------------- captions

_CAPTION_PIECES = ("how would", "a cat wear jeans", "\x00", "\n", "\t", "é", "\u202e", "\u0301" * 20, "🙂", "字", "")
_CAPTION_PIECES += ("\ud800", "W" * 400, " ", "\r\n", "\u200b")


def generate_caption_case(rng: random.Random) -> tuple[str, str, int, int]:
    def text() -> str:
        return "".join(rng.choice(_CAPTION_PIECES) for _ in range(rng.randint(0, 6)))

    return text(), text(), rng.choice((8, 16, 64, 200)), rng.choice((8, 32, 64, 300))


def run_captions(case: tuple[str, str, int, int]) -> object:
    from jeanscv_cli.extras import add_captions

    top, bottom, height, width = case
    image = np.zeros((height, width, 3), np.uint8)
    out = add_captions(image, top, bottom)
    if out.shape != image.shape:
        raise ContractViolation(f"captions changed the shape {image.shape} -> {out.shape}")
    return out


# -------------------------------------------------------------- command line

_OPTION_VALUES = {
    "--rect": lambda rng: rng.choice(("1,2,3,4", "0,0,10,10", "1,2,3", "a,b,c,d", "1,2,-3,4", "1e3,2,3,4", "", ",,,")),
    "--point": lambda rng: rng.choice(("5,5", "1e9,5", "nan,3", "inf,1", "5", "5,5,5", "-1,-1", "", "5;5", "0x10,1")),
    "--background-point": lambda rng: rng.choice(("1,1", "x,y", "1e400,2")),
    "--threshold": lambda rng: rng.choice(("128", "-1", "256", "nan", "1e999", "abc")),
    "--max-pixels": lambda rng: rng.choice(("0", "1", "64", "1000000", "-5", "1e6", "9" * 30)),
    "--gif-frames": lambda rng: rng.choice(("2", "1", "500", "501", "x")),
    "--seed": lambda rng: rng.choice(("0", "-1", "99999999999999999999", "1.5")),
    "--starts": lambda rng: rng.choice(("1", "0", "-1", "x")),
    "--preset": lambda rng: rng.choice(("default", "paper", "", "nope", "../x", "\x00")),
    "--posture": lambda rng: rng.choice(("upright", "any", "lying")),
    "--garment": lambda rng: rng.choice(("jeans", "skirt", "nope", "", "g.toml", "missing.toml", "/", "a" * 300)),
    "--kind": lambda rng: rng.choice(("auto", "photo", "silhouette", "x")),
    "--silhouette": lambda rng: rng.choice(("auto", "alpha", "threshold", "grabcut", "nope")),
    "--objects": lambda rng: rng.choice(("one", "all", "some")),
    "--style": lambda rng: rng.choice(("denim", "flat", "tweed")),
    "--format": lambda rng: rng.choice(("png", "jpg", "webp", "gif", "")),
    "--top": lambda rng: "".join(rng.choice(_CAPTION_PIECES[:-2]) for _ in range(rng.randint(0, 4))),
    "--bottom": lambda rng: "".join(rng.choice(_CAPTION_PIECES[:-2]) for _ in range(rng.randint(0, 4))),
    "--mask": lambda rng: rng.choice(("mask.png", "missing.png", "bad.png", "in.png", ".")),
    "--clicks": lambda rng: rng.choice(("clicks.json", "bad.json", "missing.json", ".")),
    "--report": lambda rng: rng.choice(("report.jsonl", "sub/report.jsonl", ".", "in.png/x")),
    "-o": lambda rng: rng.choice(("out", "out/deeper", "in.png", "é ü")),
    "-j": lambda rng: rng.choice(("1", "2", "0", "-1", "x")),
    "--device": lambda rng: rng.choice(("auto", "cpu", "cuda", "tpu")),
    "--backend": lambda rng: rng.choice(("auto", "fast", "torch", "numba")),
    "--iterations": lambda rng: rng.choice(("0", "1", "-1", "x")),
}
_FLAGS = ("--overwrite", "--json", "--svg", "--gif", "-q", "-v", "-r", "--side-by-side", "--no-clip", "--raw-half-size")
_FLAGS += ("--raw-full-size", "--bogus", "-")


def generate_cli_case(rng: random.Random) -> list[str]:
    """An argument list: an input (good, bad or missing) and a random mix of options."""
    args = [rng.choice(("in.png", "in.png", "in.svg", "bad.png", "missing.png", "*.png", "in.png in.svg", ""))]
    for _ in range(rng.randint(0, 6)):
        if rng.random() < 0.3:
            args.append(rng.choice(_FLAGS))
        else:
            option = rng.choice(sorted(_OPTION_VALUES))
            value = _OPTION_VALUES[option](rng)
            args += [f"{option}={value}"] if rng.random() < 0.3 and option.startswith("--") else [option, value]
    return args


@functools.lru_cache(maxsize=1)
def _cli_folder() -> Path:
    """The files a command-line case may name: a silhouette PNG and SVG, a mask, clicks files."""
    from PIL import Image

    folder = _SCRATCH.path("cli")
    folder.mkdir()
    yy, xx = np.mgrid[:48, :48]
    person = ((xx - 24) ** 2 / 100 + (yy - 24) ** 2 / 300 < 1).astype(np.uint8) * 255
    Image.fromarray(person).save(folder / "in.png")
    Image.fromarray(person).save(folder / "mask.png")
    (folder / "in.svg").write_text(
        '<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 256 256"><path d="M100 20 L160 20 L150 230 L106 230Z"/></svg>'
    )
    (folder / "bad.png").write_bytes(b"\x89PNG\r\n\x1a\nnot really")
    (folder / "clicks.json").write_text(
        json.dumps({"format": "jeanscv-clicks", "version": 1, "objects": [{"positive": [[24, 24]]}]})
    )
    (folder / "bad.json").write_text("{")
    (folder / "g.toml").write_bytes(b'name = "g"\nvertices = [[0, 0]]\n')
    return folder


def run_cli(args: list[str]) -> object:
    """``jeanscv ARGS`` in-process, in the case folder: exit 0/1/2, no traceback, and every
    ``jeanscv:`` line one line. The fit is kept tiny (and on torch, which needs no
    kernel compilation) by options appended last, which win."""
    import os

    from click.testing import CliRunner

    from jeanscv_cli.main import cli

    folder = _cli_folder()
    argv = [a for arg in args for a in (arg.split(" ") if arg == "in.png in.svg" else [arg])]
    argv += ["--iterations", "1", "--starts", "1", "--backend", "torch", "--device", "cpu", "-j", "1"]
    cwd = os.getcwd()
    os.chdir(folder)
    try:
        result = CliRunner().invoke(cli, argv, prog_name="jeanscv")
    finally:
        os.chdir(cwd)
        for path in folder.iterdir():  # outputs of this case must not turn the next one into a skip
            if ".jeans." in path.name or path.name in ("out", "sub", "é ü", "report.jsonl"):
                _remove(path)
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        exc = result.exception
        raise ContractViolation(f"{type(exc).__name__}: {' '.join(str(exc).split())[:200]} for {argv!r}")
    if result.exit_code not in (0, 1, 2):
        raise ContractViolation(f"exit status {result.exit_code} for {argv!r}")
    if "Traceback" in result.stderr:
        raise ContractViolation(f"a traceback for {argv!r}")
    return result


def _remove(path: Path) -> None:
    import shutil

    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        path.unlink(missing_ok=True)


# ----------------------------------------------------------------- the targets

TARGETS: dict[str, Target] = {
    target.name: target
    for target in (
        Target("svg", generate_svg_case, run_svg),
        Target("path_data", generate_path_case, run_flatten),
        Target("image", generate_image_case, run_load_image),
        Target("mask", generate_image_case, run_load_mask),
        Target("clip", generate_clip_case, run_clip),
        Target("clicks", generate_clicks_case, run_clicks),
        Target("clicks_file", generate_clicks_case, run_read_clicks),
        Target("garment", generate_garment_case, run_garment),
        Target("captions", generate_caption_case, run_captions),
        Target("cli", generate_cli_case, run_cli),
    )
}
"""Every fuzz target, by name."""

__all__ = ["TARGETS", "ContractViolation", "Target", "image_seeds", "mutate_bytes", "violation"]
