"""The CLI's extra outputs: vector SVG overlay, optimisation GIF, meme captions, side by side.

Images are ``(H, W, 3)`` RGB or ``(H, W, 4)`` RGBA ``uint8``; points are ``(N, 2)``
float64 ``(x, y)`` in image pixels (package convention: pixel ``(c, r)`` covers
``[c, c+1) x [r, r+1)``).
"""

from __future__ import annotations

import functools
import io
import os
import textwrap
import unicodedata
from dataclasses import dataclass, replace
from pathlib import Path
from xml.sax.saxutils import escape, quoteattr

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from jeanscv.io.write import on_white

GIF_MAX_SIDE = 320
JEANS_BLUE = (0, 0, 255)
_FRAME_MS = 80
_LAST_FRAME_MS = 1500
_MAX_CAPTION_LINES = 3


# ------------------------------------------------------------------ silhouette geometry


# ------------------------------------------------------------------------------- SVG


def _num(value: float) -> str:
    return format(float(value), ".6g")


def svg_document(
    vertices: np.ndarray | list[np.ndarray], contours: list[np.ndarray], size: tuple[int, int], title: str = ""
) -> str:
    """An SVG of the fit in image pixels: black silhouette, blue jeans polygons.

    Args:
        vertices: ``(N, 2)`` jeans polygon, image pixels, or one per object (ids
            ``jeans``, ``jeans-2``, ...).
        contours: silhouette boundaries ``[(K, 2)]``, image pixels, filled even-odd.
        size: ``(width, height)`` of the image; also the viewBox.
    """
    width, height = size
    lines = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" viewBox="0 0 {width} {height}">',
    ]
    if title:
        lines.append(f"  <title>{escape(title)}</title>")
    lines.append(f'  <rect id="background" x="0" y="0" width="{width}" height="{height}" fill="#ffffff"/>')
    if contours:
        d = " ".join("M" + " L".join(f"{_num(x)},{_num(y)}" for x, y in c) + " Z" for c in contours)
        lines.append(f'  <path id="silhouette" d={quoteattr(d)} fill="#000000" fill-rule="evenodd"/>')
    polygons = [vertices] if isinstance(vertices, np.ndarray) and vertices.ndim == 2 else list(vertices)
    for index, polygon in enumerate(polygons):
        points = " ".join(f"{_num(x)},{_num(y)}" for x, y in np.asarray(polygon, dtype=np.float64))
        name = "jeans" if index == 0 else f"jeans-{index + 1}"
        lines.append(f'  <polygon id="{name}" points="{points}" fill="#0000ff"/>')
    lines.append("</svg>")
    return "\n".join(lines) + "\n"


# ------------------------------------------------------------------------------- GIF


def frame_indices(iterations: int, frames: int) -> np.ndarray:
    """Which trajectory steps (0..iterations) become frames: evenly spaced, first and last included."""
    count = max(1, min(frames, iterations + 1))
    return np.unique(np.round(np.linspace(0, iterations, count)).astype(int))


def _scaled(image_size: tuple[int, int], max_side: int) -> tuple[float, tuple[int, int]]:
    width, height = image_size
    scale = min(1.0, max_side / max(width, height))
    return scale, (max(1, round(width * scale)), max(1, round(height * scale)))


