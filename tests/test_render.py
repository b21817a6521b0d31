"""Accuracy and gradient tests of jeanscv.fitting.render against independent references.

The references (tests/reference.py) point-sample each pixel 16x16 times: the fill by
the non-zero winding rule, a stroke by the distance to its segment. The renderer
computes exact box-filtered areas, so it must match the references up to their
sampling error on partially covered pixels and exactly (to float rounding) on pixels
away from any edge; tiny hand-made shapes have exact expected coverages.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from conftest import float64_tensor as _t
from reference import capsule_coverage_ref, polygon_coverage_ref

from jeanscv.fitting.render import (
    PolygonRasterizer,
    polygon_coverage,
    rasterize,
    stroke_bands,
    stroke_coverage,
    winding_integral,
)

# A non-square canvas, so that a swapped height/width shows up.
H, W = 44, 56
F64 = torch.float64


def _off_grid(points: np.ndarray, gap: float = 1e-3) -> np.ndarray:
    """Move coordinates within ``gap`` of an integer line away from it (gradcheck's kinks)."""
    frac = points - np.round(points)
    return np.where(np.abs(frac) < gap, points + 3 * gap * np.where(frac < 0, -1, 1), points)


def _shoelace(vertices: np.ndarray) -> float:
    x, y = vertices[:, 0], vertices[:, 1]
    return 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y)))


def _assert_matches_reference(got: np.ndarray, ref: np.ndarray) -> None:
    """Area within 0.5%, MAE <= 0.05 on partial pixels, solid pixels exact."""
    assert got.shape == ref.shape
    assert got.sum() == pytest.approx(ref.sum(), rel=5e-3, abs=0.05)
    partial = (ref > 0) & (ref < 1)
    if partial.any():
        assert np.abs(got - ref)[partial].mean() <= 0.05
    # Pixels next to a partial one may hold an edge that no sample point saw.
    padded = np.pad(partial, 1)
    near_edge = np.zeros_like(partial)
    for dy in (0, 1, 2):
        for dx in (0, 1, 2):
            near_edge |= padded[dy : dy + ref.shape[0], dx : dx + ref.shape[1]]
    solid = ~near_edge
    assert np.abs(got - ref)[solid].max(initial=0.0) <= 1e-6


# ---------------------------------------------------------------- random polygons


def _random_polygon(kind: str, rng: np.random.Generator) -> np.ndarray:
    centre = np.array([W / 2, H / 2]) + rng.uniform(-4, 4, 2)
    if kind == "convex":  # points on an ellipse, in angular order
        angles = np.sort(rng.uniform(0, 2 * np.pi, rng.integers(3, 10)))
        axes = rng.uniform([8, 8], [W / 2 - 6, H / 2 - 6])
        return centre + np.stack([axes[0] * np.cos(angles), axes[1] * np.sin(angles)], 1)
    if kind == "concave":  # star-shaped with random radii
        count = rng.integers(6, 14)
        angles = np.sort(rng.uniform(0, 2 * np.pi, count))
        radii = rng.uniform(4, H / 2 - 6, count)
        return centre + radii[:, None] * np.stack([np.cos(angles), np.sin(angles)], 1)
    if kind == "self_intersecting":  # random points in random order
        return rng.uniform([2, 2], [W - 2, H - 2], (rng.integers(4, 9), 2))
    if kind == "pentagram":  # winding number 2 in the middle
        angles = rng.uniform(0, 2 * np.pi) + 4 * np.pi * np.arange(5) / 5
        return centre + rng.uniform(12, H / 2 - 6) * np.stack([np.cos(angles), np.sin(angles)], 1)
    if kind == "partly_outside":
        return rng.uniform([-25, -25], [W + 25, H + 25], (rng.integers(3, 8), 2))
    raise AssertionError(kind)


POLYGON_CASES = [
    (kind, seed)
    for kind in ("convex", "concave", "self_intersecting", "pentagram", "partly_outside")
    for seed in range(4)
]


