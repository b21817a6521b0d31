"""Garment templates: the polygon the fitter deforms, and which edges are open.

A garment is data. Vertices are in canvas pixels (x right, y down) on the 256 canvas;
edge ``i`` runs from vertex ``i`` to vertex ``(i + 1) % n``. Built-ins: ``jeans`` (the
paper's), ``shorts`` and ``skirt``; more come from TOML files (:meth:`Garment.from_toml`)
and from plugins; :func:`jeanscv.plugins.get_garment` finds a garment by name or path
among all of them.

A garment TOML file::

    name = "cape"
    description = "A six-vertex cape"
    vertices = [[80, 180], [92, 80], [112, 70], [134, 70], [154, 80], [166, 180]]
    open_edges = [2, 5]        # edge i joins vertex i and i+1: the neckline and the hem
    waist = [2, 3]             # the midpoint of these vertices is centred on the canvas

    [draw]                     # optional hints for the compositor
    style = "plain"            # jeans | shorts | skirt | plain
    colour = "#3050a0"         # or [48, 80, 160]
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass, field
from itertools import combinations

import numpy as np

from ..errors import JeansError
from ..geometry import CANVAS_SIZE
from ..io.files import open_regular

#: Detail sets a garment asks the compositor for (``Garment.extra["style"]``): ``jeans``
#: and ``shorts`` have a fly, pockets, belt loops, leg hems and crotch whiskers;
#: ``skirt`` the same without whiskers (it has no crotch); ``plain`` only seams and hems.
DRAW_STYLES = ("jeans", "shorts", "skirt", "plain")

#: Bigger garment files are refused before parsing (the built-in ones are under 1 KiB).
_MAX_TOML_BYTES = 1 << 20
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")
_TOML_KEYS = {"name", "description", "vertices", "open_edges", "waist", "draw"}
_DRAW_KEYS = {"style", "colour", "color"}
_MIN_AREA = 1.0  # square canvas pixels
_MIN_EDGE = 1e-6  # canvas pixels


@dataclass(frozen=True)
class Garment:
    """A closed polygon template with open/closed edge labels.

    ``template``: ``(n, 2)`` float64 canvas pixels, n >= 3, a simple polygon (either
    orientation). ``open_edges`` are indices of edges the body passes through
    (waistband, leg openings); every other edge is closed (a seam the body should not
    cross); at least one of each. ``waist`` names two distinct vertices whose midpoint
    is the waistband centre (the paper's ``L_center`` target); they are usually the
    ends of the waistband edge but need not be adjacent. ``extra`` holds drawing hints:
    ``style`` (one of :data:`DRAW_STYLES`) and ``colour`` (``(r, g, b)`` ints).

    Construction validates all of this and raises :class:`JeansError` on bad data.
    """

    name: str
    template: np.ndarray  # (n, 2) canvas pixels
    open_edges: tuple[int, ...]
    waist: tuple[int, int]
    description: str = ""
    extra: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        template, open_edges, waist, extra = _validated(
            self.name, self.template, self.open_edges, self.waist, self.description, self.extra
        )
        # Frozen dataclass: normalised copies replace what the caller passed.
        object.__setattr__(self, "template", template)
        object.__setattr__(self, "open_edges", open_edges)
        object.__setattr__(self, "waist", waist)
        object.__setattr__(self, "extra", extra)

    @property
    def num_vertices(self) -> int:
        return int(self.template.shape[0])

    @property
    def edges(self) -> np.ndarray:
        """``(n, 2)`` vertex indices of each edge, in order."""
        n = self.num_vertices
        return np.stack([np.arange(n), (np.arange(n) + 1) % n], axis=1)

    @property
    def hems(self) -> tuple[int, int]:
        """The far ends of the two outer seams: the neighbour of each waist vertex that is
        not the other waist vertex (jeans: 0 and 3, the outer hems). Their midpoint minus
        the waist midpoint is the garment's "down"."""
        n = self.num_vertices
        left, right = self.waist
        return tuple(
            next(v for v in ((w - 1) % n, (w + 1) % n) if v != other) for w, other in ((left, right), (right, left))
        )

    @property
    def closed_edges(self) -> tuple[int, ...]:
        return tuple(i for i in range(self.num_vertices) if i not in self.open_edges)

    @property
    def style(self) -> str:
        """The compositor's detail set (:data:`DRAW_STYLES`); ``plain`` when not given."""
        return self.extra.get("style", "plain")

    def edge_pairs(self, adjacent: bool = True) -> np.ndarray:
        """``(P, 2)`` edge-index pairs for ``L_inter``; ``adjacent=False`` drops pairs sharing a vertex."""
        n = self.num_vertices
        pairs = [(a, b) for a, b in combinations(range(n), 2) if adjacent or (b - a) % n not in (1, n - 1)]
        return np.asarray(pairs, dtype=np.int64).reshape(-1, 2)

    # ------------------------------------------------------------------ TOML

    @classmethod
    def from_dict(cls, data: dict) -> Garment:
        """A garment from the parsed TOML mapping (keys as in the module docstring)."""
        if not isinstance(data, dict):
            raise JeansError("garment data must be a table")
        unknown = sorted(set(data) - _TOML_KEYS)
        if unknown:
            raise JeansError(f"unknown garment key(s) {', '.join(unknown)} (allowed: {', '.join(sorted(_TOML_KEYS))})")
        for key in ("name", "vertices", "open_edges", "waist"):
            if key not in data:
                raise JeansError(f"garment is missing the key {key!r}")
        extra = _draw_hints(data.get("draw", {}))
        return cls(
            name=data["name"],
            template=data["vertices"],
            open_edges=data["open_edges"],
            waist=data["waist"],
            description=data.get("description", ""),
            extra=extra,
        )

    @classmethod
    def from_toml(cls, path: str | os.PathLike) -> Garment:
        """Read a garment TOML file; every problem is a one-line :class:`JeansError`."""
        toml = _toml_module()
        try:
            with open_regular(path) as file:  # a FIFO would block the read forever
                data = file.read(_MAX_TOML_BYTES + 1)
            if len(data) > _MAX_TOML_BYTES:
                raise JeansError(f"garment file is larger than {_MAX_TOML_BYTES // 1024} KiB")
            text = data.decode("utf-8")
        except OSError as exc:
            raise JeansError(f"cannot read garment file: {(exc.strerror or str(exc)).lower()}") from None
        except UnicodeDecodeError:
            raise JeansError("garment file is not UTF-8 text") from None
        try:
            data = toml.loads(text)
        except toml.TOMLDecodeError as exc:
            raise JeansError(f"garment file is not valid TOML: {' '.join(str(exc).split())}") from None
        return cls.from_dict(data)

    def to_toml(self) -> str:
        """This garment as TOML text that :meth:`from_toml` reads back to an equal garment.

        Coordinates are written with ``repr`` (shortest round-tripping float text).
        """
        lines = [
            f"name = {_toml_string(self.name)}",
            f"description = {_toml_string(self.description)}",
            "vertices = [" + ", ".join(f"[{float(x)!r}, {float(y)!r}]" for x, y in self.template) + "]",
            "open_edges = [" + ", ".join(str(i) for i in self.open_edges) + "]",
            f"waist = [{self.waist[0]}, {self.waist[1]}]",
        ]
        draw = []
        if "style" in self.extra:
            draw.append(f"style = {_toml_string(self.extra['style'])}")
        if "colour" in self.extra:
            draw.append("colour = [" + ", ".join(str(c) for c in self.extra["colour"]) + "]")
        if draw:
            lines += ["", "[draw]", *draw]
        return "\n".join(lines) + "\n"

    def same_as(self, other: Garment) -> bool:
        """Field-by-field equality (``==`` cannot compare the template arrays)."""
        return (
            self.name == other.name
            and self.description == other.description
            and np.array_equal(self.template, other.template)
            and self.open_edges == other.open_edges
            and self.waist == other.waist
            and self.extra == other.extra
        )


# ---------------------------------------------------------------------- validation


def _validated(
    name: object, template: object, open_edges: object, waist: object, description: object, extra: object
) -> tuple[np.ndarray, tuple[int, ...], tuple[int, int], dict]:
    """Check a garment's fields; return normalised ``(template, open_edges, waist, extra)``."""
    if not isinstance(name, str) or not _NAME.match(name):
        raise JeansError(
            f"garment name must be letters, digits, '_', '.' or '-' (starting with a letter or digit), got {name!r}"
        )
    if not isinstance(description, str):
        raise JeansError("garment description must be a string")
    vertices = _vertex_array(template)
    n = len(vertices)
    opened = _index_list(open_edges, n, "open_edges")
    if len(set(opened)) != len(opened):
        raise JeansError("open_edges has a repeated edge")
    if not opened:
        raise JeansError("a garment needs at least one open edge")
    if len(opened) == n:
        raise JeansError("a garment needs at least one closed edge")
    pair = _index_list(waist, n, "waist")
    if len(pair) != 2 or pair[0] == pair[1]:
        raise JeansError("waist must be two different vertex indices")
    _check_simple_polygon(vertices)
    if not isinstance(extra, dict):
        raise JeansError("garment extra must be a dict")
    extra = dict(extra)
    if "style" in extra and extra["style"] not in DRAW_STYLES:
        raise JeansError(f"unknown draw style {extra['style']!r} (use {', '.join(DRAW_STYLES)})")
    if "colour" in extra:
        extra["colour"] = _colour(extra["colour"])
    return vertices, tuple(sorted(opened)), (pair[0], pair[1]), extra


def _vertex_array(template: object) -> np.ndarray:
    """``(n, 2)`` float64 copy of the vertices, checked for shape, type and range."""
    if isinstance(template, (str, bytes)):
        raise JeansError("vertices must be a list of [x, y] pairs")
    try:
        rows = [list(p) for p in template]  # type: ignore[union-attr]
    except TypeError:
        raise JeansError("vertices must be a list of [x, y] pairs") from None
    if any(len(p) != 2 for p in rows):
        raise JeansError("vertices must be a list of [x, y] pairs")
    if not all(_is_number(c) for p in rows for c in p):
        raise JeansError("vertex coordinates must be numbers")
    vertices = np.array(rows, dtype=np.float64).reshape(-1, 2)
    if len(vertices) < 3:
        raise JeansError(f"a garment needs at least 3 vertices, got {len(vertices)}")
    if not np.all(np.isfinite(vertices)):
        raise JeansError("vertex coordinates must be finite")
    if vertices.min() < 0 or vertices.max() > CANVAS_SIZE:
        raise JeansError(f"vertices must lie on the {CANVAS_SIZE}x{CANVAS_SIZE} canvas (0..{CANVAS_SIZE} px)")
    return vertices


def _is_number(value: object) -> bool:
    """An int or float (numpy's too), but not a bool: TOML ``true`` is no coordinate."""
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))


