"""Read an SVG silhouette: parse its filled shapes and rasterise them onto the canvas.

The paper's inputs are SVG files holding one filled path in a 256x256 viewBox. This
module turns such a file into the silhouette ``S``: a ``(canvas, canvas)`` float32
coverage image in ``[0, 1]``. Everything is stdlib + numpy:

* XML is parsed with ``xml.parsers.expat``; any entity declaration or DOCTYPE
  internal subset is refused before and during parsing (no billion laughs, nothing is
  ever fetched).
* Path data (all SVG 1.1 commands, including elliptical arcs) becomes cubic Bezier
  segments, which are mapped to canvas pixels and flattened adaptively (chord error
  at most :data:`FLATTEN_TOLERANCE` canvas px): :mod:`jeanscv.io.svg_path`.
* Polygons are filled with the exact nonzero / evenodd rule at ``supersample**2``
  sample points per pixel by a vectorised scanline (crossings of every edge with
  every sample row, accumulated with ``bincount`` + ``cumsum``), then box-averaged:
  :mod:`jeanscv.io.svg_raster`.

Framing: the viewBox (or ``width``/``height`` when there is no viewBox) is scaled
uniformly to fit the canvas, aspect kept, centred; a 256x256 viewBox at the origin
maps 1:1. The silhouette is the union of every visible filled ``path``, ``rect``,
``circle``, ``ellipse``, ``polygon`` and ``polyline`` (also through ``g``, ``a``,
``switch``, nested ``svg`` and ``use``), each with its own fill rule; shapes filled
``none`` or white (a backdrop) do not count, any other colour does. Not supported
(ignored): CSS ``<style>`` sheets and classes, ``clip-path``, masks,
``preserveAspectRatio``, strokes, text and images.
"""

from __future__ import annotations

import math
import re
import zlib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from xml.parsers import expat

import numpy as np

from jeanscv.errors import JeansError
from jeanscv.geometry import invert_affine
from jeanscv.io.files import open_regular

from .svg_path import (
    _NUMBER,
    _NUMBER_RE,
    _SEPARATORS_ONLY_RE,
    FLATTEN_TOLERANCE,
    MAX_SEGMENTS,
    _parse_path_data,
    _PathBuilder,
    flatten_path_data,
)
from .svg_raster import _rasterize_shapes, _Shape

#: File extensions read as SVG silhouettes.
SVG_EXTENSIONS = frozenset({".svg", ".svgz"})

MAX_FILE_BYTES = 64 * 1024 * 1024
"""Largest SVG accepted, after gunzipping an ``.svgz``."""

_MAX_DEPTH = 200  # element nesting; the tree walk recurses twice per level
_MAX_USE_DEPTH = 16  # <use> indirections

_SVG_NS = "http://www.w3.org/2000/svg"
_XLINK_NS = "http://www.w3.org/1999/xlink"

_LENGTH_RE = re.compile(r"\s*(" + _NUMBER + r")\s*(px|pt|pc|mm|cm|in|%|)\s*")
_UNIT_PX = {"": 1.0, "px": 1.0, "pt": 96 / 72, "pc": 16.0, "mm": 96 / 25.4, "cm": 96 / 2.54, "in": 96.0}
_TRANSFORM_RE = re.compile(r"[\s,]*(matrix|translate|scale|rotate|skewX|skewY)\s*\(([^)]*)\)[\s,]*")


@dataclass(eq=False)
class SvgSilhouette:
    """A silhouette read from an SVG.

    ``alpha``: ``(canvas_size, canvas_size)`` float32 in ``[0, 1]``, the fraction of
    each canvas pixel covered by the filled shapes (the paper's ``S``).
    ``canvas_to_image``: ``(2, 3)`` float64 affine from canvas pixels to SVG user
    units (the viewBox coordinate system); identity for a 256x256 viewBox at 0.
    ``width``, ``height``: the viewBox size in user units.
    """

    alpha: np.ndarray
    canvas_to_image: np.ndarray
    width: float
    height: float


