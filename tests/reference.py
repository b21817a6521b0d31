"""Independent numpy references for the rasterizer and the jalgorithm's loss terms.

Nothing here imports jeanscv: coverage is estimated by point sampling (``n x n``
sample points per pixel at ``(c + (i + 0.5)/n, r + (j + 0.5)/n)``), the fill by the
non-zero winding rule evaluated on every sample point, a stroke by the distance from
each sample point to its segment, and the seven terms are written straight from the
paper's equations (Pagurek, SIGBOVIK 2023, eqs. 2-10).

Convention (as in jeanscv): x right, y down, pixel ``(c, r)`` covers
``[c, c+1) x [r, r+1)``. Maps are ``(height, width)`` float64.
"""

from __future__ import annotations

from itertools import combinations

import numpy as np

#: Rows of pixels handled per chunk, to bound the memory of the sample arrays.
_CHUNK_SAMPLES = 1 << 21


def sample_grid(x0: int, y0: int, width: int, height: int, samples: int) -> tuple[np.ndarray, np.ndarray]:
    """Sample points of the pixel block ``[x0, x0+width) x [y0, y0+height)``.

    Returns ``(x, y)``, each ``(height * samples, width * samples)`` float64, laid out
    so that ``a.reshape(height, samples, width, samples).mean(axis=(1, 3))`` averages
    the samples of each pixel.
    """
    offsets = (np.arange(samples) + 0.5) / samples
    xs = (x0 + np.arange(width)[:, None] + offsets[None, :]).reshape(-1)
    ys = (y0 + np.arange(height)[:, None] + offsets[None, :]).reshape(-1)
    return np.meshgrid(xs, ys)


def pixel_mean(samples_map: np.ndarray, samples: int) -> np.ndarray:
    """Average a ``(h*n, w*n)`` sample map to ``(h, w)`` pixels."""
    h, w = samples_map.shape[0] // samples, samples_map.shape[1] // samples
    return samples_map.reshape(h, samples, w, samples).mean(axis=(1, 3))


