"""The fast path: numba kernels of the jalgorithm's objective and rasterizer (CPU).

The torch code (:mod:`jeanscv.fitting.loss`, :mod:`jeanscv.fitting.render`) is the reference; these
kernels compute the same quantities in float64 with hand-written gradients (see
``raster.py`` and ``objective.py``) and agree with it to rounding (tests/test_fast.py).
Kernels are compiled on first use and cached on disk in the per-user cache
(:mod:`.cache`, never inside the installed package), so a fresh process loads them
instead of compiling.

Which path a fit takes: :func:`jeanscv.device.resolve_backend` (``JEANSCV_BACKEND=torch|fast``,
else fast on CPU when numba imports).
"""

from __future__ import annotations

import functools
import math
import threading
from pathlib import Path

import numpy as np

from ...device import fast_available
from ..terms import STROKE_HALF_WIDTH, TERM_NAMES, affine_residual_operator
from .cache import kernel_cache_dir

#: Segments per round cap of a stroke polygon (render.CAP_SEGMENTS).
CAP_SEGMENTS = 8


def kernels_cached(folder: Path = Path(__file__).parent) -> bool:
    """Whether the cache of the kernels in ``folder`` (:func:`kernel_cache_dir`) holds
    the fit's step loop.

    False on a fresh install, whose first fit compiles the kernels (about half a minute,
    once). Reads file names only, so it costs no import of numba. An index left by an
    older version counts as present.
    """
    return any(kernel_cache_dir(folder).glob("objective.descend-*.nbi"))


@functools.lru_cache(maxsize=8)
def cap_offsets(half_width: float) -> tuple[np.ndarray, np.ndarray]:
    """``(cos_r, sin_r)`` of a capsule's cap points (render.stroke_outlines)."""
    angle = math.pi / CAP_SEGMENTS
    a, b, rhs = CAP_SEGMENTS - 2, 2.0, math.pi / math.sin(angle)
    scale = (-b + math.sqrt(b * b + 4 * a * rhs)) / (2 * a)
    radii = np.array([half_width] + [half_width * scale] * (CAP_SEGMENTS - 1) + [half_width])
    angles = np.linspace(-math.pi / 2, math.pi / 2, CAP_SEGMENTS + 1)
    return np.cos(angles) * radii, np.sin(angles) * radii


