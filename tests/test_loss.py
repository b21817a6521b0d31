"""Tests of jeanscv.fitting.loss: the paper's seven terms against hand-made exact cases and an
independent 8x8 supersampled numpy reference (tests/reference.py), their gradients,
batching, and the weighted module.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch
from conftest import PAPER_SHAPES, paper_silhouette
from conftest import float64_tensor as _t
from reference import loss_terms_ref, rigid_ref

from jeanscv.errors import JeansError
from jeanscv.fitting.garments import JEANS, Garment
from jeanscv.fitting.loss import (
    PAPER_WEIGHTS,
    JalgorithmLoss,
    affine_residual_operator,
    jalgorithm_terms,
    upright_term,
    weighted_total,
)
from testkit.synthetic import silhouette_zoo

TERMS = ("center", "coverage", "rigid", "open", "closed", "inter", "inside")
F64 = torch.float64


def _terms(vertices, silhouette, **kwargs) -> dict[str, float]:
    """Terms of one candidate as floats."""
    out = jalgorithm_terms(_t(vertices)[None], _t(silhouette), **kwargs)
    for value in out.values():
        assert value.shape == (1,)
    return {name: value.item() for name, value in out.items()}


def _reference(vertices, silhouette, garment: Garment = JEANS, **kwargs) -> dict[str, float]:
    return loss_terms_ref(vertices, silhouette, garment.template, garment.open_edges, garment.waist, **kwargs)


def _assert_terms_close(got: dict[str, float], ref: dict[str, float], rel: float = 0.05, floor: float = 1e-3) -> None:
    bad = {k: (got[k], ref[k]) for k in TERMS if abs(got[k] - ref[k]) > max(rel * abs(ref[k]), floor)}
    assert not bad, f"terms off the reference (got, ref): {bad}"


def _smooth_silhouette(size: int, centre, axes, softness: float) -> np.ndarray:
    """An ellipse with a logistic edge ``softness`` px wide: S smooth in the vertices."""
    yy, xx = np.mgrid[0:size, 0:size] + 0.5
    radius = np.hypot((xx - centre[0]) / axes[0], (yy - centre[1]) / axes[1])
    return 1.0 / (1.0 + np.exp((radius - 1.0) * min(axes) / softness))


def _off_grid(points: np.ndarray, gap: float = 1e-3) -> np.ndarray:
    frac = points - np.round(points)
    return np.where(np.abs(frac) < gap, points + 3 * gap * np.where(frac < 0, -1, 1), points)


# ---------------------------------------------------------------- hand-made cases

#: S: the filled square [64, 192]^2, exact 0/1 pixels.
SQUARE_S = np.zeros((256, 256))
SQUARE_S[64:192, 64:192] = 1.0
#: X: the square [96, 160]^2 in jeans vertex order, with collinear points on the bottom.
SQUARE_X = np.array(
    [[96, 160], [96, 96], [160, 96], [160, 160], [140, 160], [128, 160], [116, 160], [106, 160]], dtype=np.float64
)


def test_square_in_square_exact_terms() -> None:
    got = _terms(SQUARE_X, SQUARE_S)
    assert got["inside"] == pytest.approx(0.0, abs=1e-12)
    assert got["coverage"] == pytest.approx((0.5 - (1 - 64**2 / 128**2)) ** 2, abs=1e-12)  # 0.0625
    # Waist vertices 1 and 2: midpoint (128, 96) / 256 = (0.5, 0.375).
    assert got["center"] == pytest.approx(0.125**2, abs=1e-12)
    # Every stroke lies inside S (the strokes reach 93.5..162.5).
    assert got["open"] == pytest.approx(-1.0, abs=1e-9)
    assert got["closed"] == pytest.approx(1.0, abs=1e-9)
    assert got["rigid"] == pytest.approx(rigid_ref(SQUARE_X, JEANS.template), rel=1e-9)
    assert got["rigid"] > 1e-3


def test_square_in_square_inter() -> None:
    # Non-adjacent edges are >= 10 px apart: their 5-px strokes never touch.
    assert _terms(SQUARE_X, SQUARE_S, inter_pairs="non_adjacent")["inter"] == pytest.approx(0.0, abs=1e-12)
    got = _terms(SQUARE_X, SQUARE_S)["inter"]
    ref = _reference(SQUARE_X, SQUARE_S, samples=16)["inter"]
    assert got == pytest.approx(ref, rel=0.02)
    # By hand, with areas for pixel sums: collinear neighbours share the cap disc
    # (pi r^2), right-angle ones 3/4 of it plus the inner r x r square; the union is
    # the two capsules' areas less that. Pixel products shave a few % off the overlap.
    r, disc = 2.5, np.pi * 2.5**2
    lengths = [64, 64, 64, 20, 12, 12, 10, 10]
    by_hand = 0.0
    for i in range(8):
        overlap = 0.75 * disc + r * r if i in (7, 0, 1, 2) else disc
        by_hand += overlap / (2 * r * (lengths[i] + lengths[(i + 1) % 8]) + 2 * disc - overlap)
    assert by_hand == pytest.approx(0.7311, abs=1e-4)
    assert got == pytest.approx(by_hand, rel=0.1)


#: A rectangle garment, mirror-symmetric about x = 128, with the top edge open.
RECT = Garment(
    name="rect",
    template=np.array([[90.3, 190.9], [90.3, 60.2], [165.7, 60.2], [165.7, 190.9]]),
    open_edges=(1,),
    waist=(1, 2),
)


def test_half_plane_silhouette_mirror_symmetry() -> None:
    """S is the left half of the canvas; the rectangle is symmetric about x = 128.

    The mirror x -> 256 - x maps the pixel grid onto itself and S onto 1 - S, so every
    stroke union and the fill lie half on S: L_open = -1/2, L_closed = 1/2, L_inside
    = 1/2, and the uncovered part of S is 128 * 256 - area / 2.
    """
    s = np.zeros((256, 256))
    s[:, :128] = 1.0
    got = _terms(RECT.template, s, garment=RECT)
    area = (165.7 - 90.3) * (190.9 - 60.2)
    assert got["open"] == pytest.approx(-0.5, abs=1e-9)
    assert got["closed"] == pytest.approx(0.5, abs=1e-9)
    assert got["inside"] == pytest.approx(0.5, abs=1e-9)
    assert got["coverage"] == pytest.approx((0.5 - (128 * 256 - area / 2) / (128 * 256)) ** 2, abs=1e-9)
    assert got["center"] == pytest.approx(((128 / 256 - 0.5) ** 2 + (60.2 / 256 - 0.5) ** 2), abs=1e-12)
    assert got["rigid"] == pytest.approx(0.0, abs=1e-20)
    assert _terms(RECT.template, s, garment=RECT, inter_pairs="non_adjacent")["inter"] == pytest.approx(0, abs=1e-12)
    ref = _reference(RECT.template, s, garment=RECT, samples=16)
    _assert_terms_close(got, ref, rel=0.02, floor=1e-6)


def test_strokes_outside_silhouette() -> None:
    # S only far from the polygon: no stroke on the body, no fill on the body.
    s = np.zeros((256, 256))
    s[:20, :20] = 1.0
    got = _terms(SQUARE_X, s)
    assert got["open"] == pytest.approx(0.0, abs=1e-12)
    assert got["closed"] == pytest.approx(0.0, abs=1e-12)
    assert got["inside"] == pytest.approx(1.0, abs=1e-12)
    assert got["coverage"] == pytest.approx(0.25, abs=1e-12)


# ---------------------------------------------------------------- rigidity


def _affine(kind: str) -> np.ndarray:
    if kind == "identity":
        return np.array([[1.0, 0, 0], [0, 1, 0]])
    if kind == "scale":
        return np.array([[1.7, 0, -40], [0, 0.6, 25]])
    if kind == "rotation":
        c, s = np.cos(0.7), np.sin(0.7)
        return np.array([[c, -s, 60], [s, c, -30]])
    if kind == "shear":
        return np.array([[1.0, 0.45, -20], [0, 1, 0]])
    if kind == "general":
        return np.array([[0.8, -0.3, 17.5], [0.25, 1.3, -41.0]])
    raise AssertionError(kind)


@pytest.mark.parametrize("kind", ["identity", "scale", "rotation", "shear", "general"])
def test_rigid_is_zero_for_affine_images_of_template(kind: str) -> None:
    matrix = _affine(kind)
    vertices = JEANS.template @ matrix[:, :2].T + matrix[:, 2]
    assert _terms(vertices, SQUARE_S)["rigid"] == pytest.approx(0.0, abs=1e-14)


@pytest.mark.parametrize("vertex", [0, 5])
def test_rigid_of_one_moved_vertex_is_its_leverage_complement(vertex: int) -> None:
    # Moving vertex k by d leaves residual (I - H) d e_k, of squared norm
    # |d|^2 (1 - h_kk), h_kk the leverage of row k of the design [Xbar, 1].
    shift = np.array([3.0, -4.0])
    vertices = JEANS.template.copy()
    vertices[vertex] += shift
    q, _ = np.linalg.qr(np.hstack([JEANS.template, np.ones((8, 1))]))
    leverage = float((q[vertex] ** 2).sum())
    expected = (shift @ shift) * (1 - leverage) / 256**2
    got = _terms(vertices, SQUARE_S)["rigid"]
    assert got == pytest.approx(expected, rel=1e-9)
    assert got == pytest.approx(rigid_ref(vertices, JEANS.template), rel=1e-9)


def test_rigid_random_non_affine_matches_least_squares() -> None:
    rng = np.random.default_rng(2)
    vertices = JEANS.template @ np.array([[1.1, 0.2], [-0.1, 0.9]]) + rng.normal(0, 5, (8, 2))
    assert _terms(vertices, SQUARE_S)["rigid"] == pytest.approx(rigid_ref(vertices, JEANS.template), rel=1e-9)


def test_affine_residual_operator_is_the_residual_projector() -> None:
    op = affine_residual_operator(JEANS.template)
    design = np.hstack([JEANS.template, np.ones((8, 1))])
    assert op.shape == (8, 8)
    np.testing.assert_allclose(op, op.T, atol=1e-12)
    np.testing.assert_allclose(op @ op, op, atol=1e-12)
    np.testing.assert_allclose(op @ design, 0.0, atol=1e-9)
    assert np.trace(op) == pytest.approx(8 - 3, abs=1e-9)


# ---------------------------------------------------------------- against the reference


@pytest.mark.parametrize("name", PAPER_SHAPES)
def test_terms_match_reference_on_paper_silhouettes(name: str) -> None:
    s = paper_silhouette(name, np.float64)
    _assert_terms_close(_terms(JEANS.template, s), _reference(JEANS.template, s))


@pytest.fixture(scope="module")
def zoo() -> dict[str, np.ndarray]:
    return silhouette_zoo(["person", "spider", "disc"])


@pytest.mark.parametrize(
    "name,inter_pairs", [("person", "all"), ("spider", "all"), ("disc", "all"), ("spider", "non_adjacent")]
)
def test_terms_match_reference_on_synthetic_silhouettes(zoo, name: str, inter_pairs: str) -> None:
    s = zoo[name].astype(np.float64)
    # A scaled, shifted, jittered template: edges cross the body's outline.
    rng = np.random.default_rng(len(name))
    vertices = JEANS.template * 1.3 - 30 + rng.normal(0, 4, (8, 2))
    got = _terms(vertices, s, inter_pairs=inter_pairs)
    _assert_terms_close(got, _reference(vertices, s, inter_pairs=inter_pairs))
    if inter_pairs == "non_adjacent":
        # Only adjacent strokes of this candidate touch.
        assert got["inter"] == pytest.approx(0.0, abs=1e-12)


OFF_CANVAS = {
    "over_top_left": JEANS.template * 1.6 - 170,
    "over_bottom_right": JEANS.template * 1.6 + 20,
    "half_outside_right": JEANS.template + [150, -100],
}


@pytest.mark.parametrize("case", sorted(OFF_CANVAS))
def test_terms_match_reference_partly_off_canvas(zoo, case: str) -> None:
    s = zoo["person"].astype(np.float64)
    vertices = OFF_CANVAS[case]
    _assert_terms_close(_terms(vertices, s), _reference(vertices, s))


@pytest.mark.parametrize("crop", ["rows", "cols"])
def test_terms_match_reference_on_non_square_silhouette(zoo, crop: str) -> None:
    # 200 x 256 and 256 x 200 crops; the terms normalise by the width.
    full = zoo["person"].astype(np.float64)
    s = full[28:228] if crop == "rows" else np.ascontiguousarray(full[:, 28:228])
    vertices = JEANS.template - ([0, 28] if crop == "rows" else [28, 0])
    _assert_terms_close(_terms(vertices, s), _reference(vertices, s))


def test_unknown_inter_pairs_is_rejected() -> None:
    with pytest.raises(JeansError):
        jalgorithm_terms(_t(JEANS.template)[None], _t(SQUARE_S), inter_pairs="nonadjacent")


def test_template_inter_pairs() -> None:
    s = SQUARE_S
    all_pairs = _terms(JEANS.template, s)["inter"]
    assert all_pairs == pytest.approx(_reference(JEANS.template, s, samples=16)["inter"], rel=0.02)
    # The template's non-adjacent strokes are >= 5 px apart.
    assert _terms(JEANS.template, s, inter_pairs="non_adjacent")["inter"] == pytest.approx(0.0, abs=1e-12)


# ---------------------------------------------------------------- batching and weights


def _three_candidates() -> np.ndarray:
    rng = np.random.default_rng(8)
    return np.stack(
        [
            JEANS.template,
            JEANS.template * 0.8 + 30 + rng.normal(0, 3, (8, 2)),
            # Partly off the canvas, so the candidates' windows differ in size and place.
            JEANS.template @ np.array([[0.9, 0.2], [-0.2, 1.1]]) + rng.normal(0, 3, (8, 2)) + [120, -90],
        ]
    )


def test_batch_equals_separate_calls() -> None:
    candidates = _three_candidates()
    zoo = silhouette_zoo(["person", "dog", "blob_a"])
    s = zoo["person"].astype(np.float64)
    batch = jalgorithm_terms(_t(candidates), _t(s))
    per_candidate_s = np.stack([zoo[n] for n in ("person", "dog", "blob_a")]).astype(np.float64)
    batch_own = jalgorithm_terms(_t(candidates), _t(per_candidate_s))
    for i in range(3):
        alone = _terms(candidates[i], s)
        alone_own = _terms(candidates[i], per_candidate_s[i])
        for name in TERMS:
            assert batch[name].shape == (3,)
            assert batch[name][i].item() == pytest.approx(alone[name], abs=1e-5)
            assert batch_own[name][i].item() == pytest.approx(alone_own[name], abs=1e-5)


def test_module_equals_weighted_paper_terms() -> None:
    candidates = _t(_three_candidates())
    s = torch.as_tensor(silhouette_zoo(["person"])["person"])
    terms = jalgorithm_terms(candidates, s.to(F64))
    by_hand = sum(PAPER_WEIGHTS[name] * terms[name] for name in TERMS)
    assert set(PAPER_WEIGHTS) == set(TERMS)
    torch.testing.assert_close(weighted_total(terms, PAPER_WEIGHTS), by_hand, atol=1e-12, rtol=0)
    torch.testing.assert_close(JalgorithmLoss(s)(candidates), by_hand, atol=1e-9, rtol=0)
    custom = {"coverage": 2.0, "inside": 0.5}
    expected = 2.0 * terms["coverage"] + 0.5 * terms["inside"]
    torch.testing.assert_close(weighted_total(terms, custom), expected, atol=1e-12, rtol=0)
    torch.testing.assert_close(JalgorithmLoss(s, weights=custom)(candidates), expected, atol=1e-9, rtol=0)


# ---------------------------------------------------------------- gradients


@pytest.mark.parametrize("term", TERMS)
def test_terms_gradcheck_small_canvas(term: str) -> None:
    s = _t(_smooth_silhouette(32, (15.3, 17.1), (9.0, 12.0), 2.0))
    vertices = _off_grid((JEANS.template - 128) * 0.2 + 16 + np.random.default_rng(1).normal(0, 0.3, (8, 2)))
    x = _t(vertices)[None].requires_grad_(True)
    assert torch.autograd.gradcheck(lambda v: jalgorithm_terms(v, s)[term], (x,))


@pytest.mark.parametrize("inter_pairs", ["all", "non_adjacent"])
def test_loss_module_gradcheck_small_canvas(inter_pairs: str) -> None:
    """The nn.Module form, batched (B, N, 2) -> (B,), with the default preset's weights too."""
    from jeanscv.fitting.presets import get_preset

    s = _t(_smooth_silhouette(32, (15.3, 17.1), (9.0, 12.0), 2.0))
    rng = np.random.default_rng(2)
    vertices = np.stack([_off_grid((JEANS.template - 128) * 0.2 + 16 + rng.normal(0, 0.3, (8, 2))) for _ in range(2)])
    x = _t(vertices).requires_grad_(True)
    for weights in (None, get_preset("default").weights):
        module = JalgorithmLoss(s, weights=weights, inter_pairs=inter_pairs)
        assert module(x).shape == (2,)
        assert torch.autograd.gradcheck(module, (x,))