def _resize_float(plane: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """Area-average a ``(H, W)`` float plane to ``size`` = (width, height)."""
    if plane.shape[::-1] == tuple(size):
        return plane.astype(np.float32)
    return np.asarray(Image.fromarray(plane.astype(np.float32), "F").resize(size, Image.Resampling.BOX))


def optimisation_gif(result, max_frames: int = 50, max_side: int = GIF_MAX_SIDE) -> bytes:
    """An animated GIF of the fit: the jeans at evenly spaced iterations, in the paper's style.

    Silhouettes are drawn black on white; photos are shown downscaled. A thin bar along
    the bottom shows the progress through the iterations; the last frame is held.
    Needs ``result.fit.trajectory``: ``(iterations + 1, N, 2)`` canvas pixels.
    """
    from jeanscv.paint.figures import draw_figure, draw_garment

    fit, silhouette = result.fit, result.silhouette
    trajectory = np.asarray(fit.trajectory, dtype=np.float64)
    steps = frame_indices(trajectory.shape[0] - 1, max_frames)
    if result.kind == "silhouette":
        mask = np.asarray(silhouette.mask, dtype=np.float32)
        scale, size = _scaled(mask.shape[::-1], max_side)
        small = _resize_float(mask, size)

        def draw(canvas_vertices: np.ndarray) -> np.ndarray:
            verts = silhouette.to_mask(canvas_vertices) * scale
            return draw_figure(small, verts, fit.garment)
    else:
        photo = on_white(result.source.pixels if result.source is not None else result.image)
        scale, size = _scaled(photo.shape[1::-1], max_side)
        small = np.asarray(Image.fromarray(photo).resize(size, Image.Resampling.LANCZOS))

        def draw(canvas_vertices: np.ndarray) -> np.ndarray:
            verts = silhouette.framing.to_image(canvas_vertices) * scale
            return draw_garment(small, verts, fit.garment)

    width, height = size
    bar = max(2, height // 80)
    last = max(int(steps[-1]), 1)
    frames = []
    for step in steps:
        frame = draw(trajectory[step])
        done = int(round(width * step / last))
        frame[height - bar :, :done] = JEANS_BLUE
        frames.append(Image.fromarray(frame))
    durations = [_FRAME_MS] * (len(frames) - 1) + [_LAST_FRAME_MS]
    # One palette for every frame, from the last (the photo and the jeans in place):
    # mapping onto it is ~50x quicker than Pillow's own palette per frame, and smaller.
    palette = frames[-1].quantize(255, method=Image.Quantize.FASTOCTREE, dither=Image.Dither.NONE)
    frames = [frame.quantize(palette=palette, dither=Image.Dither.FLOYDSTEINBERG) for frame in frames]
    buffer = io.BytesIO()
    frames[0].save(buffer, "GIF", save_all=True, append_images=frames[1:], duration=durations, loop=0, disposal=1)
    return buffer.getvalue()


# ---------------------------------------------------------------------------- memes

_FONT_CANDIDATES = (
    "Impact.ttf",
    "impact.ttf",
    "Anton-Regular.ttf",
    "DejaVuSans-Bold.ttf",
    "LiberationSans-Bold.ttf",
)
_FONT_DIRS = (
    Path(__file__).parent / "fonts",
    Path("/usr/share/fonts/truetype/dejavu"),
    Path("/usr/share/fonts/TTF"),
    Path("/usr/share/fonts/dejavu"),
    Path("/usr/share/fonts/truetype/liberation"),
    Path("/Library/Fonts"),
    Path("/System/Library/Fonts/Supplemental"),
    Path(os.environ.get("WINDIR", "C:/Windows")) / "Fonts",
)


def find_font() -> Path | None:
    """A bold sans font file for captions, or None for Pillow's bundled default.

    ``$JEANSCV_FONT`` wins; then a font in ``cli/fonts``; then Impact, Anton, DejaVu
    Sans Bold or Liberation Sans Bold from the usual system folders; then matplotlib's
    copy of DejaVu Sans Bold, if matplotlib is installed (found without importing it).
    """
    override = os.environ.get("JEANSCV_FONT")
    if override and Path(override).is_file():
        return Path(override)
    bundled = sorted((Path(__file__).parent / "fonts").glob("*.[to]tf"))
    if bundled:
        return bundled[0]
    for folder in _FONT_DIRS:
        for name in _FONT_CANDIDATES:
            if (folder / name).is_file():
                return folder / name
    import importlib.util

    spec = importlib.util.find_spec("matplotlib")
    if spec is not None and spec.submodule_search_locations:
        for location in spec.submodule_search_locations:
            candidate = Path(location) / "mpl-data" / "fonts" / "ttf" / "DejaVuSans-Bold.ttf"
            if candidate.is_file():
                return candidate
    return None


def wide_font() -> Path | None:
    """The font for captions the bold sans font cannot write: Noto Sans CJK Bold (Latin,
    Greek, Cyrillic, Chinese, Japanese, Korean) from the ``cvttf-notosanscjk-bold``
    package, found without importing it; None when it is not installed."""
    import importlib.util

    spec = importlib.util.find_spec("cvttf_NotoSansCJK_Bold")
    for location in (spec.submodule_search_locations or []) if spec is not None else []:
        found = sorted(Path(location).glob("*.[to]tf"))
        if found:
            return found[0]
    return None


#: A code point no font maps: what a font draws for a character it lacks (its box).
_UNMAPPED = "\U0010ffff"


@functools.lru_cache(maxsize=8192)
def _covers(path: Path | None, char: str) -> bool:
    """Whether the font draws ``char`` as its own glyph, not as its missing-glyph box."""
    if char.isspace():
        return True
    font = _font(24, path)

    def drawn(text: str) -> bytes:
        canvas = Image.new("L", (64, 64))
        ImageDraw.Draw(canvas).text((8, 8), text, font=font, fill=255)
        return canvas.tobytes()

    return drawn(char) != drawn(_UNMAPPED)


def caption_text(text: str) -> tuple[str, Path | None]:
    """A caption as it is drawn (upper case), and the font that draws it.

    The bold sans font (:func:`find_font`) when it has every character, else the font
    that has the most (the wide one, :func:`wide_font`, for CJK). A character that font
    lacks loses only the accent it lacks (Greek tonos), or, when nothing of it can be
    drawn (an emoji), is written as its name in brackets, ``[DOG FACE]``: never a box.
    Joiners, variation selectors and skin tones that go with an emoji are dropped.
    """
    text = text.upper()
    fonts = list(dict.fromkeys(f for f in (find_font(), wide_font()) if f is not None)) or [None]

    def drawable(font: Path | None, char: str) -> str:  # what of the character the font draws
        parts = [part for part in unicodedata.normalize("NFD", char) if _covers(font, part)]
        return "".join(parts) if parts and unicodedata.category(parts[0])[0] != "M" else ""

    font = max(fonts, key=lambda f: sum(bool(drawable(f, c)) for c in set(text)))  # the first of equals
    drawn = []
    for char in text:
        part = drawable(font, char)
        if part:
            drawn.append(part)
        elif unicodedata.category(char) not in ("Mn", "Me", "Cf", "Sk"):
            drawn.append(f"[{unicodedata.name(char, 'symbol')}]")
    return unicodedata.normalize("NFC", "".join(drawn)), font


@functools.lru_cache(maxsize=128)
def _font(size: int, path: Path | None):
    if path is not None:
        try:
            return ImageFont.truetype(str(path), size)
        except OSError:
            pass  # unreadable font file: fall back to the bundled one
    return ImageFont.load_default(size=size)


def _wrap(text: str, font, stroke: int, max_width: float) -> list[str] | None:
    """Greedy word wrap to ``max_width`` pixels; None when one word alone is too wide."""
    lines: list[str] = []
    for word in text.split():
        trial = f"{lines[-1]} {word}" if lines else word
        if lines and font.getlength(trial) + 2 * stroke <= max_width:
            lines[-1] = trial
        elif font.getlength(word) + 2 * stroke <= max_width:
            lines.append(word)
        else:
            return None
    return lines


def _wrap_breaking(text: str, font, stroke: int, max_width: float) -> list[str] | None:
    """Greedy word wrap to ``max_width`` pixels where a word too wide for a line of its
    own is broken between its letters (a CJK caption has no spaces to break at; a letter
    keeps its accents); None when one letter alone is too wide."""

    def fits(line: str) -> bool:
        return font.getlength(line) + 2 * stroke <= max_width

    lines: list[str] = []
    for word in text.split():
        if lines and fits(f"{lines[-1]} {word}"):
            lines[-1] = f"{lines[-1]} {word}"
            continue
        letters: list[str] = []
        for char in word:
            if letters and unicodedata.category(char).startswith("M"):
                letters[-1] += char  # a combining accent stays with its letter
            else:
                letters.append(char)
        line = ""
        for letter in letters:
            if line and not fits(line + letter):
                lines.append(line)
                line = ""
            line += letter
            if not fits(line):
                return None
        lines.append(line)
    return lines


#: Past three lines a caption takes at most this share of the picture's height (the top
#: and the bottom caption together two thirds: the subject stays in sight between them)...
_CAPTION_HEIGHT_SHARE = 1 / 3
#: ...at a font size down to this share of the height (never under 8 pixels): a caption
#: that does not fit so is cut, and the page says it is too long.
_CAPTION_FLOOR_SHARE = 1 / 40


@dataclass(frozen=True)
class CaptionFit:
    """How one caption is drawn across a picture: its font (file and size), outline
    width and lines; ``cut`` when even the smallest size could not hold it all (its last
    line then ends in an ellipsis)."""

    size: int
    stroke: int
    lines: tuple[str, ...]
    font_path: Path | None = None
    cut: bool = False

    @property
    def font(self):
        return _font(self.size, self.font_path)

    @property
    def line_height(self) -> int:
        ascent, descent = self.font.getmetrics()
        return ascent + descent + self.stroke

    def summary(self) -> dict:
        """What the page is told of it: ``lines`` (how many), ``size`` and ``cut``."""
        return {"lines": len(self.lines), "size": self.size, "cut": self.cut}


def _stroke(size: int) -> int:
    return max(1, round(size / 14))


def fit_caption(text: str, width: int, height: int, font_path: Path | None = None) -> CaptionFit:
    """How a classic meme caption is drawn across a ``width`` x ``height`` picture.

    Fewer lines win over a bigger font: the largest size (at most 1/8 of the height)
    at which the upper-case text fits 94% of the width on one line, else on two, else
    on three, each with a smaller size floor; else 1/24 of the height, on three lines
    (words too long for a line broken); past three lines (or lines wider than the
    picture), the largest size from there down to 1/40 of the height at which the lines,
    words broken only where one is wider than a line, take at most a third of the
    height. Only a caption that does not fit even so is cut to three lines at 1/24 with
    an ellipsis (``cut``).
    """
    text = " ".join(text.upper().split())
    max_width = 0.94 * width
    largest = max(8, int(min(height / 8, width / 4)))
    for lines_allowed, floor in ((1, height / 12), (2, height / 16), (3, height / 24)):
        size = largest
        while size >= max(8, int(floor)):
            font = _font(size, font_path)
            lines = _wrap(text, font, _stroke(size), max_width)
            if lines is not None and len(lines) <= lines_allowed:
                return CaptionFit(size, _stroke(size), tuple(lines), font_path)
            size = int(size * 0.92) if size > 8 else 0
    size = max(8, int(height / 24))
    font = _font(size, font_path)
    chars = max(1, int(max_width / max(font.getlength("W"), 1)))
    lines = textwrap.wrap(text, chars, break_long_words=True) or [""]
    # Lines of letters as wide as a "W" (most captions that get here) are drawn as they
    # were before captions gained more lines, to the byte; those that would be cut, or
    # run off the picture's sides (CJK letters are wider), are fitted below instead.
    inside = all(font.getlength(line) + 2 * _stroke(size) <= max_width for line in lines)
    if len(lines) <= _MAX_CAPTION_LINES and inside:
        return CaptionFit(size, _stroke(size), tuple(lines), font_path)
    fitted = _fit_more_lines(text, max_width, height, size, font_path)
    if fitted is not None:
        return fitted
    lines = lines[:_MAX_CAPTION_LINES]
    lines[-1] = lines[-1][: max(0, chars - 1)] + "\u2026"
    return CaptionFit(size, _stroke(size), tuple(lines), font_path, cut=True)


def _fit_more_lines(text: str, max_width: float, height: int, start: int, font_path: Path | None) -> CaptionFit | None:
    """The largest size from ``start`` down to the floor at which ``text``, wrapped to
    as many lines as it needs, takes at most a third of the height; None if none does."""
    floor = max(8, int(height * _CAPTION_FLOOR_SHARE))
    size = max(start, floor)
    while True:
        fit = CaptionFit(size, _stroke(size), (), font_path)
        lines = _wrap_breaking(text, fit.font, fit.stroke, max_width)
        if lines and len(lines) * fit.line_height <= _CAPTION_HEIGHT_SHARE * height:
            return replace(fit, lines=tuple(lines))
        if size == floor:
            return None
        size = max(floor, int(size * 0.92))  # the floor itself is tried last


def caption_fits(width: int, height: int, top: str | None, bottom: str | None) -> dict[str, CaptionFit]:
    """How ``top`` and ``bottom`` are drawn across a ``width`` x ``height`` picture
    (keys ``"top"``, ``"bottom"``; a blank caption has none): what :func:`add_captions`
    draws, and what the page is told of them."""
    fits = {}
    for key, text in (("top", top), ("bottom", bottom)):
        if text and text.strip():
            drawn, font_path = caption_text(text)
            fits[key] = fit_caption(drawn, width, height, font_path)
    return fits


def add_captions(image: np.ndarray, top: str | None, bottom: str | None) -> np.ndarray:
    """Classic meme captions: bold white upper-case text with a black outline,
    ``top`` along the top edge and ``bottom`` along the bottom edge. Returns a copy."""
    if not (top or bottom):
        return image
    height, width = image.shape[:2]
    return draw_captions(image, caption_fits(width, height, top, bottom))


def draw_captions(image: np.ndarray, fits: dict[str, CaptionFit]) -> np.ndarray:
    """``image`` with the captions of :func:`caption_fits` drawn on it. Returns a copy."""
    canvas = Image.fromarray(np.ascontiguousarray(image))
    draw = ImageDraw.Draw(canvas)
    width, height = canvas.size
    margin = max(2, height // 40)
    fill = (255, 255, 255, 255) if canvas.mode == "RGBA" else (255, 255, 255)
    outline = (0, 0, 0, 255) if canvas.mode == "RGBA" else (0, 0, 0)
    for key, fit in fits.items():
        font, line_height = fit.font, fit.line_height
        y = margin if key == "top" else height - margin - line_height * len(fit.lines)
        for line in fit.lines:
            x = (width - font.getlength(line)) / 2
            draw.text((x, y), line, font=font, fill=fill, stroke_width=fit.stroke, stroke_fill=outline)
            y += line_height
    return np.asarray(canvas).copy()


def side_by_side(left: np.ndarray, right: np.ndarray) -> np.ndarray:
    """``left | right`` (same height); RGB and RGBA mixed become RGBA."""
    if left.shape[0] != right.shape[0]:
        raise ValueError("side by side needs images of the same height")
    channels = max(left.shape[2], right.shape[2])

    def widen(image: np.ndarray) -> np.ndarray:
        if image.shape[2] == channels:
            return image
        return np.concatenate([image, np.full(image.shape[:2] + (1,), 255, np.uint8)], axis=2)

    return np.concatenate([widen(left), widen(right)], axis=1)