def winding_numbers(x: np.ndarray, y: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    """Winding number of the closed polygon ``vertices`` ``(N, 2)`` around each point.

    Sunday's crossing rule: an edge crossing the point's horizontal ray upwards with
    the point on its left counts +1, downwards with the point on its right -1.
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    wn = np.zeros(x.shape, np.int32)
    for (ax, ay), (bx, by) in zip(vertices, np.roll(vertices, -1, axis=0)):
        side = (bx - ax) * (y - ay) - (x - ax) * (by - ay)
        wn += ((ay <= y) & (by > y) & (side > 0)).astype(np.int32)
        wn -= ((ay > y) & (by <= y) & (side < 0)).astype(np.int32)
    return wn


def segment_distance(x: np.ndarray, y: np.ndarray, start, end) -> np.ndarray:
    """Euclidean distance from each point to the closed segment ``start``-``end``."""
    (ax, ay), (bx, by) = np.asarray(start, np.float64), np.asarray(end, np.float64)
    dx, dy = bx - ax, by - ay
    length2 = dx * dx + dy * dy
    if length2 == 0.0:
        t = np.zeros_like(x)
    else:
        t = np.clip(((x - ax) * dx + (y - ay) * dy) / length2, 0.0, 1.0)
    return np.hypot(x - (ax + t * dx), y - (ay + t * dy))


def _clipped_box(low: np.ndarray, high: np.ndarray, height: int, width: int) -> tuple[int, int, int, int] | None:
    """Integer pixel box ``(x0, y0, x1, y1)`` covering ``[low, high]``, inside the canvas."""
    x0, y0 = (int(max(np.floor(v), 0)) for v in low)
    x1 = int(min(np.ceil(high[0]) + 1, width))
    y1 = int(min(np.ceil(high[1]) + 1, height))
    if x1 <= x0 or y1 <= y0:
        return None
    return x0, y0, x1, y1


def _coverage_in_box(inside_fn, low, high, height: int, width: int, samples: int) -> np.ndarray:
    """Pixel coverage of a point set given by ``inside_fn(x, y) -> bool``, 0 off its box."""
    out = np.zeros((height, width))
    box = _clipped_box(np.asarray(low, np.float64), np.asarray(high, np.float64), height, width)
    if box is None:
        return out
    x0, y0, x1, y1 = box
    rows_per_chunk = max(1, _CHUNK_SAMPLES // ((x1 - x0) * samples * samples))
    for r0 in range(y0, y1, rows_per_chunk):
        r1 = min(r0 + rows_per_chunk, y1)
        x, y = sample_grid(x0, r0, x1 - x0, r1 - r0, samples)
        out[r0:r1, x0:x1] = pixel_mean(inside_fn(x, y).astype(np.float64), samples)
    return out


def polygon_coverage_ref(vertices: np.ndarray, height: int, width: int, samples: int = 16) -> np.ndarray:
    """Point-sampled non-zero-winding fill coverage ``(height, width)`` of a polygon ``(N, 2)``."""
    vertices = np.asarray(vertices, dtype=np.float64)
    return _coverage_in_box(
        lambda x, y: winding_numbers(x, y, vertices) != 0,
        vertices.min(axis=0),
        vertices.max(axis=0),
        height,
        width,
        samples,
    )


def capsule_coverage_ref(start, end, height: int, width: int, half_width: float = 2.5, samples: int = 16) -> np.ndarray:
    """Point-sampled coverage of ``{p : dist(p, segment) <= half_width}``."""
    start, end = np.asarray(start, np.float64), np.asarray(end, np.float64)
    return _coverage_in_box(
        lambda x, y: segment_distance(x, y, start, end) <= half_width,
        np.minimum(start, end) - half_width,
        np.maximum(start, end) + half_width,
        height,
        width,
        samples,
    )


def rigid_ref(vertices: np.ndarray, template: np.ndarray, scale: float = 256.0) -> float:
    """``||X - T Xbar||^2`` in normalised coordinates, ``T`` from a least-squares solve."""
    x = np.asarray(vertices, np.float64) / scale
    design = np.hstack([np.asarray(template, np.float64) / scale, np.ones((len(template), 1))])
    coefficients, *_ = np.linalg.lstsq(design, x, rcond=None)
    return float(((x - design @ coefficients) ** 2).sum())


def loss_terms_ref(
    vertices: np.ndarray,
    silhouette: np.ndarray,
    template: np.ndarray,
    open_edges: tuple[int, ...],
    waist: tuple[int, int],
    inter_pairs: str = "all",
    half_width: float = 2.5,
    samples: int = 8,
) -> dict[str, float]:
    """The seven unweighted terms for one candidate, from the paper's equations.

    ``J`` and each ``R(e)`` are ``samples x samples`` point-sampled coverages on the
    canvas; the union ``R(E)`` of a set of strokes is the per-sample logical or.
    ``vertices``: ``(N, 2)`` canvas pixels; ``silhouette``: ``(H, W)`` alpha in [0, 1].
    """
    vertices = np.asarray(vertices, np.float64)
    s = np.asarray(silhouette, np.float64)
    height, width = s.shape
    scale = float(width)
    n = len(vertices)
    edges = [(i, (i + 1) % n) for i in range(n)]
    closed_edges = tuple(i for i in range(n) if i not in open_edges)

    # One window holds the polygon and every stroke, so unions are pointwise ors.
    box = _clipped_box(vertices.min(axis=0) - half_width - 1, vertices.max(axis=0) + half_width + 1, height, width)
    j = np.zeros((height, width))
    strokes = np.zeros((n, height, width))
    union_open = np.zeros((height, width))
    union_closed = np.zeros((height, width))
    if box is not None:
        x0, y0, x1, y1 = box
        x, y = sample_grid(x0, y0, x1 - x0, y1 - y0, samples)
        j[y0:y1, x0:x1] = pixel_mean((winding_numbers(x, y, vertices) != 0).astype(float), samples)
        hits = [segment_distance(x, y, vertices[a], vertices[b]) <= half_width for a, b in edges]
        for i, hit in enumerate(hits):
            strokes[i, y0:y1, x0:x1] = pixel_mean(hit.astype(float), samples)
        union_open[y0:y1, x0:x1] = pixel_mean(
            np.logical_or.reduce([hits[i] for i in open_edges]).astype(float), samples
        )
        union_closed[y0:y1, x0:x1] = pixel_mean(
            np.logical_or.reduce([hits[i] for i in closed_edges]).astype(float), samples
        )

    def ratio(numerator: float, denominator: float) -> float:
        # Nothing drawn on the canvas (0 / 0) counts as 0, as a limit of tiny shapes would.
        return float(numerator / denominator) if denominator > 0 else 0.0

    waist_mid = vertices[list(waist)].mean(axis=0) / scale
    center = float(((waist_mid - 0.5) ** 2).sum())
    coverage = float((0.5 - np.maximum(s - j, 0).sum() / s.sum()) ** 2)
    rigid = rigid_ref(vertices, template, scale)
    open_term = -ratio((union_open * s).sum(), union_open.sum())
    closed_term = ratio((union_closed * s).sum(), union_closed.sum())
    inter = 0.0
    for a, b in combinations(range(n), 2):
        if inter_pairs == "non_adjacent" and (b - a) % n in (1, n - 1):
            continue
        inter += ratio((strokes[a] * strokes[b]).sum(), np.minimum(strokes[a] + strokes[b], 1.0).sum())
    inside = ratio(np.maximum(j - s, 0).sum(), j.sum())
    return {
        "center": center,
        "coverage": coverage,
        "rigid": rigid,
        "open": open_term,
        "closed": closed_term,
        "inter": inter,
        "inside": inside,
    }
