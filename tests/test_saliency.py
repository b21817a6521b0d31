"""Superpixel saliency (boundary connectivity, Zhu et al. 2014) and the focus cue, on
tiny synthetic images with known answers."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from jeanscv.subject.saliency import SuperpixelGraph, focus, saliency_map


def _graph(labels: np.ndarray) -> SuperpixelGraph:
    """A graph over hand-made labels (colours and edges are not used by focus)."""
    count = int(labels.max()) + 1
    area = np.bincount(labels.ravel(), minlength=count).astype(np.float64)
    return SuperpixelGraph(
        labels, np.zeros((count, 3)), np.zeros((count, 2)), area, np.zeros((count, 4), bool), np.zeros((0, 2), int)
    )


def test_focus_is_mean_detail_over_its_95th_percentile():
    labels = np.array([[0, 0, 1, 1], [2, 2, 2, 2]], np.int32)
    detail = np.array([[1.0, 3.0, 10.0, 10.0], [0.0, 0.0, 0.0, 0.0]])
    means = np.array([2.0, 10.0, 0.0])
    level = np.percentile(means, 95)
    assert focus(_graph(labels), detail) == pytest.approx(np.clip(means / level, 0, 1), abs=1e-12)


def _square_photo() -> np.ndarray:
    """48x48 float32 Lab: a red 16x16 square in the middle of a grey frame."""
    rgb = np.full((48, 48, 3), 0.5, np.float32)
    rgb[16:32, 16:32] = (0.8, 0.1, 0.1)
    return cv2.cvtColor(rgb, cv2.COLOR_RGB2LAB)


def test_saliency_of_a_centred_square_is_the_square():
    graph = SuperpixelGraph.of(_square_photo(), 8)
    saliency = graph.to_pixels(saliency_map(graph, "sum", 4.0))
    square = np.zeros((48, 48), bool)
    square[16:32, 16:32] = True
    assert saliency.max() == pytest.approx(1.0)
    # SLIC's regions follow the square's edges to within a pixel or so (33 of 256 edge pixels off).
    assert np.count_nonzero((saliency > 0.5) != square) <= 40
    assert np.median(saliency[square]) > 0.9 and np.median(saliency[~square]) < 0.1


def test_sharpness_halves_the_saliency_of_blurred_regions():
    graph = SuperpixelGraph.of(_square_photo(), 8)
    plain = saliency_map(graph, "minimax")
    sharp_square = graph.mean_of(np.pad(np.ones((16, 16)), 16)) > 0.5
    weighted = saliency_map(graph, "minimax", sharpness=sharp_square.astype(float))
    # The square stays at the top; the rest keeps half of its (already low) value.
    assert weighted[sharp_square] == pytest.approx(plain[sharp_square], rel=1e-9)
    assert weighted[~sharp_square] == pytest.approx(0.5 * plain[~sharp_square], rel=1e-9, abs=1e-12)
