"""Read an SVG silhouette: parse its filled shapes and rasterise them onto the canvas.

The paper's inputs are SVG files holding one filled path in a 256x256 viewBox. This
module turns such a file into the silhouette ``S``: a ``(canvas, canvas)`` float32
coverage image in ``[0, 1]``. Everything is stdlib + numpy:

* XML is parsed with ``xml.parsers.expat``; any entity declaration or DOCTYPE
  internal subset is refused before and during parsing (no billion laughs, nothing is
  ever fetched).
* Path data (all SVG 1.1 commands, including elliptical arcs) becomes cubic Bezier
  segments, which are mapped to canvas pixels and flattened adaptively (chord error
  at most :data:`FLATTEN_TOLERANCE` canvas px).
* Polygons are filled with the exact nonzero / evenodd rule at ``supersample**2``
  sample points per pixel by a vectorised scanline (crossings of every edge with
  every sample row, accumulated with ``bincount`` + ``cumsum``), then box-averaged.

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
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from xml.parsers import expat

import numpy as np

from jeanscv.errors import JeansError
from jeanscv.geometry import invert_affine
from jeanscv.io.files import open_regular

#: File extensions read as SVG silhouettes.
SVG_EXTENSIONS = frozenset({".svg", ".svgz"})

FLATTEN_TOLERANCE = 0.05
"""Largest distance, in canvas px, between a curve and its flattened polyline."""

MAX_SEGMENTS = 2_000_000
"""Most line segments (after flattening, over all shapes) a silhouette may have."""

MAX_FILE_BYTES = 64 * 1024 * 1024
"""Largest SVG accepted, after gunzipping an ``.svgz``."""

_MAX_COORD = 1e9  # canvas px; keeps sample-index arithmetic far from overflow
_MAX_DEPTH = 200  # element nesting; the tree walk recurses twice per level
_MAX_USE_DEPTH = 16  # <use> indirections
_CROSSING_BUDGET = 1_000_000  # scanline crossings per chunk: bounds memory (~100 MB)
_BAND_PIXELS = 32  # canvas rows rasterised together

_SVG_NS = "http://www.w3.org/2000/svg"
_XLINK_NS = "http://www.w3.org/1999/xlink"

_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_NUMBER_RE = re.compile(_NUMBER)
_PATH_SCAN_RE = re.compile(r"[\s,]*([MmZzLlHhVvCcSsQqTtAa]|" + _NUMBER + r"|[^\s,])")
_SEPARATORS_ONLY_RE = re.compile(r"[\s,]*")
_LENGTH_RE = re.compile(r"\s*(" + _NUMBER + r")\s*(px|pt|pc|mm|cm|in|%|)\s*")
_UNIT_PX = {"": 1.0, "px": 1.0, "pt": 96 / 72, "pc": 16.0, "mm": 96 / 25.4, "cm": 96 / 2.54, "in": 96.0}
_TRANSFORM_RE = re.compile(r"[\s,]*(matrix|translate|scale|rotate|skewX|skewY)\s*\(([^)]*)\)[\s,]*")
_COMMANDS = frozenset("MmZzLlHhVvCcSsQqTtAa")
_CUT_RE = re.compile(r"[\s,MmZzLlHhVvCcSsQqTtAa]")
_ARITY = {"M": 2, "L": 2, "H": 1, "V": 1, "C": 6, "S": 4, "Q": 4, "T": 2, "A": 7}


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


def flatten_path_data(d: str, tolerance: float = FLATTEN_TOLERANCE) -> list[np.ndarray]:
    """Parse SVG path data ``d`` and flatten it to closed polylines in its own units.

    Returns one ``(k, 2)`` float64 array per subpath that draws something (the
    closing edge back to the first point is implied, not repeated). Curves are
    flattened to within ``tolerance`` units. Raises :class:`JeansError` for malformed
    data.
    """
    if not tolerance > 0:
        raise JeansError(f"flattening tolerance must be positive, not {tolerance!r}")
    builder = _PathBuilder()
    _parse_path_data(d, builder)
    cubics, sub = builder.arrays()
    if len(cubics) == 0:
        return []
    a, b, piece_sub = _flatten(cubics, sub, tolerance, None)
    out = []
    for index in np.unique(piece_sub):
        pieces = piece_sub == index
        points = np.vstack([a[pieces], b[pieces][-1:]])
        if np.array_equal(points[-1], points[0]) and len(points) > 1:
            points = points[:-1]
        out.append(points)
    return out


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


class _PathBuilder:
    """Accumulates outlines as cubic Bezier segments, each tagged with its subpath.

    Lines are stored as cubics with thirds-points controls (zero second difference,
    so they flatten to exactly one segment); quadratics are degree-elevated exactly.
    """

    _FLUSH = 65536  # segments kept as Python floats before packing into numpy

    def __init__(self) -> None:
        self.coords: list[float] = []  # 8 per cubic: x0 y0 x1 y1 x2 y2 x3 y3
        self.sub: list[int] = []
        self.packed: list[tuple[np.ndarray, np.ndarray]] = []  # bounds memory
        self.n_packed = 0
        self.n_sub = 0
        self.x = self.y = 0.0
        self.start_x = self.start_y = 0.0
        self.new_sub = True

    def _pack(self) -> None:
        self.packed.append(
            (np.array(self.coords, dtype=np.float64).reshape(-1, 4, 2), np.array(self.sub, dtype=np.int64))
        )
        self.n_packed += len(self.sub)
        self.coords.clear()
        self.sub.clear()
        if self.n_packed > MAX_SEGMENTS:
            raise JeansError(f"path is too complex: over {MAX_SEGMENTS} segments")

    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """``(n, 4, 2)`` float64 control points and ``(n,)`` int64 subpath ids."""
        self._pack()
        cubics = np.concatenate([c for c, _ in self.packed])
        sub = np.concatenate([i for _, i in self.packed])
        self.packed = [(cubics, sub)]
        if not np.all(np.isfinite(cubics)):
            raise JeansError("path has non-finite coordinates")
        return cubics, sub

    def move_to(self, x: float, y: float) -> None:
        self.x = self.start_x = x
        self.y = self.start_y = y
        self.new_sub = True

    def close(self) -> None:
        self.x, self.y = self.start_x, self.start_y
        self.new_sub = True

    def _append(self, values: tuple[float, ...]) -> None:
        if self.new_sub:
            self.n_sub += 1
            self.new_sub = False
        self.coords.extend(values)
        self.sub.append(self.n_sub)
        if len(self.sub) >= self._FLUSH:
            self._pack()

    def line_to(self, x: float, y: float) -> None:
        x0, y0 = self.x, self.y
        if x != x0 or y != y0:
            dx, dy = (x - x0) / 3, (y - y0) / 3
            self._append((x0, y0, x0 + dx, y0 + dy, x - dx, y - dy, x, y))
            self.x, self.y = x, y

    def cubic_to(self, x1: float, y1: float, x2: float, y2: float, x: float, y: float) -> None:
        self._append((self.x, self.y, x1, y1, x2, y2, x, y))
        self.x, self.y = x, y

    def quad_to(self, qx: float, qy: float, x: float, y: float) -> None:
        x0, y0 = self.x, self.y
        self.cubic_to(x0 + 2 / 3 * (qx - x0), y0 + 2 / 3 * (qy - y0), x + 2 / 3 * (qx - x), y + 2 / 3 * (qy - y), x, y)

    def arc_to(self, rx: float, ry: float, rotation: float, large: bool, sweep: bool, x: float, y: float) -> None:
        """Elliptical arc per SVG 1.1 F.6.5 (endpoint to centre) and F.6.6 (radii)."""
        x1, y1 = self.x, self.y
        if x1 == x and y1 == y:
            return
        if not all(map(math.isfinite, (rx, ry, rotation, x, y, x1, y1))):
            raise JeansError("path has non-finite coordinates")
        rx, ry = abs(rx), abs(ry)
        if rx == 0 or ry == 0:
            self.line_to(x, y)
            return
        phi = math.radians(rotation % 360)
        cos, sin = math.cos(phi), math.sin(phi)
        hx, hy = (x1 - x) / 2, (y1 - y) / 2
        xp, yp = cos * hx + sin * hy, -sin * hx + cos * hy
        # in radius units (a, b) the correction and the centre are scale-free
        a, b = xp / rx, yp / ry
        lam = a * a + b * b
        if lam > 1:  # radii too small to join the endpoints: scale them up
            root = math.sqrt(lam)
            rx, ry, a, b, lam = rx * root, ry * root, a / root, b / root, 1.0
        if lam < 1e-20 and not large:
            self.line_to(x, y)  # radius > 1e10 chords: the arc bulges < 1e-10 chords
            return
        coef = math.sqrt(max(1.0 - lam, 0.0) / lam) if lam > 0 else 0.0
        if large == sweep:
            coef = -coef
        ca, cb = coef * b, -coef * a  # centre in the rotated frame, radius units
        cx = cos * ca * rx - sin * cb * ry + (x1 + x) / 2
        cy = sin * ca * rx + cos * cb * ry + (y1 + y) / 2
        theta = math.atan2(b - cb, a - ca)
        delta = math.atan2(-b - cb, -a - ca) - theta
        if sweep and delta < 0:
            delta += 2 * math.pi
        elif not sweep and delta > 0:
            delta -= 2 * math.pi
        if not all(map(math.isfinite, (cx, cy, rx, ry, delta))):
            self.line_to(x, y)  # absurd radii (overflow): the arc is its chord
            return
        # 45-degree cubic pieces: radial error 4e-6 * radius
        n = max(1, math.ceil(abs(delta) / (math.pi / 4) - 1e-9))
        step = delta / n
        k = 4 / 3 * math.tan(step / 4)

        def point(ux: float, uy: float) -> tuple[float, float]:
            return (cx + rx * cos * ux - ry * sin * uy, cy + rx * sin * ux + ry * cos * uy)

        for i in range(n):
            # the unit-circle piece from angle t0 to t1, then mapped onto the ellipse
            t0, t1 = theta + i * step, theta + (i + 1) * step
            c0, s0, c1, s1 = math.cos(t0), math.sin(t0), math.cos(t1), math.sin(t1)
            p1 = point(c0 - k * s0, s0 + k * c0)
            p2 = point(c1 + k * s1, s1 - k * c1)
            end = (x, y) if i == n - 1 else point(c1, s1)  # land exactly on the endpoint
            self.cubic_to(*p1, *p2, *end)


def _take_flag(tokens: list[str], i: int) -> tuple[bool, int]:
    """Read an arc flag at ``tokens[i]``; a flag may be glued to what follows it.

    Returns the flag and the index of the next token (a glued remainder replaces
    ``tokens[i]`` in place, so the index stays).
    """
    if i >= len(tokens):
        raise JeansError("malformed path data: an arc ends early")
    tok = tokens[i]
    if tok[0] not in "01":
        raise JeansError(f"malformed path data: an arc flag must be 0 or 1, not {tok!r}")
    if len(tok) == 1:
        return tok == "1", i + 1
    tokens[i] = tok[1:]
    return tok[0] == "1", i


def _bad_token(tokens: list[str]) -> str:
    """The first token that is neither a command nor a number (for error messages)."""
    for tok in tokens:
        if tok not in _COMMANDS and not _NUMBER_RE.fullmatch(tok):
            return tok
    return ""


def _path_chunks(d: str, size: int = 1 << 18) -> Iterator[tuple[str, bool]]:
    """Yield ``(piece, is_last)``: ``d`` cut into pieces of about ``size`` characters.

    Cuts fall on a separator or before a command letter, so no token is split;
    tokenising piecewise keeps the token list small for huge paths.
    """
    start = 0
    while len(d) - start > size:
        match = _CUT_RE.search(d, start + size)
        if match is None:
            break
        yield d[start : match.start()], False
        start = match.start()
    yield d[start:], True


def _parse_path_data(d: str, b: _PathBuilder, piece_size: int = 1 << 18) -> None:
    """Parse SVG path data into ``b``; raise :class:`JeansError` on any error."""
    cmd = ""
    last_cubic = last_quad = None  # reflected-control bookkeeping for S/s and T/t
    first = True
    pending: list[str] = []  # tokens of a command cut by a piece boundary
    awaiting = False  # a command letter was read and its arguments are still due
    for piece, is_last in _path_chunks(d, piece_size):
        # every non-separator character lands in some token; junk fails float() below
        tokens = pending + _PATH_SCAN_RE.findall(piece)
        pending = []
        if first and tokens:
            if tokens[0] not in ("M", "m"):
                raise JeansError("malformed path data: it must start with a moveto (M or m)")
            first = False
        i, n = 0, len(tokens)
        while i < n:
            tok = tokens[i]
            if tok in _COMMANDS:
                cmd = tok
                i += 1
                if cmd in "Zz":
                    b.close()
                    last_cubic = last_quad = None
                    cmd = ""
                    continue
                awaiting = True
            elif not cmd:
                raise JeansError(f"malformed path data: {tok!r} where a command was expected")
            if not is_last and n - i < 7:  # maybe cut: finish it with the next piece
                pending = tokens[i:]
                break
            upper = cmd.upper()
            rel = cmd.islower()
            x0, y0 = b.x, b.y
            awaiting = False
            if upper == "A":
                try:
                    rx, ry, rot = float(tokens[i]), float(tokens[i + 1]), float(tokens[i + 2])
                    large, i = _take_flag(tokens, i + 3)
                    sweep, i = _take_flag(tokens, i)
                    x, y = float(tokens[i]), float(tokens[i + 1])
                    i += 2
                except (ValueError, IndexError):
                    raise JeansError(f"malformed path data: expected 7 arc parameters after {cmd!r}") from None
                if rel:
                    x, y = x + x0, y + y0
                b.arc_to(rx, ry, rot, large, sweep, x, y)
                last_cubic = last_quad = None
                continue
            k = _ARITY[upper]
            try:
                v = [float(t) for t in tokens[i : i + k]]
            except ValueError:
                bad = _bad_token(tokens[i : i + k])
                if bad:
                    raise JeansError(f"malformed path data: unexpected {bad[:20]!r}") from None
                v = []
            if len(v) != k:
                raise JeansError(f"malformed path data: expected {k} numbers after {cmd!r}")
            i += k
            if upper == "H":
                b.line_to(v[0] + x0 if rel else v[0], y0)
                last_cubic = last_quad = None
                continue
            if upper == "V":
                b.line_to(x0, v[0] + y0 if rel else v[0])
                last_cubic = last_quad = None
                continue
            if rel:
                v = [value + (x0 if j % 2 == 0 else y0) for j, value in enumerate(v)]
            if upper == "M":
                b.move_to(v[0], v[1])
                cmd = "l" if rel else "L"  # further pairs are implicit linetos
                last_cubic = last_quad = None
            elif upper == "L":
                b.line_to(v[0], v[1])
                last_cubic = last_quad = None
            elif upper == "C":
                b.cubic_to(*v)
                last_cubic, last_quad = (v[2], v[3]), None
            elif upper == "S":
                c1 = (2 * x0 - last_cubic[0], 2 * y0 - last_cubic[1]) if last_cubic else (x0, y0)
                b.cubic_to(c1[0], c1[1], *v)
                last_cubic, last_quad = (v[0], v[1]), None
            elif upper == "Q":
                b.quad_to(*v)
                last_cubic, last_quad = None, (v[0], v[1])
            else:  # T
                q = (2 * x0 - last_quad[0], 2 * y0 - last_quad[1]) if last_quad else (x0, y0)
                b.quad_to(q[0], q[1], v[0], v[1])
                last_cubic, last_quad = None, q
    if awaiting:
        raise JeansError(f"malformed path data: {cmd!r} has no arguments")


# ---------------------------------------------------------------- flattening


def _flatten(
    cubics: np.ndarray, sub: np.ndarray, tol: float, canvas_size: int | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Flatten ``(n, 4, 2)`` cubics to line pieces ``(a, b, piece_sub)``.

    Each cubic gets ``ceil(sqrt(0.75 * L / tol))`` uniform pieces, where ``L`` is the
    largest second difference of its control points: the chord error of a uniform
    split into ``m`` pieces is at most ``max|B''| / (8 m^2) <= 6 L / (8 m^2)``.
    A cubic whose control box misses the canvas becomes one chord: the region between
    curve and chord then holds no sample, so coverage is unchanged.
    """
    d1 = cubics[:, 0] - 2 * cubics[:, 1] + cubics[:, 2]
    d2 = cubics[:, 1] - 2 * cubics[:, 2] + cubics[:, 3]
    second = np.maximum(np.hypot(d1[:, 0], d1[:, 1]), np.hypot(d2[:, 0], d2[:, 1]))
    pieces = np.ceil(np.sqrt(0.75 * second / tol))
    if canvas_size is not None:
        lo, hi = cubics.min(axis=1), cubics.max(axis=1)
        off = np.any(hi < 0, axis=1) | np.any(lo > canvas_size, axis=1)
        pieces[off] = 1
    pieces = np.maximum(pieces, 1)
    if pieces.sum() > MAX_SEGMENTS:
        raise JeansError(f"path is too complex: over {MAX_SEGMENTS} segments after flattening")
    counts = pieces.astype(np.int64)
    if np.all(counts == 1):  # lines only: no evaluation needed
        return cubics[:, 0].copy(), cubics[:, 3].copy(), sub
    seg = np.repeat(np.arange(len(cubics)), counts)
    ends = np.cumsum(counts)  # one past each cubic's last piece
    t = np.arange(len(seg)) - np.repeat(ends - counts, counts)
    t = t / counts[seg]
    a = _bezier(cubics, seg, t)  # piece starts
    b = np.empty_like(a)
    b[:-1] = a[1:]
    b[ends - 1] = cubics[:, 3]  # each cubic's last piece ends on its end point
    return a, b, sub[seg]


