"""SVG path data (``d``, every SVG 1.1 command, elliptical arcs included) to cubic
Bezier segments, and their adaptive flattening to polylines (chord error at most
:data:`FLATTEN_TOLERANCE`). Part of :mod:`jeanscv.io.svg`, which reads whole documents.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterator

import numpy as np

from jeanscv.errors import JeansError

FLATTEN_TOLERANCE = 0.05
"""Largest distance, in canvas px, between a curve and its flattened polyline."""

MAX_SEGMENTS = 2_000_000
"""Most line segments (after flattening, over all shapes) a silhouette may have."""

_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_NUMBER_RE = re.compile(_NUMBER)
_PATH_SCAN_RE = re.compile(r"[\s,]*([MmZzLlHhVvCcSsQqTtAa]|" + _NUMBER + r"|[^\s,])")
_SEPARATORS_ONLY_RE = re.compile(r"[\s,]*")
_COMMANDS = frozenset("MmZzLlHhVvCcSsQqTtAa")
_CUT_RE = re.compile(r"[\s,MmZzLlHhVvCcSsQqTtAa]")
_ARITY = {"M": 2, "L": 2, "H": 1, "V": 1, "C": 6, "S": 4, "Q": 4, "T": 2, "A": 7}


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


class _Reflected:
    """The control points a following S/s or T/t reflects: the last C or S's second
    (``cubic``) and the last Q or T's (``quad``); None after any other command."""

    __slots__ = ("cubic", "quad")

    def __init__(self) -> None:
        self.cubic: tuple[float, float] | None = None
        self.quad: tuple[float, float] | None = None


def _arc_arguments(tokens: list[str], i: int, cmd: str) -> tuple[list, int]:
    """An arc's 7 parameters from ``tokens[i]`` (its flags may be glued to what follows
    them) and the index of the next token."""
    try:
        rx, ry, rot = float(tokens[i]), float(tokens[i + 1]), float(tokens[i + 2])
        large, i = _take_flag(tokens, i + 3)
        sweep, i = _take_flag(tokens, i)
        x, y = float(tokens[i]), float(tokens[i + 1])
        i += 2
    except (ValueError, IndexError):
        raise JeansError(f"malformed path data: expected 7 arc parameters after {cmd!r}") from None
    return [rx, ry, rot, large, sweep, x, y], i


def _numbers(tokens: list[str], k: int, cmd: str) -> list[float]:
    """The ``k`` numbers of one argument group of ``cmd`` (``tokens``: the next ``k``)."""
    try:
        v = [float(t) for t in tokens]
    except ValueError:
        bad = _bad_token(tokens)
        if bad:
            raise JeansError(f"malformed path data: unexpected {bad[:20]!r}") from None
        v = []
    if len(v) != k:
        raise JeansError(f"malformed path data: expected {k} numbers after {cmd!r}")
    return v


def _draw(b: _PathBuilder, cmd: str, v: list, last: _Reflected) -> str:
    """Draw one argument group ``v`` of ``cmd`` (any command but Z) from ``b``'s current
    point, updating ``last``. Returns the command that further groups repeat (after a
    moveto, a lineto)."""
    upper, rel = cmd.upper(), cmd.islower()
    x0, y0 = b.x, b.y
    cubic = quad = None
    if upper == "A":
        x, y = v[5], v[6]
        if rel:
            x, y = x + x0, y + y0
        b.arc_to(v[0], v[1], v[2], v[3], v[4], x, y)
    elif upper == "H":
        b.line_to(v[0] + x0 if rel else v[0], y0)
    elif upper == "V":
        b.line_to(x0, v[0] + y0 if rel else v[0])
    else:
        if rel:
            v = [value + (x0 if j % 2 == 0 else y0) for j, value in enumerate(v)]
        if upper == "M":
            b.move_to(v[0], v[1])
            cmd = "l" if rel else "L"  # further pairs are implicit linetos
        elif upper == "L":
            b.line_to(v[0], v[1])
        elif upper == "C":
            b.cubic_to(*v)
            cubic = (v[2], v[3])
        elif upper == "S":
            c1 = (2 * x0 - last.cubic[0], 2 * y0 - last.cubic[1]) if last.cubic else (x0, y0)
            b.cubic_to(c1[0], c1[1], *v)
            cubic = (v[0], v[1])
        elif upper == "Q":
            b.quad_to(*v)
            quad = (v[0], v[1])
        else:  # T
            quad = (2 * x0 - last.quad[0], 2 * y0 - last.quad[1]) if last.quad else (x0, y0)
            b.quad_to(quad[0], quad[1], v[0], v[1])
    last.cubic, last.quad = cubic, quad
    return cmd


def _parse_path_data(d: str, b: _PathBuilder, piece_size: int = 1 << 18) -> None:
    """Parse SVG path data into ``b``; raise :class:`JeansError` on any error."""
    cmd = ""
    last = _Reflected()
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
                    last.cubic = last.quad = None
                    cmd = ""
                    continue
                awaiting = True
            elif not cmd:
                raise JeansError(f"malformed path data: {tok!r} where a command was expected")
            if not is_last and n - i < 7:  # maybe cut: finish it with the next piece
                pending = tokens[i:]
                break
            awaiting = False
            if cmd in "Aa":
                v, i = _arc_arguments(tokens, i, cmd)
            else:
                k = _ARITY[cmd.upper()]
                v = _numbers(tokens[i : i + k], k, cmd)
                i += k
            cmd = _draw(b, cmd, v, last)
    if awaiting:
        raise JeansError(f"malformed path data: {cmd!r} has no arguments")


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