def read_svg_silhouette(path: str | Path, canvas_size: int = 256, supersample: int = 4) -> SvgSilhouette:
    """Read the SVG (or gzipped ``.svgz``) at ``path`` and rasterise its filled shapes."""
    try:
        with open_regular(path) as handle:
            data = handle.read(MAX_FILE_BYTES + 1)
    except OSError as exc:
        raise JeansError(f"not an SVG file: cannot read it ({exc.strerror or exc})") from None
    return read_svg_silhouette_from_bytes(data, canvas_size, supersample)


def read_svg_silhouette_from_bytes(data: bytes, canvas_size: int = 256, supersample: int = 4) -> SvgSilhouette:
    """Like :func:`read_svg_silhouette`, for the file's bytes."""
    if not isinstance(canvas_size, int) or not 1 <= canvas_size <= 8192:
        raise JeansError(f"canvas size must be an integer in 1..8192, not {canvas_size!r}")
    if not isinstance(supersample, int) or not 1 <= supersample <= 16:
        raise JeansError(f"supersample must be an integer in 1..16, not {supersample!r}")
    root = _parse_xml(_maybe_gunzip(bytes(data)))
    min_x, min_y, width, height = _root_viewbox(root)
    scale = canvas_size / max(width, height)
    user_to_canvas = np.array(
        [
            [scale, 0.0, (canvas_size - scale * width) / 2 - scale * min_x],
            [0.0, scale, (canvas_size - scale * height) / 2 - scale * min_y],
            [0.0, 0.0, 1.0],
        ]
    )

    shapes: list[_Shape] = []
    # Finite transforms can compose to inf or nan (matrix(1e300 ...) twice); the
    # coordinate check in _rasterize_shapes refuses those, so numpy's warning would be a
    # second line for one bad file.
    with np.errstate(all="ignore"):
        _Walker(root, shapes, (width, height)).walk(root, user_to_canvas, _DEFAULT_STYLE, 0)
        if not shapes:
            raise JeansError("SVG has no filled path")
        alpha = _rasterize_shapes(shapes, canvas_size, supersample)
    if not np.any(alpha):
        raise JeansError(
            "silhouette is empty: the path encloses no area inside the viewBox (or is thinner than a sample)"
        )
    return SvgSilhouette(
        alpha=alpha, canvas_to_image=invert_affine(user_to_canvas[:2]), width=float(width), height=float(height)
    )


# --------------------------------------------------------------------------- XML


class _Node:
    __slots__ = ("tag", "attrs", "children")

    def __init__(self, tag: str | None, attrs: dict[str, str]):
        self.tag = tag  # local name for SVG elements, None for foreign ones
        self.attrs = attrs
        self.children: list[_Node] = []


def _maybe_gunzip(data: bytes) -> bytes:
    if len(data) > MAX_FILE_BYTES:
        raise JeansError("SVG file is too large (over 64 MiB)")
    if data[:2] != b"\x1f\x8b":
        return data
    inflater = zlib.decompressobj(16 + zlib.MAX_WBITS)
    try:
        out = inflater.decompress(data, MAX_FILE_BYTES + 1)
    except zlib.error:
        raise JeansError("not an SVG file: corrupt gzip data") from None
    if len(out) > MAX_FILE_BYTES:
        raise JeansError("SVG file is too large (over 64 MiB unzipped)")
    return out


def _refuse_entities(data: bytes) -> None:
    """Refuse entity declarations before expat sees them (it would expand them)."""
    if data[:2] in (b"\xff\xfe", b"\xfe\xff", b"<\x00", b"\x00<"):
        little = data[:2] in (b"\xff\xfe", b"<\x00")
        text = data.decode("utf-16-le" if little else "utf-16-be", errors="replace")
    else:
        text = data.decode("latin-1")  # ASCII-compatible encodings: bytes are enough
    if "<!ENTITY" in text:
        raise JeansError("SVG declares XML entities, which are refused for safety")
    if re.search(r"<!DOCTYPE[^>\[]*\[", text):
        raise JeansError("SVG has a DOCTYPE internal subset, which is refused for safety")


