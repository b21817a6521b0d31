"""Property-based tests (hypothesis): the renderer, the loss and the framing stay sane
for arbitrary finite inputs, degenerate and far-away ones included."""

from __future__ import annotations

import numpy as np
import torch
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from jeanscv.fitting.garments import JEANS
from jeanscv.fitting.loss import PAPER_WEIGHTS, jalgorithm_terms, weighted_total
from jeanscv.fitting.render import polygon_coverage, stroke_coverage
from jeanscv.subject.framing import frame_mask

SIZE = 24
coordinates = st.one_of(
    st.floats(-5.0, SIZE + 5.0, allow_nan=False),
    st.floats(-1e6, 1e6, allow_nan=False),
    st.sampled_from([0.0, 1.0, 12.0, float(SIZE)]),
)
settings.register_profile("jeanscv", deadline=None, suppress_health_check=[HealthCheck.too_slow])
settings.load_profile("jeanscv")


def _finite_grad(output: torch.Tensor, vertices: torch.Tensor) -> bool:
    (grad,) = torch.autograd.grad(output.sum(), vertices)
    return bool(torch.isfinite(grad).all())


@settings(max_examples=60)
@given(arrays(np.float64, (5, 2), elements=coordinates))
def test_polygon_coverage_is_finite_bounded_and_differentiable(points):
    vertices = torch.tensor(points, requires_grad=True)
    coverage = polygon_coverage(vertices[None], SIZE, SIZE)
    assert torch.isfinite(coverage).all()
    assert coverage.min() >= 0.0 and coverage.max() <= 1.0
    assert _finite_grad(coverage * torch.linspace(0, 1, SIZE * SIZE).view(SIZE, SIZE), vertices)


@settings(max_examples=60)
@given(arrays(np.float64, (2, 2), elements=coordinates))
def test_stroke_coverage_is_finite_bounded_and_differentiable(points):
    vertices = torch.tensor(points, requires_grad=True)
    coverage = stroke_coverage(vertices[:1], vertices[1:], SIZE, SIZE)
    assert torch.isfinite(coverage).all()
    assert coverage.min() >= 0.0 and coverage.max() <= 1.0 + 1e-6
    assert _finite_grad(coverage, vertices)


silhouettes = st.sampled_from(["full", "square", "random", "dot"])


def _silhouette(kind: str, seed: int) -> torch.Tensor:
    s = torch.zeros(256, 256, dtype=torch.float64)
    if kind == "full":
        s[:] = 1.0
    elif kind == "square":
        s[60:200, 50:180] = 1.0
    elif kind == "dot":
        s[128, 128] = 0.5
    else:
        s = torch.as_tensor(np.random.default_rng(seed).random((256, 256)))
    return s


@settings(max_examples=30)
@given(
    arrays(np.float64, (8, 2), elements=st.one_of(st.floats(-300, 600, allow_nan=False), st.floats(-1e6, 1e6))),
    silhouettes,
    st.integers(0, 3),
)
def test_loss_terms_and_gradients_are_finite(points, kind, seed):
    vertices = torch.tensor(points, requires_grad=True)
    terms = jalgorithm_terms(vertices[None], _silhouette(kind, seed), JEANS, "all")
    for name, value in terms.items():
        assert torch.isfinite(value).all(), name
    assert _finite_grad(weighted_total(terms, PAPER_WEIGHTS), vertices)


def test_loss_is_finite_for_collapsed_polygons():
    for points in (np.full((8, 2), 100.0), np.repeat([[10.0, 10.0], [200.0, 50.0]], 4, axis=0)):
        vertices = torch.tensor(points, requires_grad=True)
        terms = jalgorithm_terms(vertices[None], _silhouette("square", 0), JEANS, "all")
        assert all(torch.isfinite(v).all() for v in terms.values())
        assert _finite_grad(weighted_total(terms, PAPER_WEIGHTS), vertices)


@settings(max_examples=60)
@given(
    st.integers(20, 900),
    st.integers(20, 900),
    st.tuples(st.floats(0.05, 0.95), st.floats(0.05, 0.95), st.floats(0.05, 0.9), st.floats(0.05, 0.9)),
    arrays(np.float64, (8, 2), elements=st.floats(-50, 300, allow_nan=False)),
)
def test_framing_round_trip(width, height, box, canvas_points):
    mask = np.zeros((height, width), np.float32)
    x0, y0 = int(box[0] * (width - 1)), int(box[1] * (height - 1))
    x1 = min(width, x0 + max(1, int(box[2] * width)))
    y1 = min(height, y0 + max(1, int(box[3] * height)))
    mask[y0:y1, x0:x1] = 1.0
    canvas, framing = frame_mask(mask)
    assert canvas.shape == (256, 256) and 0.0 <= canvas.min() and canvas.max() <= 1.0
    back = framing.to_canvas(framing.to_image(canvas_points))
    # Relative to the coordinate or to the canvas size, whichever is larger.
    assert np.all(np.abs(back - canvas_points) <= 1e-6 * np.maximum(np.abs(canvas_points), 256.0))
    # The object's box lands centred on the canvas.
    centre = framing.to_canvas(np.array([(x0 + x1) / 2, (y0 + y1) / 2]))
    assert np.allclose(centre, 128.0, atol=256.0 / framing.side + 1e-9)


@settings(max_examples=40)
@given(arrays(np.bool_, st.tuples(st.integers(1, 40), st.integers(1, 40))))
def test_frame_mask_same_for_bool_and_float_masks(mask):
    """A bool mask is framed without a full-frame float copy, with the same result."""
    if not mask.any():
        return
    canvas_bool, framing_bool = frame_mask(mask)
    canvas_float, framing_float = frame_mask(mask.astype(np.float32))
    np.testing.assert_array_equal(canvas_bool, canvas_float)
    assert framing_bool == framing_float