class Objective:
    """The weighted jalgorithm objective of one garment, ``inter_pairs`` and weights,
    evaluated with its gradient by the numba kernel (:func:`objective.objective`)."""

    def __init__(self, garment, inter_pairs: str, weights: dict[str, float]) -> None:
        n = garment.num_vertices
        if n > 62:
            from ...errors import JeansError

            raise JeansError("the fast backend handles garments of up to 62 vertices")
        self.weights = np.array([float(weights.get(name, 0.0)) for name in TERM_NAMES])
        self.waist = np.asarray(garment.waist, np.int64)
        self.hems = np.asarray(garment.hems, np.int64)
        self.residual = affine_residual_operator(garment.template)
        self.is_open = np.zeros(n, np.bool_)
        self.is_open[list(garment.open_edges)] = True
        self.is_closed = ~self.is_open
        self.pair = np.zeros((n, n), np.bool_)
        for i, j in garment.edge_pairs(adjacent=inter_pairs == "all"):
            self.pair[min(i, j), max(i, j)] = True
        self._row_sums: dict[int, tuple[np.ndarray, np.ndarray]] = {}

    def row_sums(self, silhouette: np.ndarray) -> np.ndarray:
        """``(C, C + 1)`` prefix sums of ``S`` along rows, kept for the last few targets."""
        key = id(silhouette)
        kept = self._row_sums.get(key)
        if kept is None or kept[0] is not silhouette:
            sums = np.zeros((silhouette.shape[0], silhouette.shape[1] + 1))
            np.cumsum(silhouette, axis=1, out=sums[:, 1:])
            if len(self._row_sums) > 8:
                self._row_sums.clear()
            kept = self._row_sums[key] = (silhouette, sums)
        return kept[1]

    def _target(self, silhouette: np.ndarray, half_width: float):
        """The kernel's :class:`objective.Target`: ``silhouette`` and this objective."""
        from .objective import Target

        cos_r, sin_r = cap_offsets(half_width)
        return Target(
            silhouette,
            self.row_sums(silhouette),
            half_width,
            self.weights,
            self.waist,
            self.hems,
            self.residual,
            self.is_open,
            self.is_closed,
            self.pair,
            cos_r,
            sin_r,
        )

    def __call__(
        self,
        vertices: np.ndarray,
        silhouette: np.ndarray,
        half_width: float = STROKE_HALF_WIDTH,
        need_grad: bool = True,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(totals (B,), grad (B, N, 2), terms (B, 8))`` for canvas-pixel ``vertices``
        ``(B, N, 2)`` on a square float64 ``silhouette``; ``grad`` is d total / d vertices.

        Totals add only the terms of non-zero weight, as loss.weighted_total does.
        """
        from .kernels import objective

        vertices = np.ascontiguousarray(vertices, dtype=np.float64)
        silhouette = np.ascontiguousarray(silhouette, dtype=np.float64)
        totals = np.empty(vertices.shape[0])
        terms = np.empty((vertices.shape[0], len(TERM_NAMES)))
        grad = np.empty(vertices.shape)
        target = self._target(silhouette, float(half_width))
        objective(
            vertices,
            target,
            need_grad,
            totals,
            terms,
            grad,
            scratch(silhouette.shape[0], target.half_width, vertices.shape[1]),
        )
        return totals, grad, terms

    def descend(self, optimizer, target: np.ndarray, steps: int, half_width: float) -> tuple[np.ndarray, np.ndarray]:
        """``steps`` Adam steps of ``optimizer`` (:class:`jeanscv.fitting.adam.BatchAdam`) on
        ``target`` in one kernel call (:func:`objective.descend`): ``(totals (k, B), params
        after each step (k, B, N, 2))``; ``k < steps``: at step ``k`` every start diverged."""
        from .kernels import descend

        target = np.ascontiguousarray(target, dtype=np.float64)
        step_sizes, bias2 = optimizer.corrections(steps)
        batch, n = optimizer.params.shape[:2]
        totals = np.empty((steps, batch))
        path = np.empty((steps, batch, n, 2))
        beta1, beta2 = optimizer.betas
        done = descend(
            optimizer.params,
            optimizer.exp_avg,
            optimizer.exp_avg_sq,
            step_sizes,
            bias2,
            beta1,
            beta2,
            optimizer.eps,
            self._target(target, float(half_width)),
            totals,
            path,
            scratch(target.shape[0], float(half_width), n),
        )
        optimizer.steps += done
        return totals[:done], path[:done]


_scratch: dict = {}


def scratch(size: int, half_width: float, n: int):
    """The kernel's work arrays (:class:`objective.Scratch`) for a ``size`` canvas and
    ``n`` edges, made once per process and shared by every objective (the kernels hold
    the GIL, so no two calls use them at once; each leaves them as the next expects)."""
    from .objective import Scratch, band_scratch_rows

    key = (size, half_width, n)
    if key not in _scratch:
        rows = band_scratch_rows(size, half_width)
        _scratch[key] = Scratch(
            # The per-pixel bit mask of strokes, as narrow as the edges allow: it is
            # read at every stroke pixel, and a quarter of the bytes stays in cache.
            np.zeros(size * size, np.uint8 if n <= 8 else np.uint16 if n <= 16 else np.int64),
            np.zeros((size, size + 2)),
            np.zeros((size, size + 2), np.uint8),
            np.empty((size, size + 2), np.int64),
            np.zeros(size, np.int64),
            np.empty((size, size)),
            np.empty((size, size + 2)),
            np.empty((size, size + 2)),
            np.empty((n, rows, 15)),
            np.empty((n, rows, 13)),
            np.empty(size * size, np.int64),
            np.empty(size * size, np.int64),
            np.empty((size * size, n)),
            np.empty((size * size, 2), np.bool_),
            np.zeros((n, rows), np.bool_),
        )
    return _scratch[key]


def polygon_coverage(
    vertices: np.ndarray, height: int, width: int, top: int = 0, rows: int | None = None, dtype=np.float64
) -> np.ndarray:
    """Exact coverage of the closed polygon ``vertices`` ``(N, 2)`` on rows ``top ..
    top + rows`` of a ``height x width`` grid (render.polygon_coverage)."""
    from .kernels import polygon_coverage_rows

    rows = height - top if rows is None else rows
    out = np.empty((rows, width), dtype)
    polygon_coverage_rows(np.ascontiguousarray(vertices, dtype=np.float64), height, width, top, rows, out)
    return out


def stroke_coverage(
    start: np.ndarray, end: np.ndarray, height: int = 256, width: int = 256, half_width: float = STROKE_HALF_WIDTH
) -> np.ndarray:
    """``(M, height, width)`` stroke alphas of segments ``(M, 2)`` (render.stroke_coverage)."""
    from .kernels import stroke_maps

    start = np.ascontiguousarray(start, dtype=np.float64).reshape(-1, 2)
    end = np.ascontiguousarray(end, dtype=np.float64).reshape(-1, 2)
    out = np.zeros((len(start), height, width))
    cos_r, sin_r = cap_offsets(float(half_width))
    stroke_maps(start, end, height, width, float(half_width), cos_r, sin_r, out)
    return out


_warming: threading.Thread | None = None


def warm_up() -> None:
    """Load numba and the cached kernels in a background thread (and, before they are
    cached, start :mod:`ahead`'s second compiling process).

    The first call of any numba function in a process sets up LLVM (about half a
    second, as long again as importing numba); started before decoding and
    segmenting a photo, that happens while they run (OpenCV releases the GIL) instead
    of before the fit. Later calls of the kernels wait for it where they need it.
    """
    global _warming
    if _warming is not None or not fast_available():
        return
    if not kernels_cached():  # a first run: a second core compiles what this one reaches last
        from . import ahead

        ahead.start()

    _warming = threading.Thread(target=load_kernels, name="jeanscv-warm-up", daemon=True)
    _warming.start()


def warming() -> bool:
    """Whether :func:`warm_up`'s thread is still loading (or compiling) the kernels."""
    return _warming is not None and _warming.is_alive()


def load_kernels() -> None:
    """Load (or, with an empty cache, compile) every kernel a photo's run calls: the
    objective, the fit's step loop and the compositing's rasterizers, on tiny inputs."""
    from ..adam import BatchAdam
    from ..garments import JEANS

    square = JEANS.template / 16.0
    kernel = Objective(JEANS, "all", {"coverage": 1.0})
    kernel(square[None], np.ones((16, 16)), 0.25)
    kernel.descend(BatchAdam(square[None] / 16.0, 0.01), np.ones((16, 16)), 1, 0.25)
    load_rasterizers()


def load_rasterizers() -> None:
    """Load (or compile) the rasterizers that compositing calls, on a tiny input."""
    from ..garments import JEANS

    square = JEANS.template / 16.0
    polygon_coverage(square, 16, 16)
    stroke_coverage(square[:1], square[1:2], 16, 16)