def _parse_xml(data: bytes) -> _Node:
    """Parse ``data`` into a tree of :class:`_Node`; the root must be ``<svg>``."""
    if not data.strip():
        raise JeansError("not an SVG file: it is empty")
    _refuse_entities(data)
    parser = expat.ParserCreate(namespace_separator="}")
    stack: list[_Node] = []
    roots: list[_Node] = []

    def start(name: str, attrs: dict[str, str]) -> None:
        ns, _, local = name.rpartition("}")
        keep = {}
        for key, value in attrs.items():
            key_ns, _, key_local = key.rpartition("}")
            if key_ns in ("", _XLINK_NS):  # foreign attributes must not shadow ours
                keep[key_local] = value
        node = _Node(local if ns in ("", _SVG_NS) else None, keep)
        if stack:
            stack[-1].children.append(node)
        else:
            roots.append(node)
        stack.append(node)
        if len(stack) > _MAX_DEPTH:
            raise JeansError("SVG elements are nested too deeply")

    def end(name: str) -> None:
        stack.pop()

    def doctype(name: str, sysid: str | None, pubid: str | None, has_internal_subset: int) -> None:
        if has_internal_subset:
            raise JeansError("SVG has a DOCTYPE internal subset, which is refused for safety")

    def entity(*args: object) -> None:
        raise JeansError("SVG declares XML entities, which are refused for safety")

    def external(*args: object) -> int:
        raise JeansError("SVG references an external entity, which is refused for safety")

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    parser.StartDoctypeDeclHandler = doctype
    parser.EntityDeclHandler = entity
    parser.UnparsedEntityDeclHandler = entity
    parser.ExternalEntityRefHandler = external
    try:
        parser.Parse(data, True)
    except expat.ExpatError as exc:
        raise JeansError(f"not an SVG file: XML {exc}") from None
    except (ValueError, UnicodeError, LookupError) as exc:  # LookupError: an unknown declared encoding
        raise JeansError(f"not an SVG file: {' '.join(str(exc).split())}") from None
    if not roots or roots[0].tag != "svg":
        raise JeansError("not an SVG file: the root element is not <svg>")
    return roots[0]


# ------------------------------------------------------------- attributes, style


def _numbers(text: str, what: str) -> list[float]:
    """All numbers in a whitespace/comma separated list; anything else is an error."""
    if not _SEPARATORS_ONLY_RE.fullmatch(_NUMBER_RE.sub(" ", text)):
        raise JeansError(f"malformed {what}: {text.strip()[:40]!r}")
    return [float(v) for v in _NUMBER_RE.findall(text)]


def _length(text: str | None, default: float, what: str, percent_of: float | None = None) -> float:
    """A length in px (user units); ``%`` needs ``percent_of``; font units are refused."""
    if text is None or not text.strip():
        return default
    match = _LENGTH_RE.fullmatch(text)
    if match is None or (match.group(2) == "%" and percent_of is None):
        raise JeansError(f"unsupported length for {what}: {text.strip()[:40]!r}")
    unit = percent_of / 100 if match.group(2) == "%" else _UNIT_PX[match.group(2)]
    value = float(match.group(1)) * unit
    if not math.isfinite(value):
        raise JeansError(f"non-finite length for {what}")
    return value


def _root_viewbox(root: _Node) -> tuple[float, float, float, float]:
    """``(min_x, min_y, width, height)`` of the root's user coordinate system."""
    box = root.attrs.get("viewBox")
    if box is not None and box.strip():
        values = _numbers(box, "viewBox")
        if len(values) != 4 or not all(math.isfinite(v) for v in values):
            raise JeansError("malformed viewBox: it needs four finite numbers")
        if values[2] <= 0 or values[3] <= 0:
            raise JeansError("SVG viewBox has a zero or negative size")
        return values[0], values[1], values[2], values[3]
    try:
        width = _length(root.attrs.get("width"), 0.0, "width")
        height = _length(root.attrs.get("height"), 0.0, "height")
    except JeansError:
        width = height = 0.0
    if width <= 0 or height <= 0:
        raise JeansError("SVG has no viewBox and no absolute width and height")
    return 0.0, 0.0, width, height