def _bezier(cubics: np.ndarray, seg: np.ndarray, t: np.ndarray) -> np.ndarray:
    """``(m, 2)`` points of cubics ``cubics[seg]`` at ``t`` (exact at t = 0)."""
    t = t[:, None]
    s = 1.0 - t
    out = (s * s * s) * cubics[seg, 0]
    out += (3 * s * s * t) * cubics[seg, 1]
    out += (3 * s * t * t) * cubics[seg, 2]
    out += (t * t * t) * cubics[seg, 3]
    return out


# --------------------------------------------------------------- rasterisation


class _Shape:
    """One filled element: its outline in user units and its user-to-canvas map."""

    def __init__(self, cubics: np.ndarray, sub: np.ndarray, ctm: np.ndarray, evenodd: bool):
        self.cubics = cubics  # (n, 4, 2) user units
        self.sub = sub  # (n,) subpath ids
        self.ctm = ctm  # (3, 3) user units -> canvas px
        self.evenodd = evenodd


class _Edges:
    """Non-horizontal edges in sample units, ready for the scanline.

    Sample ``(col, row)`` sits at canvas point ``((col + .5) / s, (row + .5) / s)``;
    an edge crosses sample rows ``j0 <= row < j1`` (half-open in y, so a vertex shared
    by two edges is counted once and an extremum twice with opposite signs).
    """

    def __init__(self, a: np.ndarray, b: np.ndarray, s: int, evenodd: bool):
        flip = b[:, 1] < a[:, 1]
        top = np.where(flip[:, None], b, a) * s - 0.5  # in sample index coordinates
        bottom = np.where(flip[:, None], a, b) * s - 0.5
        j0 = np.ceil(top[:, 1])
        j1 = np.ceil(bottom[:, 1])
        keep = j1 > j0
        self.x = top[keep, 0]
        self.y = top[keep, 1]
        self.dxdy = (bottom[keep, 0] - top[keep, 0]) / (bottom[keep, 1] - top[keep, 1])
        self.dir = np.where(flip[keep], -1.0, 1.0)
        self.j0 = j0[keep].astype(np.int64)
        self.j1 = j1[keep].astype(np.int64)
        self.evenodd = evenodd
        if len(self.x):
            self.rows = (int(self.j0.min()), int(self.j1.max()))
            xs = np.concatenate([top[keep, 0], bottom[keep, 0]])
            self.cols = (int(np.floor(xs.min())) + 1, int(np.floor(xs.max())) + 1)
        else:
            self.rows = self.cols = (0, 0)

    def inside(self, r0: int, r1: int, c0: int, c1: int) -> np.ndarray:
        """``(r1 - r0, c1 - c0)`` bool: which samples the fill rule puts inside."""
        live = (self.j0 < r1) & (self.j1 > r0)
        j0 = np.maximum(self.j0[live], r0)
        counts = np.minimum(self.j1[live], r1) - j0
        total = int(counts.sum())
        if total > _CROSSING_BUDGET and r1 - r0 > 1:
            mid = (r0 + r1) // 2
            return np.vstack([self.inside(r0, mid, c0, c1), self.inside(mid, r1, c0, c1)])
        width = c1 - c0
        edge = np.repeat(np.flatnonzero(live), counts)
        row = np.repeat(j0 - np.cumsum(counts) + counts, counts) + np.arange(total)
        x = self.x[edge] + (row - self.y[edge]) * self.dxdy[edge]
        # a crossing at x flips every sample strictly to its right: cols > x
        col = np.clip(np.floor(np.clip(x, c0 - 2, c1 + 2)).astype(np.int64) + 1 - c0, 0, width)
        acc = np.bincount((row - r0) * (width + 1) + col, weights=self.dir[edge], minlength=(r1 - r0) * (width + 1))
        winding = np.cumsum(acc.reshape(r1 - r0, width + 1)[:, :width], axis=1)
        if self.evenodd:
            return np.remainder(winding, 2) != 0
        return winding != 0


