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
most and that the click lies deepest in; the piece under the click is kept
(:mod:`.click_first`). A first positive click inside a detected animal's box (the
shipped detector's, :mod:`.click_detected`) whose cut holds it starts instead from that
box, as a person's box would; later clicks then change only what lies near them. Every further click is a geodesic
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

import numpy as np

from jeanscv.detect import Detection
from jeanscv.errors import JeansError, NothingFound
from jeanscv.subject.clicks import Box, ObjectClicks

from .box_cut import box_recut, box_score
from .boxed import at_full_size, box_alone
from .click_detected import DetectedBox, detected_boxes, meant_box
from .click_first import FirstClick, _agreed
from .click_masks import (
    box_mask,
    box_pixels,
    constrained,
    depth_in,
    held_pieces,
    largest_piece_point,
    new_border_strip,
    piece_points,
)
from .click_parts import (
    SEED_FRACTION,
    ClickGraph,
    PixelRefiner,
    colour_density,
    simulated_click,
)
from .grabcut import cut_pool
from .masks import (
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

#: After a box (a person's, or a detected animal's that a first click started from) a
#: click changes only what lies within this share of the box's diagonal of it. After a
#: first click in a detected animal's box, bench.clicks on both shared sets (one run):
#: without this limit harmful clicks 6 of 101 (real) and 21 of 250 (pets), IoU@5 0.861
#: and 0.804; with 0.5, 6 and 20, 0.864 and 0.824; with 0.25, 5 and 10, 0.842 and 0.827.
_BOX_REACH = 0.25

#: Click sequences a session remembers (a mask of the working copy each, ~0.2 MB).
_CACHED_SEQUENCES = 64

Point = tuple[float, float]


class ClickSession(FirstClick):
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
        detector: str = "auto",
        detections: Sequence[Detection] | None = None,
    ):
        """``shared``: auto's hypotheses of this photo, when :func:`photo.segment` has cut
        them already (or will: they are cut once, by whichever asks first).
        ``automatic``: the automatic subject as the caller shows it (an ``(H, W)`` bool
        mask of the photo, e.g. the detector's), which negative clicks alone edit; by
        default :func:`photo.segment`'s. ``detector``: ``auto`` (the shipped detector's
        boxes start the clicks inside them, :mod:`.click_detected`) or ``none``;
        ``detections``: the photo's detections, where the caller has them (not found again)."""
        rgb, _ = _validate_image(image)
        self.detections, problem = detected_boxes(rgb, detector, detections)
        if problem:
            import warnings

            from .detected import DetectorWarning

            warnings.warn(f"jeanscv: {problem}", DetectorWarning, stacklevel=2)
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
        a box alone, without positive clicks, is enough. :class:`NothingFound` "nothing found
        there" when the mask is smaller than a click's seed disc (a click on plain
        background gave the clicked pixel alone): never an empty or one-pixel object.
        """
        clicks = ObjectClicks(tuple(positive), tuple(negative), box)  # one object's, checked as a file's are
        positive, negative = clicks.positive, clicks.negative
        working, detected = self._resolved(clicks)
        if np.count_nonzero(working) < self._smallest:
            # Only the clicked pixels themselves (a click on plain background): no object,
            # which the person is told instead of getting jeans on a speck.
            if clicks.edits_automatic:
                raise NothingFound("nothing is left of the automatic subject after those clicks")
            if clicks.box is not None:
                raise NothingFound("nothing found in that box: click inside the subject")
            raise NothingFound("nothing clear there: click inside the subject")
        found = at_full_size(working, self.shape, positive, negative, clicks.box)
        if detected is not None:
            found.details["detection"] = detected.to_json()
        return found

    def working_mask(
        self, positive: Sequence[Point], negative: Sequence[Point] = (), box: Box | None = None
    ) -> np.ndarray:
        """The mask at working resolution (``(h, w)`` bool, a view of the session's own),
        for previews. A negative click that lands on a positive one's working pixel
        (clicks a few pixels apart on a large photo) is left to :meth:`segment`'s full
        resolution."""
        return self._resolved(ObjectClicks(tuple(positive), tuple(negative), box))[0]

    def meant(self, point: Point) -> DetectedBox | None:
        """The detected object a first positive click at ``point`` (photo pixels) starts
        from (:func:`~.click_detected.meant_box`), or None."""
        return self._meant(self._to_working(point))

    def _meant(self, point: tuple[int, int]) -> DetectedBox | None:
        """:meth:`meant` of a working pixel: in a detection's box (whole photo pixels) and
        on its cut."""
        if not self.detections:
            return None
        x, y = point
        width, height = self.shape[1], self.shape[0]
        centre = ((x + 0.5) * width / self.size[0], (y + 0.5) * height / self.size[1])

        def holds_click(box: tuple[int, int, int, int]) -> bool:
            return bool(self._boxed(box, ())[y, x])

        return meant_box(self.detections, centre, holds_click)

    def _resolved(self, clicks: ObjectClicks) -> tuple[np.ndarray, DetectedBox | None]:
        """The working mask of one object's clicks (read-only) and the detected object
        its first positive click starts from (or None)."""
        positive, negative = clicks.positive, clicks.negative
        pos = [self._to_working(p) for p in positive]
        neg = [q for q in (self._to_working(p) for p in negative) if q not in pos]
        sequence = tuple(("+", p) for p in pos) + tuple(("-", p) for p in neg)
        detected = None
        if clicks.box is not None:
            mask = self._boxed(box_pixels(clicks.box, self.shape[::-1]), sequence)
        elif not pos:
            mask = self._minus(sequence)
        else:
            mask = self._after(sequence)
            detected = self._meant(pos[0])
        mask.flags.writeable = False
        return mask, detected

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
            return self._remember(key, box_alone(self._rgb, box, self.size, self._pixels)[0])
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
        # near it (a negative click on the background between a dog's legs must not take
        # the dog).
        near = self._near(clicks[-1][1], box)
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

    def _near(self, point: tuple[int, int], box: tuple[int, int, int, int]) -> np.ndarray:
        """``(h, w)`` bool: the working pixels within :data:`_BOX_REACH` of ``box``'s
        diagonal (whole photo pixels) of ``point`` (a working pixel): what a click after
        a box may change."""
        x0, y0, x1, y1 = box_pixels(box, self.shape[::-1], self.size)
        reach = _BOX_REACH * math.hypot(x1 - x0, y1 - y0)
        rows, columns = np.ogrid[: self.size[1], : self.size[0]]
        return (columns - point[0]) ** 2 + (rows - point[1]) ** 2 <= reach**2

    def _in_box(self, point: tuple[int, int], box: tuple[int, int, int, int]) -> bool:
        """Whether working pixel ``point`` lies in ``box`` (whole photo pixels)."""
        x0, y0, x1, y1 = box_pixels(box, self.shape[::-1], self.size)
        return x0 <= point[0] < x1 and y0 <= point[1] < y1

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
        if len(clicks) == 1 and (detected := self._meant(clicks[0][1])) is not None:
            # Inside a detected object's box, on its cut: the box and the click, as a
            # person's box would start (already refined); later clicks correct it as usual.
            return self._remember(clicks, self._boxed(detected.box, clicks))
        near = previous = None
        if len(clicks) == 1:
            mask = self._first(clicks[0][1])
        else:
            previous = self._after(clicks[:-1])
            mask = self._step(previous, clicks)
            detected = self._meant(clicks[0][1])
            if detected is not None and self._in_box(clicks[-1][1], detected.box):
                # Started from a detected animal's box: as after a person's box, a click
                # inside it changes only what lies near the click. One outside it (the
                # object goes on past a box round a part of it) changes what it reaches.
                near = self._near(clicks[-1][1], detected.box)
                mask = np.where(near, mask, previous)
        pos = [p for sign, p in clicks if sign == "+"]
        neg = [p for sign, p in clicks if sign == "-"]
        refined = constrained(self._pixels.refine(mask), pos, neg)
        # The refinement's colour models can erase a small object whole (a dark cat on a
        # dark monitor): then the superpixel mask stands.
        mask = refined if np.count_nonzero(refined) >= min(self._smallest, np.count_nonzero(mask)) else mask
        if near is not None:  # the refinement too: nothing changes far from the click
            mask = np.where(near, mask, previous)
        return self._remember(clicks, mask)

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


def segment_with_clicks(image: np.ndarray, positive: Sequence[Point], negative: Sequence[Point] = ()) -> Segmentation:
    """One object's mask from its clicks (a :class:`ClickSession` used once)."""
    return ClickSession(image).segment(positive, negative)


__all__ = ["ClickSession", "WORKING_SIZE", "segment_with_clicks", "simulated_click"]