def _index_list(values: object, n: int, what: str) -> list[int]:
    """Integer vertex/edge indices in ``0..n-1``."""
    if isinstance(values, (str, bytes)) or not hasattr(values, "__iter__"):
        raise JeansError(f"{what} must be a list of indices")
    out = []
    for v in values:  # type: ignore[union-attr]
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)):
            raise JeansError(f"{what} must hold integers, got {v!r}")
        if not 0 <= int(v) < n:
            raise JeansError(f"{what} index {int(v)} is out of range 0..{n - 1}")
        out.append(int(v))
    return out


def polygon_area(vertices: np.ndarray) -> float:
    """Signed shoelace area of ``(n, 2)`` vertices (positive when clockwise on a y-down screen)."""
    x, y = vertices[:, 0], vertices[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def _cross(o: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    return float((a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]))


def _segments_touch(p1: np.ndarray, p2: np.ndarray, q1: np.ndarray, q2: np.ndarray, tol: float) -> bool:
    """True when closed segments ``p1p2`` and ``q1q2`` share a point (``tol`` in px² of cross products)."""
    d1, d2 = _cross(q1, q2, p1), _cross(q1, q2, p2)
    d3, d4 = _cross(p1, p2, q1), _cross(p1, p2, q2)
    if ((d1 > tol and d2 < -tol) or (d1 < -tol and d2 > tol)) and (
        (d3 > tol and d4 < -tol) or (d3 < -tol and d4 > tol)
    ):
        return True

    def on_segment(a: np.ndarray, b: np.ndarray, p: np.ndarray, d: float) -> bool:
        """``p``, collinear with ``ab`` when ``d`` ~ 0, within its bounding box."""
        low, high = np.minimum(a, b) - 1e-9, np.maximum(a, b) + 1e-9
        return abs(d) <= tol and bool(np.all((low <= p) & (p <= high)))

    return (
        on_segment(q1, q2, p1, d1)
        or on_segment(q1, q2, p2, d2)
        or on_segment(p1, p2, q1, d3)
        or on_segment(p1, p2, q2, d4)
    )


def crossing_edges(vertices: np.ndarray) -> tuple[int, int] | None:
    """The first pair of edges ``(i, j)`` that makes the closed polygon non-simple, or None.

    Non-adjacent edges may not touch at all; adjacent edges may not fold back onto
    each other (a spike whose two edges overlap).
    """
    v = np.asarray(vertices, dtype=np.float64)
    n = len(v)
    tol = 1e-9 * max(1.0, float(np.abs(v).max()) ** 2)
    for i in range(n):
        a, b = v[i], v[(i + 1) % n]
        for j in range(i + 1, n):
            c, d = v[j], v[(j + 1) % n]
            if (j - i) % n in (1, n - 1):
                # Adjacent: they share one vertex; a fold-back makes them collinear and opposite.
                shared, p, q = (b, a, d) if j == i + 1 else (a, b, c)
                if abs(_cross(shared, p, q)) <= tol and np.dot(p - shared, q - shared) > 0:
                    return (i, j)
            elif _segments_touch(a, b, c, d, tol):
                return (i, j)
    return None


def _check_simple_polygon(vertices: np.ndarray) -> None:
    n = len(vertices)
    lengths = np.linalg.norm(np.roll(vertices, -1, axis=0) - vertices, axis=1)
    short = np.flatnonzero(lengths < _MIN_EDGE)
    if short.size:
        i = int(short[0])
        raise JeansError(f"edge {i} (vertices {i} and {(i + 1) % n}) has zero length")
    # Crossings first: a bow tie's net area can be zero, and that is not the problem.
    pair = crossing_edges(vertices)
    if pair is not None:
        raise JeansError(f"the garment polygon intersects itself (edges {pair[0]} and {pair[1]})")
    if abs(polygon_area(vertices)) < _MIN_AREA:
        raise JeansError("the garment polygon is too small (under 1 square pixel)")


def _colour(value: object) -> tuple[int, int, int]:
    """``"#rrggbb"`` or ``[r, g, b]`` (0..255) as an ``(r, g, b)`` tuple."""
    if isinstance(value, str):
        if re.fullmatch(r"#[0-9A-Fa-f]{6}", value):
            return tuple(int(value[k : k + 2], 16) for k in (1, 3, 5))  # type: ignore[return-value]
        raise JeansError(f"colour must be '#rrggbb' or [r, g, b], got {value!r}")
    try:
        rgb = [c for c in value]  # type: ignore[union-attr]
    except TypeError:
        raise JeansError(f"colour must be '#rrggbb' or [r, g, b], got {value!r}") from None
    if len(rgb) != 3 or any(
        isinstance(c, bool) or not isinstance(c, (int, np.integer)) or not 0 <= c <= 255 for c in rgb
    ):
        raise JeansError(f"colour must be '#rrggbb' or three integers 0..255, got {value!r}")
    return tuple(int(c) for c in rgb)  # type: ignore[return-value]


def _draw_hints(draw: object) -> dict:
    """The TOML ``[draw]`` table as ``Garment.extra`` (``color`` is accepted for ``colour``)."""
    if not isinstance(draw, dict):
        raise JeansError("[draw] must be a table")
    unknown = sorted(set(draw) - _DRAW_KEYS)
    if unknown:
        raise JeansError(f"unknown [draw] key(s) {', '.join(unknown)} (allowed: style, colour)")
    extra = {}
    if "style" in draw:
        extra["style"] = draw["style"]
    if "colour" in draw or "color" in draw:
        extra["colour"] = draw.get("colour", draw.get("color"))
    return extra


def _toml_module():
    """``tomllib`` (Python 3.11+) or the ``tomli`` backport."""
    try:
        import tomllib

        return tomllib
    except ModuleNotFoundError:
        try:
            import tomli

            return tomli
        except ModuleNotFoundError:
            raise JeansError("reading garment files on Python 3.10 needs the 'tomli' package") from None


def _toml_string(text: str) -> str:
    """A TOML basic string (JSON escapes are valid TOML escapes)."""
    import json

    return json.dumps(text, ensure_ascii=False)


# ---------------------------------------------------------------------- built-ins


def _cut_legs(template: np.ndarray, y: float) -> np.ndarray:
    """The jeans template with its leg-bottom vertices (0, 3, 4, 7) moved up to height
    ``y`` along their own seams: the outer seams are vertical, the inner ones run from
    the crotch, so the shorts are exactly the jeans cut off at ``y``."""
    cut = template.copy()
    for bottom, top in ((0, 1), (3, 2), (4, 5), (7, 6)):
        t = (y - template[top, 1]) / (template[bottom, 1] - template[top, 1])
        cut[bottom] = template[top] + t * (template[bottom] - template[top])
    return cut


JEANS = Garment(
    name="jeans",
    # The paper's prototypical jeans: 0 outer bottom-left, 1 waist left, 2 waist right,
    # 3 outer bottom-right, 4 inner bottom-right, 5 crotch right, 6 crotch left,
    # 7 inner bottom-left.
    template=np.array(
        [
            [86.6217, 202.201],
            [86.6217, 70.2886],
            [159.059, 70.2886],
            [159.059, 202.201],
            [133.897, 202.201],
            [128.559, 105.364],
            [117.884, 105.364],
            [111.784, 202.201],
        ]
    ),
    # Edge i joins vertex i and i+1: 1 is the waistband (1-2), 3 the right leg
    # opening (3-4), 7 the left leg opening (7-0).
    open_edges=(1, 3, 7),
    waist=(1, 2),
    description="The paper's prototypical jeans (8 vertices).",
    extra={"style": "jeans"},
)

SHORTS = Garment(
    name="shorts",
    # The jeans cut off at mid-thigh (y = 150): same vertex roles, crotch unchanged.
    template=_cut_legs(JEANS.template, 150.0),
    open_edges=JEANS.open_edges,
    waist=JEANS.waist,
    description="The jeans cut off at mid-thigh (8 vertices, same topology as the jeans).",
    extra={"style": "shorts"},
)

_JEANS_CENTRE_X = float(JEANS.template[[1, 2], 0].mean())
_SKIRT_HEM_Y, _SKIRT_HEM_HALF = 172.0, 48.0

SKIRT = Garment(
    name="skirt",
    # An A-line trapezoid: 0 hem left, 1 waist left, 2 waist right, 3 hem right. The
    # waistband is the jeans' own; the hem flares a third wider, a knee-length drop.
    template=np.array(
        [
            [_JEANS_CENTRE_X - _SKIRT_HEM_HALF, _SKIRT_HEM_Y],
            JEANS.template[1],
            JEANS.template[2],
            [_JEANS_CENTRE_X + _SKIRT_HEM_HALF, _SKIRT_HEM_Y],
        ]
    ),
    # Edge 1 is the waistband (1-2), edge 3 the hem (3-0); the sides are closed.
    open_edges=(1, 3),
    waist=(1, 2),
    description="An A-line skirt (4 vertices: waistband and hem open).",
    extra={"style": "skirt"},
)

GARMENTS: dict[str, Garment] = {g.name: g for g in (JEANS, SHORTS, SKIRT)}


__all__ = [
    "DRAW_STYLES",
    "GARMENTS",
    "Garment",
    "JEANS",
    "SHORTS",
    "SKIRT",
    "crossing_edges",
    "polygon_area",
]