def _parse_style(text: str | None) -> dict[str, str]:
    out = {}
    if text:
        for item in text.split(";"):
            key, sep, value = item.partition(":")
            if sep:
                out[key.strip().lower()] = value.replace("!important", "").strip().lower()
    return out


def _is_zero(value: str) -> bool:
    """Whether an opacity value is zero (``0``, ``0.0``, ``0%``)."""
    match = _NUMBER_RE.match(value.strip())
    return match is not None and float(match.group()) <= 0


def _parse_transform(text: str | None) -> np.ndarray:
    """The 3x3 matrix of an SVG ``transform`` list (applied right to left)."""
    matrix = np.eye(3)
    if text is None or not text.strip():
        return matrix
    pos = 0
    while pos < len(text):
        match = _TRANSFORM_RE.match(text, pos)
        if match is None:
            if text[pos:].strip(" \t\r\n,"):
                raise JeansError(f"malformed transform: {text.strip()[:40]!r}")
            break
        pos = match.end()
        name, args = match.group(1), _numbers(match.group(2), "transform")
        if not all(math.isfinite(v) for v in args):
            raise JeansError("malformed transform: non-finite number")
        matrix = matrix @ _transform_matrix(name, args)
    return matrix


def _transform_matrix(name: str, args: list[float]) -> np.ndarray:
    allowed = {"matrix": (6,), "translate": (1, 2), "scale": (1, 2), "rotate": (1, 3), "skewX": (1,), "skewY": (1,)}[
        name
    ]
    if len(args) not in allowed:
        raise JeansError(f"malformed transform: {name} takes {' or '.join(map(str, allowed))} numbers, got {len(args)}")
    m = np.eye(3)
    if name == "matrix":
        a, b, c, d, e, f = args
        m[:2] = [[a, c, e], [b, d, f]]
    elif name == "translate":
        m[0, 2], m[1, 2] = args[0], (args[1] if len(args) == 2 else 0.0)
    elif name == "scale":
        m[0, 0], m[1, 1] = args[0], (args[1] if len(args) == 2 else args[0])
    elif name == "rotate":
        angle = math.radians(args[0])
        cos, sin = math.cos(angle), math.sin(angle)
        m[:2, :2] = [[cos, -sin], [sin, cos]]
        if len(args) == 3:
            cx, cy = args[1], args[2]
            m[:2, 2] = [cx - cos * cx + sin * cy, cy - sin * cx - cos * cy]
    elif name == "skewX":
        m[0, 1] = math.tan(math.radians(args[0]))
    else:
        m[1, 0] = math.tan(math.radians(args[0]))
    return m


# ------------------------------------------------------------------ tree walking


@dataclass(frozen=True)
class _Style:
    """The inherited properties that decide whether and how a shape is filled."""

    filled: bool = True
    evenodd: bool = False
    visible: bool = True


_DEFAULT_STYLE = _Style()
_SHAPES = ("path", "rect", "circle", "ellipse", "polygon", "polyline")
_CONTAINERS = ("g", "a", "symbol")


