"""The rules a click's mask obeys (:mod:`jeanscv.subject.click_masks`), on tiny masks
with exact expected answers (x right, y down; points ``(x, y)``)."""

from __future__ import annotations

import numpy as np

from jeanscv.subject import click_masks as rules


def _mask(rows: list[str]) -> np.ndarray:
    return np.array([[c == "#" for c in row] for row in rows])


def test_box_pixels_are_the_pixels_a_box_covers_end_exclusive():
    # A box's edges inside pixels take those pixels: x 1.5..4.1 covers columns 1-4.
    assert rules.box_pixels((1.5, 2.2, 4.1, 5.0), (10, 10)) == (1, 2, 5, 5)
    # The same box on an image twice the size (the working copy of a bigger photo).
    assert rules.box_pixels((1.5, 2.2, 4.1, 5.0), (10, 10), (20, 20)) == (3, 4, 9, 10)
    # Clipped to the image, and never empty.
    assert rules.box_pixels((-3.0, -1.0, 30.0, 4.0), (10, 8)) == (0, 0, 10, 4)
    assert rules.box_pixels((2.0, 2.0, 2.0, 2.0), (10, 10)) == (2, 2, 3, 3)


def test_box_mask_is_true_on_the_boxs_pixels_only():
    expected = _mask(
        [
            ".....",
            ".###.",
            ".###.",
            ".....",
        ]
    )
    np.testing.assert_array_equal(rules.box_mask((1, 1, 4, 3), (4, 5)), expected)


def test_constrained_keeps_the_clicked_piece_and_fills_its_holes_unless_clicked():
    mask = _mask(
        [
            "##.......",
            "##...####",
            ".....#..#",
            ".....#..#",
            ".....####",
        ]
    )
    ring = _mask(
        [
            ".........",
            ".....####",
            ".....####",
            ".....####",
            ".....####",
        ]
    )
    # A positive click on the ring: the square piece goes, the ring's hole is filled.
    np.testing.assert_array_equal(rules.constrained(mask, [(5, 2)], []), ring)
    # A negative click in the hole keeps it open; the clicked pixels obey the clicks.
    hole = _mask([".........", ".........", "......##.", "......##.", "........."])
    np.testing.assert_array_equal(rules.constrained(mask, [(5, 2)], [(6, 2)]), ring & ~hole)
    # No positive click: no piece is kept.
    assert not rules.constrained(mask, [], []).any()
    # A positive click off the mask is in, alone.
    lone = rules.constrained(mask, [(2, 4)], [])
    assert lone.sum() == 1 and lone[4, 2]


def test_depth_is_the_distance_to_the_boundary_at_least_two():
    region = np.zeros((11, 11), bool)
    region[1:10, 1:10] = True  # a 9x9 square: its centre pixel lies 5 pixels from outside
    assert rules.depth_in(region, 5, 5) == 5.0
    assert rules.depth_in(region, 1, 5) == 2.0  # an edge pixel: 1, raised to the floor of 2
    assert rules.relative_depth(region, 5, 5) == 1.0
    assert rules.relative_depth(region, 3, 5) == 3.0 / 5.0


def test_piece_points_give_each_big_pieces_deepest_pixel_the_largest_first():
    mask = np.zeros((9, 12), bool)
    mask[1:4, 1:4] = True  # 9 pixels, centre (2, 2)
    mask[2:7, 6:11] = True  # 25 pixels, centre (8, 4)
    mask[8, 0] = True  # a speck
    assert rules.piece_points(mask, 5) == [(8, 4), (2, 2)]
    assert rules.piece_points(mask, 10) == [(8, 4)]
    assert rules.largest_piece_point(mask) == [(8, 4)]
    assert rules.piece_points(np.zeros((3, 3), bool), 1) == [] == rules.largest_piece_point(np.zeros((3, 3), bool))


def test_a_piece_along_a_side_the_mask_does_not_reach_is_a_border_strip():
    previous = np.zeros((20, 20), bool)
    previous[8:16, 8:12] = True
    top = np.zeros((20, 20), bool)
    top[0:2, 4:16] = True  # along the top, where the mask is not
    assert rules.new_border_strip(top, previous)
    # Where the mask reaches the top already, more of it there is the object leaving the frame.
    reaching = previous.copy()
    reaching[0:8, 8:12] = True
    assert not rules.new_border_strip(top, reaching)
    inside = np.zeros((20, 20), bool)
    inside[6:8, 8:12] = True
    assert not rules.new_border_strip(inside, previous)


def test_held_pieces_keeps_the_clicked_pieces_and_the_kept_points_else_the_largest():
    mask = np.zeros((9, 12), bool)
    mask[1:4, 1:4] = True  # a small piece
    mask[2:7, 6:11] = True  # a larger one
    small, large = mask.copy(), mask.copy()
    small[:, 5:] = False
    large[:, :5] = False
    np.testing.assert_array_equal(rules.held_pieces(mask, (("+", (2, 2)),)), small)
    # A point to keep holds its piece too, unless it has left the mask.
    np.testing.assert_array_equal(rules.held_pieces(mask, (("+", (2, 2)),), [(8, 4)]), mask)
    np.testing.assert_array_equal(rules.held_pieces(mask, (("+", (2, 2)),), [(0, 8)]), small)
    # Negative clicks alone: the largest piece, the clicked pixel out.
    expected = large.copy()
    expected[3, 7] = False
    np.testing.assert_array_equal(rules.held_pieces(mask, (("-", (7, 3)),)), expected)