def test_terms_gradients_match_central_differences_on_full_canvas() -> None:
    s = _t(_smooth_silhouette(256, (128, 140), (70, 95), 6.0))
    base = JEANS.template + np.random.default_rng(3).normal(0, 3, (8, 2))
    x = _t(base)[None].requires_grad_(True)
    terms = jalgorithm_terms(x, s)
    grads = {k: torch.autograd.grad(v.sum(), x, retain_graph=True)[0][0].numpy() for k, v in terms.items()}
    step = 1e-3
    numeric = {k: np.zeros((8, 2)) for k in TERMS}
    for i in range(8):
        for axis in range(2):
            plus, minus = base.copy(), base.copy()
            plus[i, axis] += step
            minus[i, axis] -= step
            up, down = jalgorithm_terms(_t(plus)[None], s), jalgorithm_terms(_t(minus)[None], s)
            for k in TERMS:
                numeric[k][i, axis] = (up[k] - down[k]).item() / (2 * step)
    for k in TERMS:
        assert np.abs(numeric[k]).max() > 1e-5, k  # every term moves with some vertex
        assert np.linalg.norm(grads[k] - numeric[k]) <= 0.05 * np.linalg.norm(numeric[k]), k


DEGENERATE = {
    "one_point": np.full((8, 2), 100.3),
    "zero_length_edges": JEANS.template[[0, 0, 2, 2, 4, 4, 6, 6]],
    "far_positive": JEANS.template + 1e6,
    "far_negative": JEANS.template - 1e6,
    "huge": (JEANS.template - 128) * 1e4,
}


