"""Interactive segmentation: positive and negative clicks that fix the subject's mask.

Public API: :class:`ClickSession` (set a photo once, then each call with the current
clicks of one object returns its mask quickly), :func:`segment_with_clicks` (the same,
stateless) and :func:`simulated_click` (the standard simulated user, for benches).

Arrays: images ``(H, W, 3)`` RGB or ``(H, W, 4)`` RGBA ``uint8``; masks ``(H, W) bool``;
clicks ``(x, y)`` image pixels, package convention (pixel ``(c, r)`` covers
``[c, c+1) x [r, r+1)``).

How: the session works on a copy with long side ``WORKING_SIZE``, with SLIC superpixels
joined by their Lab distances. The first positive click chooses, among auto's hypotheses
that hold it (:func:`jeanscv.subject.photo.hypotheses`), a GrabCut seeded at the
click, what is geodesically nearer the click than the image border (boundary
connectivity, Zhu et al. 2014), a GrabCut seeded by that partition
(:func:`~.click_parts.geodesic_grabcut`) and what the edge of a box round that region
does not reach cheaply (:func:`~.box_cut.box_interior`), the one the others agree with
most and that the click lies deepest in; the piece under the click is kept. Every further click is a geodesic
correction on the superpixels (Bai and Sapiro 2007; Gulshan et al. 2010's geodesic
seeds): on the side of the mask where the click landed, what the click reaches more
cheaply than the other side's stand-ins changes sides; a positive click off the mask may
instead add the piece of one of auto's hypotheses that holds it, when the others agree.
After every click the pixels within a superpixel's width of the boundary are decided
again by local colour models, smoothed by a guided filter (thin parts, fine outlines).
The clicks are hard: the mask holds every positive click and none of the negative
ones; the pieces without a positive click are dropped, holes filled unless a negative
click is in one.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import cv2
import numpy as np

from jeanscv.errors import JeansError
from jeanscv.geometry import mask_box
from jeanscv.subject.clicks import Box, ObjectClicks

from .box_cut import box_interior, box_recut, box_score
from .boxed import at_full_size, box_alone
from .click_masks import (
    box_mask,
    box_pixels,
    constrained,
    depth_in,
    held_pieces,
    largest_piece_point,
    new_border_strip,
    piece_points,
    relative_depth,
)
from .click_parts import (
    SEED_FRACTION,
    ClickGraph,
    PixelRefiner,
    agreed,
    colour_density,
    geodesic_grabcut,
    interior_distance,
    seeded_grabcut,
    small_copy,
)
from .consensus import iou
from .grabcut import cut_pool
from .masks import (
    MIN_AREA_FRACTION,
    downscale,
    resize_mask,
    shape_for,
)
from .photo import Segmentation, SharedHypotheses, _validate_image

#: Long side (pixels) of the copy the clicks are segmented on.
WORKING_SIZE = 480
#: Long side of the copy auto's hypotheses are made from (as :func:`photo.segment`).
SCENE_SIZE = 640
#: Background border superpixels nearer the click than this many times its depth do not
#: stand for the background (the missed part may leave the frame there).
_ANCHOR_REACH = 1.5
#: The wrong side farther than this many times the click's depth keeps its side unless
#: the click reaches it for less than ``_CORE_PRICE`` (Lab units summed along the way).
_CORE_REACH = 2.0
_CORE_PRICE = 20.0
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

#: Click sequences a session remembers (a mask of the working copy each, ~0.2 MB).
_CACHED_SEQUENCES = 64

Point = tuple[float, float]


class ClickSession:
    """One photo, segmented again after each click (in the spirit of Segment Anything's
    predictor): the constructor does the work that does not depend on the clicks
    (downscaling, auto's hypotheses: shared with :func:`photo.segment` through a
    :class:`~jeanscv.subject.photo.SharedHypotheses`); :meth:`segment` takes one
    object's clicks.

    Results are remembered by click sequence, so adding a click to a sequence already
    segmented costs one step; the same clicks always give the same mask.
    """

    def __init__(
        self,
        image: np.ndarray,
        *,
        working_size: int = WORKING_SIZE,
        shared: SharedHypotheses | None = None,
        automatic: np.ndarray | None = None,
    ):
        """``shared``: auto's hypotheses of this photo, when :func:`photo.segment` has cut
        them already (or will: they are cut once, by whichever asks first).
        ``automatic``: the automatic subject as the caller shows it (an ``(H, W)`` bool
        mask of the photo, e.g. the detector's), which negative clicks alone edit; by
        default :func:`photo.segment`'s."""
        rgb, _ = _validate_image(image)
        self._rgb = rgb  # the box's cut crops the photo itself
        self._image = image  # for the automatic subject, which a negative click alone edits
        self.shape = rgb.shape[:2]
        height, width = self.shape
        self.size = shape_for(self.shape, working_size)  # (w, h) of the working copy
        self._shown = None  # the caller's automatic subject, at working resolution
        if automatic is not None:
            automatic = np.asarray(automatic)
            if automatic.shape != self.shape:
                raise ValueError(f"automatic mask of shape {automatic.shape}, not the photo's {self.shape}")
            self._shown = resize_mask(automatic.astype(bool, copy=False), self.size)
        self.rgb = downscale(rgb, self.size)
        scene_rgb = downscale(rgb, shape_for(self.shape, SCENE_SIZE))
        self._shared = shared or SharedHypotheses()
        # The superpixel graph (SLIC, a fifth of the set-up) is made while auto's
        # hypotheses are cut, whose Python parts leave a core idle (OpenCV releases the
        # GIL; SLIC has no randomness, so the graph is the same either way).
        with cut_pool() as pool:
            graph = pool.submit(ClickGraph, self.rgb)
            found = self._shared.of(scene_rgb).found
            self._graph = graph.result()
        self._hypotheses = {
            name: resize_mask(mask, self.size) for name, mask in (found.coarse.items() if found is not None else ())
        }
        self._cache: dict[tuple, np.ndarray] = {}
        self._seed_radius = max(1, round(SEED_FRACTION * min(self.size)))
        #: Fewer working pixels than a click's seed disc are no object (see :meth:`segment`).
        self._smallest = max(4, int(math.pi * self._seed_radius**2))
        self._pixels = PixelRefiner(self.rgb)

    # ------------------------------------------------------------------ coordinates
    def _to_working(self, point: Point) -> tuple[int, int]:
        height, width = self.shape
        x, y = float(point[0]), float(point[1])
        if not (0 <= x < width and 0 <= y < height):
            raise JeansError(f"click ({x:g}, {y:g}) is outside the {width}x{height} image")
        w, h = self.size
        return min(int(x * w / width), w - 1), min(int(y * h / height), h - 1)

    # ------------------------------------------------------------------ public
    def segment(
        self, positive: Sequence[Point], negative: Sequence[Point] = (), box: Box | None = None
    ) -> Segmentation:
        """The mask of the object these clicks describe, at the photo's resolution.

        Clicks are applied in order: positive ones first as given, then negative ones;
        the mask holds every positive click and none of the negative ones. With a
        ``box`` ``(x0, y0, x1, y1)`` the object is cut inside it (:meth:`_boxed`), and
        a box alone, without positive clicks, is enough. JeansError "nothing found
        there" when the mask is smaller than a click's seed disc (a click on plain
        background gave the clicked pixel alone): never an empty or one-pixel object.
        """
        clicks = ObjectClicks(tuple(positive), tuple(negative), box)  # one object's, checked as a file's are
        positive, negative = clicks.positive, clicks.negative
        working = self.working_mask(positive, negative, clicks.box)
        if np.count_nonzero(working) < self._smallest:
            # Only the clicked pixels themselves (a click on plain background): no object,
            # which the person is told instead of getting jeans on a speck.
            if clicks.edits_automatic:
                raise JeansError("nothing is left of the automatic subject after those clicks")
            where = "in that box" if clicks.box is not None else "there"
            raise JeansError(f"nothing found {where}: click inside the subject")
        return at_full_size(working, self.shape, positive, negative, clicks.box)

    def working_mask(
        self, positive: Sequence[Point], negative: Sequence[Point] = (), box: Box | None = None
    ) -> np.ndarray:
        """The mask at working resolution (``(h, w)`` bool, a view of the session's own),
        for previews. A negative click that lands on a positive one's working pixel
        (clicks a few pixels apart on a large photo) is left to :meth:`segment`'s full
        resolution."""
        clicks = ObjectClicks(tuple(positive), tuple(negative), box)
        positive, negative = clicks.positive, clicks.negative
        pos = [self._to_working(p) for p in positive]
        neg = [q for q in (self._to_working(p) for p in negative) if q not in pos]
        sequence = tuple(("+", p) for p in pos) + tuple(("-", p) for p in neg)
        if clicks.box is not None:
            mask = self._boxed(box_pixels(clicks.box, self.shape[::-1]), sequence)
        elif not pos:
            mask = self._minus(sequence)
        else:
            mask = self._after(sequence)
        mask.flags.writeable = False
        return mask

    def _boxed(self, box: tuple[int, int, int, int], clicks: tuple) -> np.ndarray:
        """The object inside ``box`` (photo pixels ``(x0, y0, x1, y1)``, end exclusive),
        then the clicks ((sign, working pixel) pairs, in order) as corrections.

        The box alone: :func:`~.box_cut.box_cut` on the photo's own pixels (GrabCut on a
        crop, two starts, every piece kept, holes left open), its boundary refined at
        pixel level on the working copy. Each click then corrects that mask as a click
        corrects the last one (:meth:`_step`, geodesic; what it changes far from itself
        checked by colour, :meth:`_colour_checked`), a deepest point of every piece
        standing for the object beside the positive clicks; a negative click, by that
        or by GrabCut on the box (:func:`~.box_cut.box_recut`), whichever
        :func:`~.box_cut.box_score` prefers; only within a quarter of the box's diagonal of
        the click; nothing outside the box. Remembered. (Seeding the GrabCut with the
        clicks instead made the first click after a box lower the mean IoU on the shared
        photos: its colour models are global.)"""
        key = ("box", box, clicks)
        if key in self._cache:
            return self._cache[key]
        height, width = self.shape
        x0, y0, x1, y1 = working = box_pixels(box, (width, height), self.size)
        inside = box_mask(working, self.rgb.shape[:2])
        if not clicks:
            return self._remember(key, box_alone(self._rgb, box, self.size, self._pixels))
        previous = self._boxed(box, clicks[:-1])
        # Every piece of the box's object stays, whatever the clicks add: a deepest point
        # of each is kept beside the positive clicks. They are no clicks: a negative
        # click often lands right there (a box round a thin thing holds mostly
        # background), and as a positive one it kept that pixel alone.
        stand_in = piece_points(previous, self._smallest)
        pos = [p for sign, p in clicks if sign == "+"]
        neg = [p for sign, p in clicks if sign == "-"]
        with cut_pool() as pool:
            # A negative click's GrabCut on the box (below) is cut while its geodesic step
            # is made: the same masks, 0.05 s sooner on a 12-MP photo.
            negative = clicks[-1][0] == "-"
            job = pool.submit(box_recut, self.rgb, working, previous, pos, neg, self._seed_radius) if negative else None
            mask = self._step(previous, clicks, stand_in, colour_check=True) & inside if previous.any() else previous
            keep = (pos + [(x, y) for x, y in stand_in if mask[y, x]]) or largest_piece_point(mask)
            if mask.any() and keep:
                mask = constrained(self._pixels.refine(constrained(mask, keep, neg)), keep, neg) & inside
            recut = job.result() if job is not None else None
        # Local: the box already found the object, so a click changes only what lies
        # within a quarter of the box's diagonal of it (a negative click on the
        # background between a dog's legs must not take the dog).
        (cx, cy) = clicks[-1][1]
        reach = 0.25 * math.hypot(x1 - x0, y1 - y0)
        rows, columns = np.ogrid[: mask.shape[0], : mask.shape[1]]
        near = (columns - cx) ** 2 + (rows - cy) ** 2 <= reach**2
        mask = np.where(near, mask, previous)
        if recut is not None:
            # A negative click's geodesic step can take the object where it shares the
            # background's colours (a click beside a cat on a lap took the cat); GrabCut on
            # the box re-fits its colour models and moves the boundary only where they say
            # so, but corrects less far. Of the two, the one whose colours stand apart from
            # the rest of the box's crop is kept (the score that chose the box's own cut).
            # A positive click's big step is mostly a missed part found: kept. Per click on
            # the shared photos (a box, then 10 simulated clicks), IoU falls of over 0.05:
            # 24 of 340 on the pets and 7 of 180 on the real photos when GrabCut took only
            # negative steps over 15% of the box, 14 and 2 now; see docs/clicks.md.
            recut = np.where(near, recut, previous)
            if box_score(self.rgb, recut, working) > box_score(self.rgb, mask, working):
                mask = recut
        for x, y in pos:
            mask[y, x] = True
        for x, y in neg:
            mask[y, x] = False
        return self._remember(key, mask)

    def _remember(self, key: tuple, mask: np.ndarray) -> np.ndarray:
        """``mask``, kept under ``key``; the oldest goes first: a session stays bounded."""
        if len(self._cache) >= _CACHED_SEQUENCES:
            del self._cache[next(iter(self._cache))]
        self._cache[key] = mask
        return mask

    def _minus(self, clicks: tuple) -> np.ndarray:
        """Negative clicks alone ((sign, working pixel) pairs): the automatic subject
        (:func:`photo.segment`, its hypotheses shared with this session), minus what each
        click takes away (:meth:`_step`), its largest piece kept. Remembered."""
        key = ("minus", clicks)
        if key in self._cache:
            return self._cache[key]
        if not clicks:
            mask = self._automatic()
        else:
            previous = self._minus(clicks[:-1])
            mask = self._step(previous, clicks) if previous.any() else previous
            keep = largest_piece_point(mask)
            if keep:
                mask = constrained(self._pixels.refine(mask), keep, [p for _, p in clicks])
        return self._remember(key, mask)

    def _automatic(self) -> np.ndarray:
        """The automatic subject at working resolution (empty when auto finds none): the
        caller's (``automatic``), else :func:`photo.segment`'s."""
        from .photo import segment

        if self._shown is not None:
            return self._shown.copy()
        try:
            found = segment(self._image, "auto", shared=self._shared).mask
        except JeansError:
            return np.zeros(self.rgb.shape[:2], bool)
        return resize_mask(found, self.size)

    # ------------------------------------------------------------------ steps
    def _after(self, clicks: tuple) -> np.ndarray:
        """The mask after ``clicks`` ((sign, working pixel) pairs, in order), its boundary
        refined at pixel level, remembered (the next click starts from it)."""
        if clicks in self._cache:
            return self._cache[clicks]
        if len(clicks) == 1:
            mask = self._first(clicks[0][1])
        else:
            mask = self._step(self._after(clicks[:-1]), clicks)
        pos = [p for sign, p in clicks if sign == "+"]
        neg = [p for sign, p in clicks if sign == "-"]
        refined = constrained(self._pixels.refine(mask), pos, neg)
        # The refinement's colour models can erase a small object whole (a dark cat on a
        # dark monitor): then the superpixel mask stands.
        mask = refined if np.count_nonzero(refined) >= min(self._smallest, np.count_nonzero(mask)) else mask
        return self._remember(clicks, mask)

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

    def _step(
        self,
        previous: np.ndarray,
        clicks: tuple,
        keep: Sequence[tuple[int, int]] = (),
        colour_check: bool = False,
    ) -> np.ndarray:
        """The mask after one more click, from the mask before it.

        The click says that the region around it is on the wrong side. On the
        superpixels of that side, the ones geodesically nearer the click than to what
        stands for the other side change sides. What stands for the other side: the
        clicks of the other sign; for a positive click, the background's border away
        from the click (the background spreads along the border); and, at a price of
        ``_CORE_PRICE``, the rest of the wrong side farther than ``_CORE_REACH`` times
        the click's depth, so a click takes what it reaches without crossing an edge
        (a whole sky) but not what lies beyond one. A positive click off the mask may
        add a piece of auto's hypotheses instead (:meth:`_with_pieces`). The pieces kept:
        those with a positive click or a pixel of ``keep`` (when still in), else the
        largest. With ``colour_check``, what the step moved far from the click goes back
        where its colour says so (:meth:`_colour_checked`).
        """
        sign, (x, y) = clicks[-1]
        graph = self._graph
        share = graph.mean_of(previous)
        wrong = share > 0.5 if sign == "-" else share <= 0.5
        node = int(graph.labels[y, x])
        wrong[node] = True
        depth = depth_in(previous if sign == "-" else ~previous, x, y)
        away = np.hypot(*(graph.centre_px - np.array([x, y])).T)
        anchors = np.zeros(graph.count, bool)
        anchors[[graph.labels[py, px] for s, (px, py) in clicks if s != sign]] = True
        if sign == "+":
            anchors |= graph.on_border & (away > _ANCHOR_REACH * depth)
        anchors &= wrong
        anchors[node] = False
        # With no positive click nothing stands for the object but the rest of it (the
        # automatic subject minus a click): guard what lies beyond the click's own part.
        alone = not any(s == "+" for s, _ in clicks)
        core = wrong & (away > (1.0 if alone else _CORE_REACH) * depth)
        core[node] = False
        near_click = graph.distances(wrong, [node])
        near_other = graph.distances(wrong, np.flatnonzero(anchors)) if anchors.any() else np.inf
        if core.any():
            near_other = np.minimum(near_other, graph.distances(wrong, np.flatnonzero(core)) + _CORE_PRICE)
        flip = wrong & (near_click < near_other)
        mask = previous.copy()
        mask[flip[graph.labels]] = sign == "+"
        if sign == "+" and not previous[y, x]:
            mask = self._with_pieces(previous, mask, (x, y), [p for s, p in clicks if s == "-"])
        mask = held_pieces(mask, clicks, keep)
        return self._colour_checked(previous, mask, clicks, keep, depth, away) if colour_check else mask

    def _colour_checked(
        self,
        previous: np.ndarray,
        stepped: np.ndarray,
        clicks: tuple,
        keep: Sequence[tuple[int, int]],
        depth: float,
        away: np.ndarray,
    ) -> np.ndarray:
        """``stepped``, the last click's step from ``previous``, with the superpixels it
        moved farther from the click than its ``depth`` (``away``: each superpixel's
        distance from the click) moved back where their colour is likelier on the side
        they left than on the side the click says: the superpixels the step moved near
        the click, and those under the clicks of its sign (Gaussian kernels over the
        superpixels' mean Lab colours, weighted by area); the pieces kept as
        :meth:`_step` keeps them. A click changes what its own surroundings look like,
        and what looks like the rest of the object (a negative click on the mat that
        reaches the puppy through steps too small to cost) or of the background (a
        positive click on a cat's grey flank that reaches the pavement) stays as it was.
        Used after a box, where on the shared photos it lowered the harmful clicks from 15
        to 11 of 300 with every mean the same or higher; without a box it traded photos
        (docs/clicks.md)."""
        sign = clicks[-1][0]
        graph = self._graph
        before = graph.mean_of(previous) > 0.5
        after = graph.mean_of(stepped) > 0.5
        changed = before != after
        far = changed & (away > depth)
        if not far.any():
            return stepped
        mine = changed & ~far
        mine[[graph.labels[py, px] for s, (px, py) in clicks if s == sign]] = True
        other = after if sign == "-" else ~after
        nodes = np.flatnonzero(far)
        colours = graph.colour[nodes]
        here = colour_density(colours, graph.colour[mine], graph.area[mine].astype(float))
        there = colour_density(colours, graph.colour[other], graph.area[other].astype(float))
        back = np.zeros(graph.count, bool)
        back[nodes[there > here]] = True
        if not back.any():
            return stepped
        return held_pieces(np.where(back[graph.labels], previous, stepped), clicks, keep)

    def _with_pieces(self, previous: np.ndarray, grown: np.ndarray, point, neg: list) -> np.ndarray:
        """A positive click outside the mask: of the geodesic growth and the pieces of
        auto's hypotheses that hold the click (and no negative click), the addition the
        others agree with most."""
        x, y = point
        added = {"geodesic": grown & ~previous}  # what the geodesic correction adds
        for name, hypothesis in self._hypotheses.items():
            if not hypothesis[y, x]:
                continue
            piece = constrained(hypothesis, [point], [])
            if any(piece[ny, nx] for nx, ny in neg):
                continue
            addition = piece & ~previous
            if new_border_strip(addition, previous):
                continue
            added[name] = addition
        return previous | added[_agreed(added, point, "geodesic")]


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


def simulated_click(reference: np.ndarray, predicted: np.ndarray | None) -> tuple[bool, Point]:
    """The next click of the standard simulated user (Xu et al. 2016; RITM, Sofiiuk et
    al. 2022), for measuring: ``(positive?, (x, y))``.

    The first click (``predicted`` None) at the interior point of ``reference`` farthest
    from its boundary (the image border counts as boundary); each next click in the
    largest error region (the one whose interior point lies farthest from its boundary),
    at that point: positive where the subject was missed, negative where background was
    taken. ``reference`` and ``predicted`` are ``(H, W)`` bool.
    """
    if predicted is None:
        distance = interior_distance(reference)
        y, x = np.unravel_index(np.argmax(distance), distance.shape)
        return True, (x + 0.5, y + 0.5)
    missed = interior_distance(reference & ~predicted)
    taken = interior_distance(~reference & predicted)
    positive = missed.max() >= taken.max()
    distance = missed if positive else taken
    y, x = np.unravel_index(np.argmax(distance), distance.shape)
    return bool(positive), (x + 0.5, y + 0.5)


def segment_with_clicks(image: np.ndarray, positive: Sequence[Point], negative: Sequence[Point] = ()) -> Segmentation:
    """One object's mask from its clicks (a :class:`ClickSession` used once)."""
    return ClickSession(image).segment(positive, negative)


__all__ = ["ClickSession", "WORKING_SIZE", "segment_with_clicks", "simulated_click"]