@pytest.mark.parametrize("kind,seed", POLYGON_CASES)
def test_polygon_coverage_matches_point_sampled_reference(kind: str, seed: int) -> None:
    vertices = _random_polygon(kind, np.random.default_rng(1000 * seed + len(kind)))
    got = polygon_coverage(_t(vertices), H, W).numpy()
    _assert_matches_reference(got, polygon_coverage_ref(vertices, H, W))


@pytest.mark.parametrize("kind", ["convex", "concave"])
def test_simple_polygon_area_equals_shoelace(kind: str) -> None:
    vertices = _random_polygon(kind, np.random.default_rng(7))
    assert polygon_coverage(_t(vertices), H, W).sum().item() == pytest.approx(_shoelace(vertices), abs=1e-9)


def test_orientation_and_start_vertex_do_not_matter() -> None:
    vertices = _t(_random_polygon("concave", np.random.default_rng(3)))
    base = polygon_coverage(vertices, H, W)
    torch.testing.assert_close(polygon_coverage(vertices.flip(0), H, W), base, atol=1e-12, rtol=0)
    torch.testing.assert_close(polygon_coverage(vertices.roll(3, 0), H, W), base, atol=1e-12, rtol=0)


def test_batched_vertices_render_each_polygon() -> None:
    rng = np.random.default_rng(11)
    polys = np.stack([_random_polygon("convex", rng)[:3] for _ in range(6)]).reshape(2, 3, 3, 2)
    batch = polygon_coverage(_t(polys), H, W)
    assert batch.shape == (2, 3, H, W)
    for i in range(2):
        for j in range(3):
            torch.testing.assert_close(batch[i, j], polygon_coverage(_t(polys[i, j]), H, W), atol=1e-12, rtol=0)
    torch.testing.assert_close(PolygonRasterizer(H, W)(_t(polys)), batch, atol=0, rtol=0)


# ---------------------------------------------------------------- exact small cases


def test_pixel_aligned_square_is_exactly_zero_or_one() -> None:
    square = _t([[3, 2], [9, 2], [9, 8], [3, 8]])
    expected = torch.zeros(12, 12, dtype=F64)
    expected[2:8, 3:9] = 1.0
    torch.testing.assert_close(polygon_coverage(square, 12, 12), expected, atol=1e-12, rtol=0)


def test_half_pixel_offset_square_gives_halves_and_quarters() -> None:
    square = _t([[2.5, 1.5], [8.5, 1.5], [8.5, 7.5], [2.5, 7.5]])
    expected = np.zeros((12, 12))
    expected[1:8, 2:9] = 0.5  # edge pixels
    expected[2:7, 3:8] = 1.0  # interior
    for row, col in ((1, 2), (1, 8), (7, 2), (7, 8)):
        expected[row, col] = 0.25
    got = polygon_coverage(square, 12, 12).numpy()
    np.testing.assert_allclose(got, expected, atol=1e-12, rtol=0)


def test_triangle_area_equals_shoelace() -> None:
    triangle = np.array([[1.3, 2.7], [10.2, 4.1], [4.4, 11.3]])
    got = polygon_coverage(_t(triangle), 12, 12).sum().item()
    assert got == pytest.approx(_shoelace(triangle), abs=1e-4)
    assert _shoelace(triangle) == pytest.approx(36.1, abs=1e-12)


def test_winding_integral_signs_and_multiplicity() -> None:
    square = _t([[3, 2], [9, 2], [9, 8], [3, 8]])
    start, end = square, square.roll(-1, 0)
    forward = winding_integral(start, end, 12, 12)
    backward = winding_integral(end, start, 12, 12)
    # Clockwise on screen (y down) is a positive winding here; reversing flips the sign.
    assert forward.sum().item() == pytest.approx(-backward.sum().item(), abs=1e-12)
    assert abs(forward.sum().item()) == pytest.approx(36.0, abs=1e-12)
    # Two loops traced in the same direction add up: winding 2, coverage still 1.
    doubled = winding_integral(torch.cat([start, start]), torch.cat([end, end]), 12, 12)
    torch.testing.assert_close(doubled, 2 * forward, atol=1e-12, rtol=0)
    assert set(np.unique(np.round(np.abs(doubled.numpy()), 9))) == {0.0, 2.0}
    doubled_poly = polygon_coverage(torch.cat([square, square]), 12, 12)
    torch.testing.assert_close(doubled_poly, polygon_coverage(square, 12, 12), atol=1e-12, rtol=0)