@pytest.mark.parametrize("dtype", [torch.float32, F64])
@pytest.mark.parametrize("name", sorted(DEGENERATE))
def test_degenerate_candidates_give_finite_terms_and_gradients(name: str, dtype: torch.dtype) -> None:
    s = torch.as_tensor(silhouette_zoo(["person"])["person"], dtype=dtype)
    x = torch.as_tensor(DEGENERATE[name], dtype=dtype)[None].requires_grad_(True)
    terms = jalgorithm_terms(x, s)
    for name_, value in terms.items():
        assert torch.isfinite(value).all(), name_
        assert torch.isfinite(torch.autograd.grad(value.sum(), x, retain_graph=True)[0]).all(), name_
    if name in ("far_positive", "far_negative"):
        # Nothing is drawn on the canvas: no stroke, no fill, all of S uncovered.
        assert terms["coverage"].item() == pytest.approx(0.25, abs=1e-6)
        assert terms["open"].item() == 0.0 and terms["closed"].item() == 0.0 and terms["inter"].item() == 0.0
        assert terms["inside"].item() == 0.0


@pytest.mark.parametrize("name", ["person", "spider"])
def test_terms_on_a_twice_coarser_canvas_with_half_width_strokes_agree(zoo, name: str) -> None:
    """The fitter screens starts on a 128-px canvas: the terms are ratios of areas in
    normalised coordinates, so they barely change with resolution."""
    silhouette = _t(zoo[name])
    vertices = _t(JEANS.template)[None] * 0.7 + 38.0
    full = jalgorithm_terms(vertices, silhouette, inter_pairs="non_adjacent")
    coarse_s = torch.nn.functional.avg_pool2d(silhouette[None, None], 2)[0, 0]
    coarse = jalgorithm_terms(vertices / 2, coarse_s, inter_pairs="non_adjacent", stroke_half_width=1.25)
    for term in ("center", "rigid"):
        assert float(coarse[term]) == pytest.approx(float(full[term]), rel=1e-9, abs=1e-12), term
    for term in ("coverage", "open", "closed", "inside"):
        assert float(coarse[term]) == pytest.approx(float(full[term]), abs=0.01), term
    assert float(coarse["inter"]) == pytest.approx(float(full["inter"]), abs=0.003)


