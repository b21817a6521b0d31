"""The rules a click's mask obeys, on ``(H, W) bool`` masks of the working copy: the
pieces a click keeps (:func:`constrained`), how deep a click lies in a mask, the pixels a
box covers, and what a hypothesis piece may add (:func:`new_border_strip`).

Points are ``(x, y)`` working pixels; boxes ``(x0, y0, x1, y1)``, end exclusive.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import cv2
import numpy as np

from jeanscv.subject.clicks import Box

from .click_parts import interior_distance
from .consensus import border_shares, spans_width
from .masks import MORPH_FRACTION, deepest_point, disk, fill_holes, largest_component

#: A hypothesis piece that a positive click offers may not reach more than this share of
#: the top, left or right side where the mask does not reach it already.
PIECE_CONTACT = 0.1


def box_pixels(box: Box, size: tuple[int, int], target: tuple[int, int] | None = None) -> tuple[int, int, int, int]:
    """A box ``(x0, y0, x1, y1)`` in pixels of an image of ``size`` = (w, h) as whole
    pixels of an image of ``target`` (default ``size``): the pixels it covers, end
    exclusive, at least one."""
    width, height = size
    tw, th = target or size
    sx, sy = tw / width, th / height
    x0 = min(max(int(math.floor(box[0] * sx)), 0), tw - 1)
    y0 = min(max(int(math.floor(box[1] * sy)), 0), th - 1)
    x1 = max(min(int(math.ceil(box[2] * sx)), tw), x0 + 1)
    y1 = max(min(int(math.ceil(box[3] * sy)), th), y0 + 1)
    return x0, y0, x1, y1


def piece_points(mask: np.ndarray, least: int) -> list[tuple[int, int]]:
    """A pixel ``(x, y)`` deepest inside each piece of ``mask`` of at least ``least``
    pixels (8-connected), the largest piece's first; [] when empty."""
    count, labels = cv2.connectedComponents(mask.astype(np.uint8), connectivity=8)
    if count <= 1:
        return []
    areas = np.bincount(labels.ravel(), minlength=count)
    areas[0] = 0
    order = [int(k) for k in np.argsort(-areas, kind="stable") if areas[k] >= least or k == np.argmax(areas)]
    return [deepest_point(labels == k) for k in order if areas[k] > 0]


def largest_piece_point(mask: np.ndarray) -> list[tuple[int, int]]:
    """A pixel ``(x, y)`` deepest inside the largest piece of ``mask`` ([] when empty)."""
    # masks.deepest_point's 3x3 distance mask, not interior_distance's 5x5: the box
    # figures in docs/clicks.md were measured with it (the 5x5 mask's distances differ a
    # little, and so do the points it picks).
    return [deepest_point(largest_component(mask))] if mask.any() else []


def box_mask(box: tuple[int, int, int, int], shape: tuple[int, int]) -> np.ndarray:
    """``(H, W)`` bool, True on the box's pixels ``(x0, y0, x1, y1)``, end exclusive."""
    x0, y0, x1, y1 = box
    inside = np.zeros(shape, bool)
    inside[y0:y1, x0:x1] = True
    return inside


def grouped_pieces(mask: np.ndarray) -> np.ndarray:
    """``(H, W) int32`` labels of ``mask``'s pieces (0 outside them), pieces that a
    closing of 1% of the object's size joins counting as one (the grouping of
    :func:`constrained`; a label may hold pixels of the closing outside ``mask``)."""
    eight = mask.astype(np.uint8)
    radius = int(MORPH_FRACTION * np.sqrt(max(int(eight.sum()), 1)))
    grouped = cv2.morphologyEx(eight, cv2.MORPH_CLOSE, disk(radius)) if radius > 0 else eight
    grouped |= eight
    _, components = cv2.connectedComponents(grouped, connectivity=8)
    return components


def constrained(mask: np.ndarray, pos: list, neg: list) -> np.ndarray:
    """``mask`` made to obey the clicks: the pieces that hold a positive click (pieces
    that a closing of 1% of the object's size joins count as one, as in
    :func:`~jeanscv.subject.objects.split_objects`: a leg cut off by a thin gap stays),
    holes filled unless a negative click is in one; every positive click in, every
    negative click out."""
    components = grouped_pieces(mask)
    keep = {int(components[y, x]) for x, y in pos} - {0}
    kept = (np.isin(components, list(keep)) & mask) if keep else np.zeros_like(mask, dtype=bool)
    filled = fill_holes(kept)
    holes = filled & ~kept
    if holes.any() and neg:
        _, hole_labels = cv2.connectedComponents(holes.astype(np.uint8), connectivity=4)
        drop = {int(hole_labels[y, x]) for x, y in neg} - {0}
        filled &= ~np.isin(hole_labels, list(drop))
    for x, y in pos:
        filled[y, x] = True
    for x, y in neg:
        filled[y, x] = False
    return filled


def new_border_strip(addition: np.ndarray, previous: np.ndarray) -> bool:
    """True when ``addition`` runs along the top, left or right side (more than
    ``PIECE_CONTACT`` of it) where ``previous`` does not reach, or spans the width: what
    runs along the border is mostly background (Zhu et al. 2014); where the object already
    reaches a side, more of it there is the object leaving the frame."""
    before = border_shares(previous)[:3]
    after = border_shares(addition)[:3]
    return spans_width(addition) or any(a > PIECE_CONTACT and b == 0 for a, b in zip(after, before))


def depth_in(region: np.ndarray, x: int, y: int) -> float:
    """Distance (pixels, at least 2) from (x, y) to the boundary of ``region``."""
    return max(2.0, float(interior_distance(region)[y, x]))


def relative_depth(mask: np.ndarray, x: int, y: int) -> float:
    """The click's distance to the mask's boundary over the mask's deepest distance."""
    distance = interior_distance(mask)
    return float(distance[y, x]) / max(float(distance.max()), 1.0)


def held_pieces(mask: np.ndarray, clicks: tuple, keep: Sequence[tuple[int, int]] = ()) -> np.ndarray:
    """``mask`` made to obey ``clicks`` (``(sign, point)`` pairs, ``"+"`` or ``"-"``) as
    :func:`constrained` does, the pieces kept being those with a positive click or a
    pixel of ``keep`` still in ``mask``; with neither (negative clicks alone: the
    automatic subject minus them), the largest."""
    pos = [p for sign, p in clicks if sign == "+"]
    neg = [p for sign, p in clicks if sign == "-"]
    held = pos + [(x, y) for x, y in keep if mask[y, x]]
    return constrained(mask, held or largest_piece_point(mask), neg)
