"""A session's first positive click (:class:`FirstClick`, a part of
:class:`~jeanscv.subject.interactive.ClickSession`): the candidates it chooses among
(auto's hypotheses that hold the click, a GrabCut seeded at it, the geodesic region
nearer it than the border, a GrabCut seeded by that region, what lies inside a box round
it) and the choice.

Points are ``(x, y)`` working pixels; masks ``(h, w) bool`` of the session's working copy.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from jeanscv.geometry import mask_box

from .box_cut import box_interior
from .click_masks import constrained, relative_depth
from .click_parts import SEED_FRACTION, agreed, geodesic_grabcut, seeded_grabcut, small_copy
from .consensus import iou
from .grabcut import cut_pool
from .masks import MIN_AREA_FRACTION, resize_mask

#: A geodesic region whose boundary steps cost less than this on average (Lab units over
#: the noise floor) has no edge around it: a click on plain background.
_EDGE_CONTRAST = 1.0
#: Radius of the "probably the object" disc of the click-seeded GrabCut (short side).
_PROBABLE_RADIUS = 0.3
#: The click-seeded GrabCut of the first click runs on a copy this long: GrabCut's set-up
#: costs about 1 s at 480 px and 0.15 s at 160, and on the shared photos the first
#: click's mean IoU is 0.636 at 480, 0.642 at 240, 0.648 at 160 (0.622 without it).
_CUT_SIZE = 160
#: The first click's box candidate (:meth:`ClickSession._region_box`): the box round the
#: geodesic region grown this many times about its centre.
_REGION_BOX = 1.5
#: A candidate's vote in that choice: the geodesic region and the GrabCut seeded by it
#: (nearly the same partition, one in superpixels, one in pixels) are one voter between
#: them, or together they outvote auto's hypotheses wherever the click's colour region is
#: part of the object (the torso of a figure lit from above, without its dark legs).
_VOTES = {"geodesic": 0.5, "geocut": 0.5}


class FirstClick:
    """The first positive click's methods of a click session (which holds ``rgb``,
    ``size``, ``_graph``, ``_hypotheses`` and ``_smallest``)."""

    def _first(self, point: tuple[int, int]) -> np.ndarray:
        """The mask after one positive click: of auto's hypotheses that hold the click,
        a GrabCut seeded at the click, the geodesic region nearer the click than the
        border, a GrabCut seeded by that region and what lies inside a box round it, the
        one the others agree with most and the click lies deepest in; of it, the piece
        under the click (a person clicks each thing that should wear the jeans)."""
        x, y = point
        candidates = {name: constrained(m, [point], []) for name, m in self._hypotheses.items() if m[y, x]}
        least = max(3 * self._smallest, MIN_AREA_FRACTION * self._graph.labels.size)
        # The two GrabCuts are most of a first click's time (0.08 s each on this
        # machine): they are cut side by side, the geodesic region and its box made
        # meanwhile (OpenCV releases the GIL; each thread's cut is seeded, so the masks
        # are the same either way).
        with cut_pool() as pool:
            click_cut = pool.submit(self._click_grabcut, point)
            geodesic_cut = pool.submit(geodesic_grabcut, self.rgb, [point])
            region = self._geodesic_first(point)
            # A speck says nothing of where the object is: no box round it.
            boxed = self._region_box(region) if region is not None and np.count_nonzero(region) >= least else None
            candidates["click"] = click_cut.result()
            if region is not None:  # an edge round the click: the geodesic GrabCut has one to find
                candidates["geodesic"] = region
                candidates["geocut"] = constrained(geodesic_cut.result(), [point], [])
                if boxed is not None:
                    candidates["region box"] = constrained(boxed, [point], [])
        # A candidate of a few seed discs is a GrabCut collapsed onto its seed: the
        # click's depth in it is the greatest, so it would win the choice and the
        # refinement erase it. On the shared photos, leaving such candidates out raised
        # the first click's IoU from 0.673 to 0.691 (real) and 0.499 to 0.533 (pets), none
        # lower. Under auto's smallest subject (a speck of grass texture round a click
        # beside the dog) is no object either: if nothing else is left, nothing was found.
        candidates = {name: m for name, m in candidates.items() if np.count_nonzero(m) >= least}
        if not candidates:  # the clicked pixel alone: segment() says nothing was found
            return constrained(np.zeros(self.rgb.shape[:2], bool), [point], [])
        # Ties go to the geodesic GrabCut: of the candidates, the one that generalises (it
        # is the classical baseline's first step, which held up on photos nobody
        # here tuned for).
        tie = "geocut" if "geocut" in candidates else "click"
        return constrained(candidates[_agreed(candidates, point, tie, _VOTES)], [point], [])

    def _click_grabcut(self, point: tuple[int, int]) -> np.ndarray:
        """GrabCut seeded at the click, on a copy of ``_CUT_SIZE``: probably the object
        within a disc around the click, certainly background along the border (the
        point seeds of GrabCut's users)."""
        small, onto = small_copy(self.rgb, _CUT_SIZE)
        ((px, py),) = onto([point])
        short = min(small.shape[:2])
        labels = np.full(small.shape[:2], cv2.GC_PR_BGD, np.uint8)
        cv2.circle(labels, (px, py), max(2, round(_PROBABLE_RADIUS * short)), int(cv2.GC_PR_FGD), -1)
        ring = max(1, round(0.02 * short))
        labels[:ring], labels[-ring:], labels[:, :ring], labels[:, -ring:] = (cv2.GC_BGD,) * 4
        radius = max(1, round(SEED_FRACTION * short))
        cut = seeded_grabcut(small, labels, [(px, py)], [], radius)
        return constrained(resize_mask(cut, self.size), [point], [])

    def _region_box(self, region: np.ndarray) -> np.ndarray:
        """What lies inside a box round the click's geodesic region, grown
        :data:`_REGION_BOX` times about its centre: the part of it the box's edge does not
        reach cheaply (:func:`~.box_cut.box_interior`, on a copy of the box no longer than
        :data:`_CUT_SIZE`). The geodesic region is often a part of the pet (its flank, not
        its head); the box round it says roughly where the pet is, and its edge marks off
        what surrounds it where auto's hypotheses take the sofa or the owner as well."""
        height, width = region.shape
        x, y, w, h = mask_box(region)
        cx, cy = x + w / 2, y + h / 2
        half_w, half_h = _REGION_BOX * w / 2, _REGION_BOX * h / 2
        box = (
            max(0, int(cx - half_w)),
            max(0, int(cy - half_h)),
            min(width, math.ceil(cx + half_w)),
            min(height, math.ceil(cy + half_h)),
        )
        if box[2] - box[0] < 3 or box[3] - box[1] < 3:  # no inside for the edge to leave
            return np.zeros(region.shape, bool)
        return box_interior(self.rgb, box, size=_CUT_SIZE)

    def _geodesic_first(self, point: tuple[int, int]) -> np.ndarray | None:
        """What is geodesically nearer the click than the image border (the background
        spreads along the border: Zhu et al. 2014), as superpixels; None where no edge
        surrounds it (a click on plain background)."""
        x, y = point
        graph = self._graph
        node = int(graph.labels[y, x])
        everywhere = np.ones(graph.count, bool)
        border = graph.on_border.copy()
        border[node] = False
        near_click = graph.distances(everywhere, [node])
        near_border = (
            graph.distances(everywhere, np.flatnonzero(border)) if border.any() else np.full(graph.count, np.inf)
        )
        region = near_click < near_border
        if graph.contrast(region) < _EDGE_CONTRAST:
            # No edge along its boundary (a click on plain background: the click and the
            # border reach everything for nothing, and ties split it anyhow): no object.
            return None
        return constrained(region[graph.labels], [point], [])


def _agreed(
    candidates: dict[str, np.ndarray], point: tuple[int, int], tie: str, votes: dict[str, float] | None = None
) -> str:
    """The name of the candidate mask that :func:`~.click_parts.agreed` chooses, by
    their IoU and the click's relative depth in each."""
    x, y = point
    return agreed(
        list(candidates),
        lambda a, b: iou(candidates[a], candidates[b]),
        lambda a: relative_depth(candidates[a], x, y),
        votes,
        tie,
    )