@pytest.mark.xfail(
    reason="known limitation: min(|integral of W|, 1) cancels +1 and -1 lobes inside a pixel where "
    "a self-intersecting polygon's edges cross (documented in jeanscv/fitting/render.py)",
    strict=True,
)
def test_bowtie_crossing_pixel_gets_both_lobes() -> None:
    """The non-zero rule covers both lobes; the pixel integral of W cancels them.

    The bowtie's diagonals cross at (6.5, 6.5), the centre of pixel (6, 6). The left
    lobe (winding +1) and the right lobe (winding -1) each cover 0.25 of that pixel,
    so its non-zero coverage is 0.5 and the polygon's area is 2 * 16 = 32.
    """
    bowtie = _t([[2.5, 2.5], [10.5, 10.5], [10.5, 2.5], [2.5, 10.5]])
    coverage = polygon_coverage(bowtie, 13, 13)
    reference = polygon_coverage_ref(bowtie.numpy(), 13, 13)
    assert reference[6, 6] == pytest.approx(0.5, abs=0.02)
    assert coverage[6, 6].item() == pytest.approx(0.5, abs=1e-6)
    assert coverage.sum().item() == pytest.approx(32.0, abs=1e-6)


def test_huge_triangle_covers_whole_canvas_float64() -> None:
    triangle = _t([[-1e6, -1e6], [1e6, -1e6], [0, 1e6]])
    coverage = polygon_coverage(triangle, 12, 12)
    torch.testing.assert_close(coverage, torch.ones(12, 12, dtype=F64), atol=1e-6, rtol=0)


# ---------------------------------------------------------------- strokes


