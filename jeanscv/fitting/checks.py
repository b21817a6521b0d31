"""The paper's four rules as measurable checks on a fitted garment.

1. duality: waistband centre within 16 px of the canvas centre, and the garment
   covers 15-65% of the silhouette's area;
2. no-stretch: the affine residual ``L_rigid`` <= 0.1 (normalised units);
3. torn-jean avoidance: >= 60% of the open edges' 5-px stroke lies on the body, and
   the polygon does not self-intersect;
4. dress code: >= 90% of the garment's area lies on the body.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from ..geometry import CANVAS_SIZE
from .garments import JEANS, Garment
from .objectives import polygon_coverage, stroke_coverage
from .terms import affine_residual_operator


def _segments_cross(p1: np.ndarray, p2: np.ndarray, q1: np.ndarray, q2: np.ndarray) -> bool:
    def orient(a, b, c):
        return np.sign((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]))

    return orient(p1, p2, q1) * orient(p1, p2, q2) < 0 and orient(q1, q2, p1) * orient(q1, q2, p2) < 0


def self_intersects(vertices: np.ndarray) -> bool:
    """True when two non-adjacent edges of the closed polygon properly cross."""
    v = np.asarray(vertices, dtype=np.float64)
    n = len(v)
    for i in range(n):
        for j in range(i + 1, n):
            if (j - i) % n in (1, n - 1):
                continue
            if _segments_cross(v[i], v[(i + 1) % n], v[j], v[(j + 1) % n]):
                return True
    return False


@dataclass
class RuleReport:
    """Measured quantities of the four rules and whether each check passes."""

    waist_offset_px: float
    covered_fraction: float
    rigid: float
    open_on_body: float
    self_intersects: bool
    on_body_fraction: float

    @property
    def checks(self) -> dict[str, bool]:
        return {
            "waist_centred": self.waist_offset_px <= 16.0,
            "coverage_15_65": 0.15 <= self.covered_fraction <= 0.65,
            "no_stretch": self.rigid <= 0.1,
            "open_edges_on_body": self.open_on_body >= 0.6,
            "no_self_intersection": not self.self_intersects,
            "dress_code": self.on_body_fraction >= 0.9,
        }

    @property
    def passed(self) -> bool:
        return all(self.checks.values())

    def to_json(self) -> dict:
        return {**asdict(self), "checks": self.checks, "passed": self.passed}


def rasterized(vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(fill (256, 256), strokes (N, 256, 256))``: the exact coverage of the closed
    polygon and of its edges' 5-px strokes (:mod:`jeanscv.fitting.objectives`)."""
    v = np.asarray(vertices, dtype=np.float64)
    start, end = v, np.roll(v, -1, axis=0)
    return polygon_coverage(v, CANVAS_SIZE, CANVAS_SIZE), stroke_coverage(start, end, CANVAS_SIZE, CANVAS_SIZE)


def rule_report(vertices: np.ndarray, silhouette, garment: Garment = JEANS) -> RuleReport:
    """Evaluate the four rules for canvas-pixel ``vertices`` ``(N, 2)`` on ``S`` ``(256, 256)``."""
    v = np.asarray(vertices, dtype=np.float64)
    if hasattr(silhouette, "detach"):
        silhouette = silhouette.detach().cpu().numpy()
    s = np.asarray(silhouette, dtype=np.float64)
    fill, strokes = rasterized(v)
    open_union = np.minimum(strokes[list(garment.open_edges)].sum(axis=0), 1.0)
    waist = v[list(garment.waist)].mean(axis=0)
    residual = affine_residual_operator(garment.template) @ (v / CANVAS_SIZE)
    return RuleReport(
        waist_offset_px=float(np.linalg.norm(waist - CANVAS_SIZE / 2)),
        covered_fraction=float((fill * s).sum() / s.sum()),
        rigid=float((residual**2).sum()),
        open_on_body=float((open_union * s).sum() / max(open_union.sum(), 1e-12)),
        self_intersects=self_intersects(vertices),
        on_body_fraction=float((fill * s).sum() / max(fill.sum(), 1e-12)),
    )