def _rasterize_shapes(shapes: list[_Shape], canvas_size: int, s: int) -> np.ndarray:
    """Union coverage of the shapes: ``(canvas_size, canvas_size)`` float32 in [0, 1]."""
    size = canvas_size * s
    edge_sets = []
    total = 0
    for shape in shapes:
        canvas = shape.cubics @ shape.ctm[:2, :2].T + shape.ctm[:2, 2]
        if not np.all(np.abs(canvas) < _MAX_COORD):  # also catches inf and nan
            raise JeansError("path coordinates are too large (beyond 1e9 canvas px)")
        a, b, piece_sub = _flatten(canvas, shape.sub, FLATTEN_TOLERANCE, canvas_size)
        total += len(a)
        if total > MAX_SEGMENTS:
            raise JeansError(f"path is too complex: over {MAX_SEGMENTS} segments after flattening")
        # implicit close of every subpath: its last point back to its first
        last = np.flatnonzero(np.diff(np.append(piece_sub, -1)) != 0)
        first = np.concatenate([[0], last[:-1] + 1])
        closing_a, closing_b = b[last], a[first]
        edge_sets.append(_Edges(np.concatenate([a, closing_a]), np.concatenate([b, closing_b]), s, shape.evenodd))

    alpha = np.zeros((canvas_size, canvas_size), dtype=np.float32)
    band = _BAND_PIXELS * s
    for r0 in range(0, size, band):
        r1 = min(size, r0 + band)
        mask = None
        for edges in edge_sets:
            if edges.rows[1] <= r0 or edges.rows[0] >= r1:
                continue
            c0, c1 = max(edges.cols[0], 0), min(edges.cols[1], size)
            if c1 <= c0:
                continue
            if mask is None:
                mask = np.zeros((r1 - r0, size), dtype=bool)
            mask[:, c0:c1] |= edges.inside(r0, r1, c0, c1)
        if mask is not None:
            blocks = mask.reshape((r1 - r0) // s, s, canvas_size, s)
            alpha[r0 // s : r1 // s] = blocks.sum(axis=(1, 3), dtype=np.int32) / np.float32(s * s)
    return alpha