def _random_segment(kind: str, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    start = rng.uniform([6, 6], [W - 6, H - 6])
    angle = rng.uniform(0, 2 * np.pi)
    direction = np.array([np.cos(angle), np.sin(angle)])
    if kind == "any_angle":
        return start, start + rng.uniform(1, 25) * direction
    if kind == "short":
        return start, start + rng.uniform(0.01, 1.5) * direction
    if kind == "zero_length":
        return start, start.copy()
    if kind == "axis_aligned":
        step = rng.uniform(3, 20) * np.eye(2)[rng.integers(2)] * rng.choice([-1, 1])
        return start, start + step
    if kind == "diagonal":
        return start, start + rng.uniform(3, 20) * np.array([1.0, rng.choice([-1.0, 1.0])])
    if kind == "partly_outside":
        start = rng.uniform([-4, -4], [W + 4, H + 4])
        return start, start + rng.uniform(20, 60) * direction
    if kind == "crossing_canvas":
        middle = np.array([W / 2, H / 2]) + rng.uniform(-10, 10, 2)
        return middle - 200 * direction, middle + 300 * direction
    raise AssertionError(kind)


SEGMENT_CASES = [
    (kind, seed)
    for kind in ("any_angle", "short", "zero_length", "axis_aligned", "diagonal", "partly_outside", "crossing_canvas")
    for seed in range(3)
]


@pytest.mark.parametrize("kind,seed", SEGMENT_CASES)
def test_stroke_coverage_matches_capsule_reference(kind: str, seed: int) -> None:
    start, end = _random_segment(kind, np.random.default_rng(100 * seed + len(kind)))
    got = stroke_coverage(_t(start), _t(end), H, W).numpy()
    _assert_matches_reference(got, capsule_coverage_ref(start, end, H, W))


def test_horizontal_stroke_area() -> None:
    stroke = stroke_coverage(_t([10.5, 20.5]), _t([30.5, 20.5]), 40, 40)
    assert stroke.sum().item() == pytest.approx(5 * 20 + math.pi * 2.5**2, rel=1e-3)


@pytest.mark.parametrize("half_width", [1.0, 2.5, 4.0])
def test_stroke_area_is_capsule_area_for_any_angle(half_width: float) -> None:
    rng = np.random.default_rng(5)
    starts = rng.uniform(12, 28, (6, 2))
    ends = starts + rng.uniform(-8, 8, (6, 2))
    maps = stroke_coverage(_t(starts), _t(ends), 40, 40, half_width=half_width)
    lengths = np.linalg.norm(ends - starts, axis=1)
    expected = 2 * half_width * lengths + math.pi * half_width**2
    np.testing.assert_allclose(maps.sum(dim=(-2, -1)).numpy(), expected, rtol=1e-3)


def test_stroke_bands_hold_the_whole_stroke() -> None:
    rng = np.random.default_rng(9)
    starts = rng.uniform(-3, [W + 3, H + 3], (8, 2))
    ends = starts + rng.normal(0, 12, (8, 2))
    bands = stroke_bands(_t(starts), _t(ends), H, W)
    maps = stroke_coverage(_t(starts), _t(ends), H, W)
    for i in range(8):
        inside = bands.inside[i]
        # Every band cell is one canvas pixel, each at most once, and together they
        # carry all of the stroke's coverage.
        flat = bands.flat_index(W)[i][inside]
        assert len(torch.unique(flat)) == len(flat)
        assert torch.all(bands.alpha[i][~inside] == 0)
        ref_map = capsule_coverage_ref(starts[i], ends[i], H, W)
        assert bands.alpha[i].sum().item() == pytest.approx(ref_map.sum(), rel=5e-3, abs=0.05)
        torch.testing.assert_close(maps[i].reshape(-1)[flat], bands.alpha[i][inside], atol=1e-12, rtol=0)


def test_rasterize_fill_and_strokes_in_one_pass() -> None:
    rng = np.random.default_rng(21)
    polys = _t(np.stack([_random_polygon("concave", rng)[:6] for _ in range(2)]))
    starts, ends = _t(rng.uniform(0, 40, (5, 2))), _t(rng.uniform(0, 40, (5, 2)))
    edges = (polys, polys.roll(-1, 1))
    winding, bands = rasterize(fill_edges=edges, fill_size=(H, W), strokes=(starts, ends), canvas_size=(H, W))
    torch.testing.assert_close(winding, winding_integral(*edges, H, W), atol=1e-12, rtol=0)
    alone = stroke_bands(starts, ends, H, W)
    torch.testing.assert_close(bands.alpha, alone.alpha, atol=1e-12, rtol=0)
    assert torch.equal(bands.x, alone.x) and torch.equal(bands.y, alone.y)
    assert rasterize() == (None, None)


# ---------------------------------------------------------------- gradients


@pytest.mark.parametrize("size", [(12, 12), (16, 10)])
def test_polygon_coverage_gradcheck(size: tuple[int, int]) -> None:
    height, width = size
    rng = np.random.default_rng(height)
    vertices = _off_grid(rng.uniform([1, 1], [width - 1, height - 1], (5, 2)))
    x = _t(vertices).requires_grad_(True)
    assert torch.autograd.gradcheck(lambda v: polygon_coverage(v, height, width), (x,))


@pytest.mark.parametrize("size", [(12, 12), (16, 10)])
def test_stroke_coverage_gradcheck(size: tuple[int, int]) -> None:
    height, width = size
    rng = np.random.default_rng(height + 1)
    ends = _off_grid(rng.uniform([0, 0], [width, height], (2, 2, 2)))
    x = _t(ends).requires_grad_(True)
    assert torch.autograd.gradcheck(lambda e: stroke_coverage(e[:, 0], e[:, 1], height, width), (x,))


def test_area_gradient_equals_shoelace_gradient() -> None:
    vertices = _random_polygon("concave", np.random.default_rng(4))
    x = _t(vertices).requires_grad_(True)
    polygon_coverage(x, H, W).sum().backward()
    # d|A|/dx_i = s/2 (y_{i+1} - y_{i-1}), d|A|/dy_i = s/2 (x_{i-1} - x_{i+1}).
    xs, ys = vertices[:, 0], vertices[:, 1]
    signed = 0.5 * float(np.dot(xs, np.roll(ys, -1)) - np.dot(np.roll(xs, -1), ys))
    sign = np.sign(signed)
    expected = 0.5 * sign * np.stack([np.roll(ys, -1) - np.roll(ys, 1), np.roll(xs, 1) - np.roll(xs, -1)], 1)
    np.testing.assert_allclose(x.grad.numpy(), expected, atol=1e-9)


def test_stroke_area_gradient_equals_capsule_gradient() -> None:
    start, end = np.array([12.3, 17.8]), np.array([29.6, 24.1])
    s, e = _t(start).requires_grad_(True), _t(end).requires_grad_(True)
    stroke_coverage(s, e, 40, 40).sum().backward()
    # Area 5 L + pi r^2: dA/d(start) = 5 (start - end) / L.
    unit = (start - end) / np.linalg.norm(start - end)
    np.testing.assert_allclose(s.grad.numpy(), 5 * unit, atol=1e-9)
    np.testing.assert_allclose(e.grad.numpy(), -5 * unit, atol=1e-9)


def test_single_pixel_gradient_is_nonzero_and_matches_finite_difference() -> None:
    # Vertex 1 sits inside pixel (5, 4); its two edges cross several pixels.
    vertices = np.array([[1.3, 1.7], [5.4, 4.6], [10.2, 9.3], [2.1, 10.8]])
    x = _t(vertices).requires_grad_(True)
    polygon_coverage(x, 12, 12)[4, 5].backward()
    grad = x.grad[1].numpy()
    assert np.abs(grad).min() > 0.05
    step = 1e-4
    for axis in range(2):
        plus, minus = vertices.copy(), vertices.copy()
        plus[1, axis] += step
        minus[1, axis] -= step
        diff = (polygon_coverage(_t(plus), 12, 12)[4, 5] - polygon_coverage(_t(minus), 12, 12)[4, 5]).item()
        assert grad[axis] == pytest.approx(diff / (2 * step), rel=1e-6)


DEGENERATE = {
    "one_point": np.full((5, 2), 6.3),
    "zero_length_edges": np.array([[2.2, 2.2], [2.2, 2.2], [9.7, 3.1], [9.7, 3.1], [5.5, 9.9]]),
    "far_positive": np.array([[1e6, 1e6], [1e6 + 1, 1e6], [1e6, 1e6 + 1]]),
    "far_negative": np.array([[-1e6, -1e6], [-1e6 + 1, -1e6], [-1e6, -1e6 + 1]]),
    "spanning": np.array([[-1e6, 5.5], [1e6, 6.5], [6.0, 1e6]]),
    "on_grid": np.array([[2.0, 2.0], [8.0, 2.0], [8.0, 8.0], [2.0, 8.0]]),
}


@pytest.mark.parametrize("dtype", [torch.float32, F64])
@pytest.mark.parametrize("name", sorted(DEGENERATE))
def test_degenerate_inputs_give_finite_values_and_gradients(name: str, dtype: torch.dtype) -> None:
    vertices = torch.as_tensor(DEGENERATE[name], dtype=dtype).requires_grad_(True)
    weight = torch.rand(12, 12, generator=torch.Generator().manual_seed(0), dtype=dtype)
    fill = polygon_coverage(vertices, 12, 12)
    strokes = stroke_coverage(vertices, vertices.roll(-1, 0), 12, 12)
    assert torch.isfinite(fill).all() and torch.isfinite(strokes).all()
    assert fill.min() >= 0 and fill.max() <= 1 + 1e-6
    ((fill + strokes.sum(0)) * weight).sum().backward()
    assert torch.isfinite(vertices.grad).all()
    if name in ("one_point", "far_positive", "far_negative"):
        assert fill.abs().max().item() == 0.0
