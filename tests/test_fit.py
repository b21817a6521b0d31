"""The fitter and its presets: determinism, the paper's validation, the four rules."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from conftest import PAPER_SHAPES, SHARED, paper_silhouette
from PIL import Image
from reference import loss_terms_ref

from jeanscv.errors import JeansError
from jeanscv.fitting.checks import rule_report, self_intersects
from jeanscv.fitting.fitter import fit, initial_placements
from jeanscv.fitting.garments import JEANS
from jeanscv.fitting.posture import posture
from jeanscv.fitting.render import polygon_coverage
from testkit.synthetic import ZOO, silhouette_zoo


@pytest.fixture(scope="module")
def zoo() -> dict[str, np.ndarray]:
    return silhouette_zoo()


def test_same_seed_gives_identical_vertices(zoo):
    first = fit(zoo["dog"], iterations=30, seed=3)
    second = fit(zoo["dog"], iterations=30, seed=3)
    assert np.array_equal(first.vertices, second.vertices)
    assert first.paper_terms == second.paper_terms


def test_seed_changes_the_initial_jitter():
    a = initial_placements(JEANS, 4, seed=0)
    b = initial_placements(JEANS, 4, seed=1)
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[0], JEANS.template)
    assert not np.allclose(a[1:], b[1:])


def test_placements_put_the_waist_at_the_canvas_centre():
    starts = initial_placements(JEANS, 8, seed=0)
    waist = starts[1:, list(JEANS.waist)].mean(axis=1)
    assert np.all(np.linalg.norm(waist - 128.0, axis=1) < 8.0)


def test_upside_down_detection():
    assert posture(JEANS.template, JEANS) == 0
    flipped = JEANS.template * [1.0, -1.0] + [0.0, 256.0]
    assert posture(flipped, JEANS) == 2


def test_fit_accepts_a_torch_tensor_and_rejects_bad_silhouettes(zoo):
    result = fit(torch.as_tensor(zoo["blob_a"]), iterations=5, starts=1)
    assert result.vertices.shape == (8, 2) and np.isfinite(result.vertices).all()
    with pytest.raises(JeansError, match="empty"):
        fit(np.zeros((256, 256)), iterations=1)
    with pytest.raises(JeansError, match="256x256"):
        fit(np.ones((100, 100)), iterations=1)


def test_trajectory_and_history_shapes(zoo):
    result = fit(zoo["blob_b"], iterations=12)
    assert result.trajectory.shape == (13, 8, 2)
    assert np.allclose(result.trajectory[-1], result.vertices, atol=1e-4)
    assert result.history.shape == (12, result.num_starts)
    _, upright, tilted = result.preset.upright.prunings[-1]
    assert len(result.start_ids) == upright + tilted


def test_jeans_go_on_the_legs_of_a_human_like_shape(zoo):
    silhouette = zoo["person"]
    result = fit(silhouette)
    fill = polygon_coverage(torch.as_tensor(result.vertices)[None], 256, 256)[0].numpy()
    # The synthetic person's hips are at y = 125 and its legs reach y = 235.
    assert fill[120:].sum() / fill.sum() > 0.85
    legs = silhouette.copy()
    legs[:125] = 0
    assert (fill * legs).sum() / legs.sum() > 0.5
    waist_y = result.vertices[list(JEANS.waist), 1].mean()
    assert 110 < waist_y < 145
    assert posture(result.vertices, JEANS) == 0  # upright


def test_person_matches_the_papers_figure_2():
    silhouette = paper_silhouette("person")
    figure = np.asarray(Image.open(SHARED / "person_paper_result.png").convert("RGB")).astype(int)
    blue = (figure[..., 2] > 150) & (figure[..., 0] < 120)
    result = fit(silhouette)
    jeans = polygon_coverage(torch.as_tensor(result.vertices)[None], 256, 256)[0].numpy() > 0.5
    iou = (blue & jeans).sum() / (blue | jeans).sum()
    assert iou >= 0.7, iou


@pytest.mark.parametrize("name", PAPER_SHAPES)
def test_default_preset_passes_the_four_rules_on_paper_silhouettes(name):
    silhouette = paper_silhouette(name)
    report = rule_report(fit(silhouette).vertices, silhouette)
    assert report.passed, report.to_json()


@pytest.mark.parametrize("name", sorted(ZOO))
def test_default_preset_passes_the_four_rules_on_the_zoo(name, zoo):
    report = rule_report(fit(zoo[name]).vertices, zoo[name])
    assert report.passed, report.to_json()


@pytest.mark.parametrize("name, diffvg", [("person", 6.6), ("horse", 4.1)])
def test_paper_preset_beats_diffvg_on_its_own_objective(name, diffvg):
    silhouette = paper_silhouette(name)
    result = fit(silhouette, "paper")
    assert result.paper_total < diffvg
    assert result.objective == pytest.approx(result.paper_total, rel=1e-4)


def test_paper_terms_match_an_independent_supersampled_implementation():
    silhouette = paper_silhouette("horse")
    result = fit(silhouette, "paper", iterations=40)
    reference = loss_terms_ref(result.vertices, silhouette, JEANS.template, JEANS.open_edges, JEANS.waist)
    for name, value in result.paper_terms.items():
        assert value == pytest.approx(reference[name], rel=0.05, abs=1e-3), name


def test_multi_start_is_no_worse_than_the_papers_single_start(zoo):
    silhouette = zoo["kangaroo"]
    single = fit(silhouette, starts=1, iterations=60)
    multi = fit(silhouette, iterations=60)
    assert multi.objective <= single.objective + 1e-6


def test_rule_checks_on_hand_made_cases():
    square = np.zeros((256, 256), np.float32)
    square[64:192, 64:192] = 1.0
    # The template shifted so its waistband centre is the canvas centre, inside the square.
    waist = JEANS.template[list(JEANS.waist)].mean(axis=0)
    jeans = (JEANS.template - waist) * 0.45 + 128.0
    report = rule_report(jeans, square)
    assert report.waist_offset_px == pytest.approx(0.0, abs=1e-9)
    assert report.rigid == pytest.approx(0.0, abs=1e-12)
    assert report.on_body_fraction == pytest.approx(1.0)
    assert not report.self_intersects
    assert self_intersects(np.array([[0, 0], [10, 10], [10, 0], [0, 10]], float))


def test_batch_adam_matches_torch_adam():
    from jeanscv.fitting.adam import BatchAdam

    start = torch.tensor([[1.0, -2.0], [0.5, 3.0]], dtype=torch.float64)
    ours = BatchAdam(start.numpy().copy(), lr=1e-2)
    theirs_param = start.clone().requires_grad_(True)
    theirs = torch.optim.Adam([theirs_param], lr=1e-2)
    for _ in range(50):
        ours.step(2 * ours.params**3 - ours.params)
        theirs.zero_grad()
        (0.5 * theirs_param**4 - 0.5 * theirs_param**2).sum().backward()
        theirs.step()
    np.testing.assert_allclose(ours.params, theirs_param.detach().numpy(), rtol=1e-10, atol=1e-12)


def test_posture_classes():
    from jeanscv.fitting.posture import tilt_degrees

    centre = JEANS.template[list(JEANS.waist)].mean(axis=0)

    def rotated(degrees):
        angle = np.radians(degrees)
        rot = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
        return (JEANS.template - centre) @ rot.T + centre

    assert tilt_degrees(JEANS.template, JEANS) == pytest.approx(0.0, abs=0.1)  # the template is nearly symmetric
    assert [posture(rotated(d), JEANS) for d in (0, 45, 90, -90, 135, 180)] == [0, 0, 1, 1, 2, 2]
    assert tilt_degrees(rotated(90), JEANS) == pytest.approx(90.0, abs=0.1)


def test_a_blur_schedule_runs_coarse_to_fine(zoo):
    import dataclasses

    from jeanscv.fitting.fitter import blur_schedule
    from jeanscv.fitting.objectives import blurred as blur
    from jeanscv.fitting.presets import get_preset

    assert blur_schedule((4.0, 2.0), 9) == [4.0] * 3 + [2.0] * 3 + [0.0] * 3
    silhouette = zoo["disc"].astype(np.float64)
    blurred = blur(silhouette, 3.0)
    # Mass is kept (the disc is far from the border) and the edge is softened.
    assert float(blurred.sum()) == pytest.approx(float(silhouette.sum()), rel=1e-4)
    assert float(((blurred > 0.02) & (blurred < 0.98)).sum()) > 2 * float(
        ((silhouette > 0.02) & (silhouette < 0.98)).sum()
    )
    smooth = dataclasses.replace(get_preset("default"), blur_sigmas=(4.0, 2.0))
    result = fit(zoo["blob_a"], smooth, iterations=60)
    assert rule_report(result.vertices, zoo["blob_a"]).passed


def test_screening_canvas_must_divide_the_canvas(zoo):
    import dataclasses

    from jeanscv.fitting.presets import get_preset

    odd = dataclasses.replace(get_preset("default"), screen_canvas=100)
    with pytest.raises(JeansError, match="screen_canvas"):
        fit(zoo["disc"], odd, iterations=5)


def test_pruning_keeps_the_best_upright_start_for_rule_selection():
    import dataclasses

    from jeanscv.fitting.fitter import _survivors
    from jeanscv.fitting.presets import get_preset

    rules = dataclasses.replace(get_preset("default"), keep=2)
    objective = dataclasses.replace(rules, select="objective")
    objectives = np.array([3.0, 1.0, 2.0, 0.0, 2.5])
    postures = [1, 2, 1, 2, 0]
    assert _survivors(objectives, postures, objective).tolist() == [1, 3]
    # Start 4 is the only upright one: it goes on, with the lowest objective (3).
    assert _survivors(objectives, postures, rules).tolist() == [3, 4]
    # No upright start: the best lying one (2) goes on with the overall best.
    assert _survivors(objectives, [1, 2, 1, 2, 2], rules).tolist() == [2, 3]
    # A diverged start never counts as the upright one.
    assert _survivors(np.array([np.nan, 1.0, 0.5]), [0, 1, 2], rules).tolist() == [1, 2]