class _Walker:
    """Collects every filled, visible shape of the tree as a :class:`_Shape`."""

    def __init__(self, root: _Node, shapes: list[_Shape], viewport: tuple[float, float]):
        self.shapes = shapes
        self.viewport = viewport  # what percentage lengths refer to
        self.ids: dict[str, _Node] = {}
        self.use_stack: list[str] = []
        self._index(root)

    def _index(self, node: _Node) -> None:
        todo = [node]
        while todo:
            item = todo.pop()
            ident = item.attrs.get("id")
            if ident is not None:
                self.ids.setdefault(ident, item)
            todo.extend(reversed(item.children))

    def walk(self, node: _Node, ctm: np.ndarray, style: _Style, depth: int) -> None:
        """Render ``node``'s children under the user-to-canvas matrix ``ctm``."""
        children = node.children
        if node.tag == "switch":  # only the first child that applies is rendered
            children = [
                c
                for c in children
                if c.tag is not None
                and c.tag != "foreignObject"
                and not {"requiredExtensions", "systemLanguage"} & c.attrs.keys()
            ][:1]
        for child in children:
            self.element(child, ctm, style, depth + 1)

    def element(self, node: _Node, ctm: np.ndarray, style: _Style, depth: int, via_use: bool = False) -> None:
        tag = node.tag
        if depth > _MAX_DEPTH + 64:
            raise JeansError("SVG elements are nested too deeply")
        if tag == "symbol" and not via_use:
            return  # a symbol is drawn only where a <use> instantiates it
        if tag not in _SHAPES and tag not in _CONTAINERS and tag not in ("svg", "switch", "use"):
            return  # defs, clipPath, mask, text, foreign elements...: not silhouette
        props = {
            k: node.attrs[k].strip().lower()
            for k in ("fill", "fill-rule", "fill-opacity", "opacity", "display", "visibility")
            if k in node.attrs
        }
        props.update(_parse_style(node.attrs.get("style")))
        if props.get("display") == "none" or _is_zero(props.get("opacity", "1")):
            return
        style = _Style(
            filled=_inherit(props.get("fill"), style.filled, _is_silhouette_paint),
            evenodd=_inherit(props.get("fill-rule"), style.evenodd, lambda v: v == "evenodd"),
            visible=_inherit(props.get("visibility"), style.visible, lambda v: v not in ("hidden", "collapse")),
        )
        if "fill-opacity" in props and _is_zero(props["fill-opacity"]):
            style = _Style(False, style.evenodd, style.visible)
        if tag != "svg":
            ctm = ctm @ _parse_transform(node.attrs.get("transform"))
        if tag in _CONTAINERS or tag == "switch":
            self.walk(node, ctm, style, depth)
        elif tag == "svg":
            self.walk(node, ctm @ _nested_viewport(node), style, depth)
        elif tag == "use":
            self.use(node, ctm, style, depth)
        elif style.filled and style.visible:
            builder = _PathBuilder()
            _shape_geometry(node, builder, self.viewport)
            cubics, sub = builder.arrays()
            if len(cubics):
                self.shapes.append(_Shape(cubics, sub, ctm, style.evenodd))

    def use(self, node: _Node, ctm: np.ndarray, style: _Style, depth: int) -> None:
        href = node.attrs.get("href", "").strip()
        target = self.ids.get(href[1:]) if href.startswith("#") else None
        if target is None or href in self.use_stack or len(self.use_stack) >= _MAX_USE_DEPTH:
            return
        offset = np.eye(3)
        offset[0, 2] = _length(node.attrs.get("x"), 0.0, "use x", self.viewport[0])
        offset[1, 2] = _length(node.attrs.get("y"), 0.0, "use y", self.viewport[1])
        self.use_stack.append(href)
        try:
            self.element(target, ctm @ offset, style, depth + 1, via_use=True)
        finally:
            self.use_stack.pop()


def _is_silhouette_paint(fill: str) -> bool:
    """Whether a ``fill`` value paints silhouette: anything but none and white.

    White (every channel >= 240) is taken for a background or a highlight and is
    ignored, so a white backdrop rectangle does not swallow the canvas.
    """
    fill = fill.strip().lower()
    if fill in ("none", "transparent", "white"):
        return False
    if re.fullmatch(r"#[0-9a-f]{3,4}", fill):
        channels = [int(c * 2, 16) for c in fill[1:4]]
    elif re.fullmatch(r"#[0-9a-f]{6}([0-9a-f]{2})?", fill):
        channels = [int(fill[i : i + 2], 16) for i in (1, 3, 5)]
    else:
        match = re.fullmatch(r"rgba?\(([^)]*)\)", fill)
        if match is None:
            return True  # named colours, url(#gradient), currentColor...
        parts = [p.strip() for p in re.split(r"[\s,/]+", match.group(1).strip())][:3]
        try:
            channels = [float(p[:-1]) * 2.55 if p.endswith("%") else float(p) for p in parts]
        except ValueError:
            return True
    return not (len(channels) == 3 and min(channels) >= 240)


def _inherit(value: str | None, parent: bool, parse: Callable[[str], bool]) -> bool:
    if value is None or value in ("", "inherit"):
        return parent
    return bool(parse(value))