# ---------------------------------------------------------------- upright


def _turned(degrees: float, scale: tuple[float, float] = (1.0, 1.0)) -> np.ndarray:
    """The jeans template stretched by ``scale`` (x, y) then turned by ``degrees``
    (clockwise on screen, y down) about the canvas centre, ``(1, 8, 2)``."""
    t = np.radians(degrees)
    rotation = np.array([[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]])
    return (((JEANS.template - 128) * scale) @ rotation.T + 128)[None]


@pytest.mark.parametrize(
    "degrees, expected",
    [
        (0, 0.0),
        (15, 0.0),
        (-20, 0.0),
        (30, np.cos(np.radians(20)) - np.cos(np.radians(30))),
        (45, np.cos(np.radians(20)) - np.cos(np.radians(45))),
        (60, np.cos(np.radians(20)) - 0.5),
        (90, np.cos(np.radians(20)) - 0.5),
        (180, np.cos(np.radians(20)) - 0.5),
    ],
)
def test_upright_term_of_a_turned_template(degrees: float, expected: float) -> None:
    """c = cos(turn) for a rigidly turned garment; stretching it (squat, wide jeans) changes nothing."""
    for scale in ((1.0, 1.0), (2.0, 0.5)):
        value = float(upright_term(_t(_turned(degrees, scale)))[0])
        assert value == pytest.approx(expected, abs=1e-12)


def test_upright_term_gradcheck_and_in_the_terms() -> None:
    x = _t(_turned(40.0) + np.random.default_rng(4).normal(0, 2, (1, 8, 2))).requires_grad_(True)
    assert torch.autograd.gradcheck(upright_term, (x,))
    s = _t(_smooth_silhouette(256, (128, 140), (70, 95), 6.0))
    with torch.no_grad():
        assert float(jalgorithm_terms(x, s)["upright"][0]) == float(upright_term(x)[0])