def _nested_viewport(node: _Node) -> np.ndarray:
    """Map of a nested ``<svg>``: translate(x, y), then its viewBox fitted, centred."""
    m = np.eye(3)
    m[0, 2] = _length(node.attrs.get("x"), 0.0, "svg x")
    m[1, 2] = _length(node.attrs.get("y"), 0.0, "svg y")
    box = node.attrs.get("viewBox")
    if box and box.strip():
        values = _numbers(box, "viewBox")
        try:
            width = _length(node.attrs.get("width"), 0.0, "svg width")
            height = _length(node.attrs.get("height"), 0.0, "svg height")
        except JeansError:
            return m  # percentage sizes: keep the viewBox units as they are
        if len(values) == 4 and values[2] > 0 and values[3] > 0 and width > 0 and height > 0:
            s = min(width / values[2], height / values[3])
            fit = np.array(
                [
                    [s, 0, (width - s * values[2]) / 2 - s * values[0]],
                    [0, s, (height - s * values[3]) / 2 - s * values[1]],
                    [0, 0, 1.0],
                ]
            )
            m = m @ fit
    return m


def _shape_geometry(node: _Node, b: _PathBuilder, viewport: tuple[float, float]) -> None:
    """Append the outline of a basic shape or path element to ``b``.

    ``viewport`` is the ``(width, height)`` that percentage lengths refer to.
    """
    a = node.attrs
    tag = node.tag
    width, height = viewport
    diagonal = math.hypot(width, height) / math.sqrt(2)

    def length(name: str, percent_of: float, default: float = 0.0) -> float:
        return _length(a.get(name), default, f"{tag} {name}", percent_of)

    if tag == "path":
        _parse_path_data(a.get("d", ""), b)
    elif tag in ("polygon", "polyline"):
        values = _numbers(a.get("points", ""), f"{tag} points")
        if len(values) >= 4:
            b.move_to(values[0], values[1])
            for i in range(2, len(values) - 1, 2):
                b.line_to(values[i], values[i + 1])
            b.close()
    elif tag == "rect":
        x, y = length("x", width), length("y", height)
        w, h = length("width", width), length("height", height)
        if w <= 0 or h <= 0:
            return
        rx, ry = length("rx", width, -1.0), length("ry", height, -1.0)
        rx, ry = (ry if rx < 0 else rx), (rx if ry < 0 else ry)  # one given: both
        rx, ry = min(max(rx, 0.0), w / 2), min(max(ry, 0.0), h / 2)
        if rx == 0 or ry == 0:
            b.move_to(x, y)
            b.line_to(x + w, y)
            b.line_to(x + w, y + h)
            b.line_to(x, y + h)
        else:
            b.move_to(x + rx, y)
            b.line_to(x + w - rx, y)
            b.arc_to(rx, ry, 0, False, True, x + w, y + ry)
            b.line_to(x + w, y + h - ry)
            b.arc_to(rx, ry, 0, False, True, x + w - rx, y + h)
            b.line_to(x + rx, y + h)
            b.arc_to(rx, ry, 0, False, True, x, y + h - ry)
            b.line_to(x, y + ry)
            b.arc_to(rx, ry, 0, False, True, x + rx, y)
        b.close()
    elif tag in ("circle", "ellipse"):
        cx, cy = length("cx", width), length("cy", height)
        if tag == "circle":
            rx = ry = length("r", diagonal)
        else:
            rx, ry = length("rx", width), length("ry", height)
        if rx > 0 and ry > 0:
            b.move_to(cx + rx, cy)
            b.arc_to(rx, ry, 0, False, True, cx - rx, cy)
            b.arc_to(rx, ry, 0, False, True, cx + rx, cy)
            b.close()


# -------------------------------------------------------------------- path data


# ---------------------------------------------------------------- flattening


# --------------------------------------------------------------- rasterisation


__all__ = [
    "FLATTEN_TOLERANCE",
    "MAX_FILE_BYTES",
    "MAX_SEGMENTS",
    "SVG_EXTENSIONS",
    "SvgSilhouette",
    "flatten_path_data",
    "read_svg_silhouette",
    "read_svg_silhouette_from_bytes",
]
