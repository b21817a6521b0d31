"""Follow objects' masks from frame to frame of a clip.

The first frame's masks come from the still-photo segmentation (automatic or clicked);
:class:`Follower` carries them on. For each new frame, on a copy at most
``WORK_SIDE`` pixels long:

1. a scene cut (the frames' colour histograms differ by more than :data:`CUT_DISTANCE`)
   is reported, so the caller finds the subject afresh;
2. each object's motion is measured: its whole-pixel shift by matching its previous
   pixels (masked template matching), then a similarity from its corners tracked by
   pyramidal Lucas-Kanade (forward and back); the mask moves by it as a whole, so the
   errors of a dense flow (a trail of uncovered background, a small object's motion
   smoothed into the background's) cannot grow or stall it;
3. in a band around the moved mask's edge, each pixel is re-decided from the moved mask
   and the object's colour model (histograms of the object and of its surroundings,
   learnt on the first frame and updated as it goes), so the edge stays on the subject
   and takes up what moved on its own (a leg, the tail);
4. a mask that shrinks below :data:`LOST_FRACTION` of its size when it was found, or
   whose pixels mostly have its surroundings' colours, is lost (the object left the frame
   or went behind something).

Several objects are followed each on its own; a pixel two objects claim goes to the
first. A clip run with the detector (:mod:`._reanchor`) restarts an object from a fresh
cut (:meth:`Follower.reseed`), keeps it within its detected box
(:meth:`Follower.keep_within`) and lets its band trust the colours more
(``Followed.prior``). Masks are ``(H, W)`` bool at the frame's full resolution; motions
are 2x3 maps between pixel-centre coordinates (x right, y down, centres at +0.5).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from ..geometry import mask_box
from .masks import largest_component

#: Longest side (pixels) of the copy the tracking and the re-segmentation run on.
WORK_SIDE = 640
#: Bhattacharyya distance between consecutive frames' colour histograms above which the
#: scene is taken to have cut.
CUT_DISTANCE = 0.5
#: Below this fraction of its area when it was found, an object is lost.
LOST_FRACTION = 0.15
#: Below this share of its pixels in the object's colours (rather than its surroundings'),
#: a followed mask is background: the object is lost.
UNLIKE = 0.5
#: Share of the colour model renewed from each frame's mask.
MODEL_RATE = 0.1
#: How much the moved mask counts against the colour model in the edge band (0..1): at
#: 0.5 a pixel outside the moved mask never joins it (the mask only shrinks by colour,
#: and cannot drift onto a background of its colours; a leg that swings out is lost).
PRIOR_WEIGHT = 0.5
#: Margin of the search box around an object, as a fraction of the box's longer side.
ROI_MARGIN = 0.3
#: ... and at least this many pixels: room for a small object's large moves.
MIN_MARGIN = 48
#: Half width of the edge band, as a fraction of the object's size (square root of its area).
BAND = 0.06
#: Most corners tracked per object.
_CORNERS = 150
#: Share of a key frame's corners that must still track (forward and back) for the motion
#: to be measured from the key frame; fewer, and the previous frame becomes the key.
KEY_KEEP = 0.5
#: Share of the way from the frame-to-frame motion to the key frame's measure taken each
#: frame (the rest over the next frames): on bench.clips' moving clip 0.3 kept the drift
#: (1.26 px mean, 1.64 worst over 120 frames) and the shake (0.17 px RMS) lower than taking
#: it whole (1.29, 2.32, 0.44) or none of it (the frame-to-frame motion: 7.15, 9.53, 0.31).
KEY_BLEND = 0.3
#: Most mean distance (working pixels) between the key frame's measure of the motion and
#: the frame-to-frame one for the former to be taken; further, a new key.
KEY_AGREE = 2.0
#: Quantisation of the colour model: bits kept per RGB channel.
_BITS = 4


@dataclass
class Followed:
    """One object's state: its mask on the working copy (float32 0..1), its colour model
    (object and surroundings histograms), the area it had when found, whether it is lost."""

    soft: np.ndarray
    foreground: np.ndarray
    background: np.ndarray
    found_area: float
    lost: bool = False
    # How much the moved mask counts against the colour model in the edge band: a mask
    # held to a detector's box (:mod:`._reanchor`) trusts the colours more.
    prior: float = PRIOR_WEIGHT
    # The key frame the motion is measured from (its grey copy and the object's corners
    # on it, OpenCV's coordinates) and its pose; the poses (3x3 maps from the first
    # frame's pixels) of the last frame as measured and as given out.
    key_gray: np.ndarray | None = None
    key_points: np.ndarray | None = None
    key_pose: np.ndarray = field(default_factory=lambda: np.eye(3))
    measured: np.ndarray = field(default_factory=lambda: np.eye(3))
    shown: np.ndarray = field(default_factory=lambda: np.eye(3))


@dataclass
class FollowStep:
    """What :meth:`Follower.step` found on a frame: ``cut`` (a scene cut: nothing was
    followed), and per object its full-resolution ``masks`` (None when lost) and
    ``motions`` (2x3 similarity from the previous frame's pixels to this one's, None when
    lost)."""

    cut: bool
    masks: list[np.ndarray | None]
    motions: list[np.ndarray | None]


def _colour_index(small: np.ndarray) -> np.ndarray:
    """Each pixel's colour bin, ``(h, w)`` int32 in ``[0, 2**(3 * _BITS))``."""
    q = (small >> (8 - _BITS)).astype(np.int32)
    return (q[..., 0] << (2 * _BITS)) | (q[..., 1] << _BITS) | q[..., 2]


def _histogram(index: np.ndarray, where: np.ndarray) -> np.ndarray:
    counts = np.bincount(index[where], minlength=1 << (3 * _BITS)).astype(np.float32)
    return counts / max(float(counts.sum()), 1.0)


def _scene_histogram(small: np.ndarray) -> np.ndarray:
    hist = cv2.calcHist([small], [0, 1, 2], None, [8, 8, 8], [0, 256, 0, 256, 0, 256])
    return cv2.normalize(hist, hist).astype(np.float32)


class Follower:
    """Follows masks over a clip's frames: :meth:`start` on a frame with its masks, then
    :meth:`step` on each next frame."""

    def __init__(self, work_side: int = WORK_SIDE) -> None:
        self.work_side = work_side
        self.objects: list[Followed] = []
        self._gray: np.ndarray | None = None
        self._scene: np.ndarray | None = None
        self._size: tuple[int, int] = (0, 0)  # full (width, height)
        self._work: tuple[int, int] = (0, 0)  # working (width, height)

    # ------------------------------------------------------------------ set-up
    def _small(self, pixels: np.ndarray) -> np.ndarray:
        height, width = pixels.shape[:2]
        if (width, height) != self._size:
            scale = min(1.0, self.work_side / max(width, height))
            self._size = (width, height)
            self._work = (max(1, round(width * scale)), max(1, round(height * scale)))
        rgb = np.ascontiguousarray(pixels[..., :3])
        if self._work == self._size:
            return rgb
        return cv2.resize(rgb, self._work, interpolation=cv2.INTER_AREA)

    def start(self, pixels: np.ndarray, masks: list[np.ndarray]) -> None:
        """Begin following ``masks`` (full-resolution, one per object) from ``pixels``."""
        small = self._small(pixels)
        self._gray = cv2.cvtColor(small, cv2.COLOR_RGB2GRAY)
        self._scene = _scene_histogram(small)
        index = _colour_index(small)
        self.objects = []
        for mask in masks:
            soft = cv2.resize(np.asarray(mask, np.float32), self._work, interpolation=cv2.INTER_AREA)
            inside = soft > 0.5
            area = float(np.count_nonzero(inside))
            around = self._surroundings(inside, area)
            self.objects.append(
                Followed(soft, _histogram(index, inside), _histogram(index, around), max(area, 1.0), lost=area < 1)
            )

    def reseed(self, index: int, pixels: np.ndarray, mask: np.ndarray) -> np.ndarray:
        """Follow object ``index`` afresh from ``mask`` (full resolution) on ``pixels``, the
        frame :meth:`step` last took: its mask, colour model and size when found as
        :meth:`start` makes them, its key frame forgotten (a detector's fresh cut replaces a
        mask that drifted, and what the band had learnt on the way). Returns the mask as
        followed from here (full resolution)."""
        small = self._small(pixels)
        soft = cv2.resize(np.asarray(mask, np.float32), self._work, interpolation=cv2.INTER_AREA)
        inside = soft > 0.5
        area = float(np.count_nonzero(inside))
        colours = _colour_index(small)
        around = self._surroundings(inside, area)
        prior = self.objects[index].prior
        obj = Followed(soft, _histogram(colours, inside), _histogram(colours, around), max(area, 1.0), area < 1, prior)
        self.objects[index] = obj
        return self._full(obj.soft)

    def keep_within(self, index: int, box: tuple[float, float, float, float]) -> np.ndarray:
        """Object ``index``'s mask without what lies outside ``box`` (``(x0, y0, x1, y1)``
        full-resolution pixels): the mask as followed from here (full resolution)."""
        obj = self.objects[index]
        sx, sy = self._work[0] / self._size[0], self._work[1] / self._size[1]
        x0, y0 = max(int(np.floor(box[0] * sx)), 0), max(int(np.floor(box[1] * sy)), 0)
        x1, y1 = int(np.ceil(box[2] * sx)), int(np.ceil(box[3] * sy))
        within = np.zeros(obj.soft.shape, bool)
        within[y0 : max(y1, y0), x0 : max(x1, x0)] = True
        obj.soft[~within] = 0.0
        return self._full(obj.soft)

    @staticmethod
    def _surroundings(inside: np.ndarray, area: float) -> np.ndarray:
        """A ring around the object, about a third of its size wide: its local background."""
        radius = max(3, int(0.3 * np.sqrt(max(area, 1.0))))
        grown = cv2.dilate(inside.view(np.uint8), cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1,) * 2))
        return grown.astype(bool) & ~inside

    # ------------------------------------------------------------------ a frame
    def step(self, pixels: np.ndarray) -> FollowStep:
        """Follow every object onto ``pixels`` (the next frame)."""
        small = self._small(pixels)
        gray = cv2.cvtColor(small, cv2.COLOR_RGB2GRAY)
        scene = _scene_histogram(small)
        if cv2.compareHist(self._scene, scene, cv2.HISTCMP_BHATTACHARYYA) > CUT_DISTANCE:
            self._gray, self._scene = gray, scene
            return FollowStep(True, [None] * len(self.objects), [None] * len(self.objects))
        index = _colour_index(small)
        taken = np.zeros(gray.shape, bool)
        masks, motions = [], []
        for obj in self.objects:
            mask, motion = None, None
            if not obj.lost:
                mask, motion = self._follow(obj, gray, index, taken)
            masks.append(mask)
            motions.append(motion)
        self._gray, self._scene = gray, scene
        return FollowStep(False, masks, motions)

    def _motion(self, obj: Followed, gray: np.ndarray) -> np.ndarray | None:
        """The object's motion from the previous frame to this one: a 2x3 affine map
        between pixel-centre coordinates of the working copy, None when it cannot be
        measured. Its whole-pixel shift is found by matching its previous pixels (masked
        template matching over its box and a margin), then refined by :meth:`_tracked`
        (dense optical flow, on a small object over a busy background, smoothed its motion
        away into the background's)."""
        inside = obj.soft > 0.5
        box = _box(inside)
        if box is None:
            return None
        bx0, by0, bx1, by1 = box
        margin = max(int(ROI_MARGIN * max(bx1 - bx0, by1 - by0)), MIN_MARGIN)
        height, width = gray.shape
        x0, y0 = max(bx0 - margin, 0), max(by0 - margin, 0)
        x1, y1 = min(bx1 + margin, width), min(by1 + margin, height)
        here = np.ascontiguousarray(gray[y0:y1, x0:x1])
        template = np.ascontiguousarray(self._gray[by0:by1, bx0:bx1])
        weight = np.ascontiguousarray(inside[by0:by1, bx0:bx1].astype(np.uint8))
        found = cv2.matchTemplate(here, template, cv2.TM_SQDIFF, mask=weight)
        _, _, (mx, my), _ = cv2.minMaxLoc(np.nan_to_num(found, nan=np.inf, posinf=np.inf))
        dx, dy = mx - (bx0 - x0), my - (by0 - y0)
        return self._tracked(obj, inside, gray, (dx, dy))

    def _tracked(self, obj: Followed, inside: np.ndarray, gray: np.ndarray, shift: tuple[int, int]) -> np.ndarray:
        """The similarity that moves the object's corners (features inside it, off its edge)
        from the previous frame to where pyramidal Lucas-Kanade finds them in this one,
        starting from ``shift``, keeping those that track back to where they started; the
        whole-pixel ``shift`` alone when too few track. The similarity is then measured
        again from the key frame (:meth:`_keyed`), so its errors do not add up frame
        after frame."""
        dx, dy = shift
        shifted = np.array([[1.0, 0.0, dx], [0.0, 1.0, dy]])
        inner = cv2.erode(inside.view(np.uint8), np.ones((5, 5), np.uint8))
        corners = cv2.goodFeaturesToTrack(self._gray, _CORNERS, 0.01, 3, mask=inner)
        if corners is None or len(corners) < 6:
            return _shifted(self._keyed(obj, shifted, None, gray), 0.5)
        start = corners.reshape(-1, 1, 2).astype(np.float32)
        guess = start + np.float32([dx, dy])
        moved, good = _tracked_both_ways(self._gray, gray, start, guess, levels=3)
        matrix = None
        if np.count_nonzero(good) >= 6:
            matrix, _ = cv2.estimateAffinePartial2D(
                start[good], moved[good], method=cv2.RANSAC, ransacReprojThreshold=1.5
            )
        if matrix is None:
            return _shifted(self._keyed(obj, shifted, None, gray), 0.5)
        matrix = self._keyed(obj, matrix, start, gray)
        return _shifted(matrix, 0.5)  # OpenCV's pixel centres are at whole numbers, jeanscv's at +0.5

    def _keyed(self, obj: Followed, step: np.ndarray, corners: np.ndarray | None, gray: np.ndarray) -> np.ndarray:
        """The motion to give out for ``step`` (2x3, previous frame to this one, OpenCV's
        coordinates): the object's pose measured again from its key frame (the key frame's
        corners tracked to this frame from where ``step`` puts them), and the motion that
        takes the pose given out on the last frame a share :data:`KEY_BLEND` of the way
        from where ``step`` puts it to that measure.

        Frame-to-frame measures are each a hundredth of a pixel off, which on bench.clips'
        moving clip added up to 9 px over 300 frames (the jeans carried by them drifted as
        much); the key frame's measure does not add up, but taken whole each new key's
        correction was a visible step (0.51 px RMS frame-to-frame shake on that clip, 0.17
        blended). Where too few key corners track, or the measure disagrees with ``step``,
        the previous frame (``corners``: the object's corners on it; None: none to track)
        becomes the key and ``step`` is the measure."""
        step3 = np.vstack([step, [0.0, 0.0, 1.0]])
        predicted = step3 @ obj.measured
        measured = None
        if obj.key_gray is not None and obj.key_gray.shape == gray.shape:
            expected = predicted @ np.linalg.inv(obj.key_pose)  # key frame -> this one
            points = obj.key_points
            guess = (points.reshape(-1, 2) @ expected[:2, :2].T + expected[:2, 2]).reshape(-1, 1, 2)
            moved, good = _tracked_both_ways(obj.key_gray, gray, points, guess.astype(np.float32), levels=2)
            if np.count_nonzero(good) >= max(6, KEY_KEEP * len(points)):
                matrix, _ = cv2.estimateAffinePartial2D(
                    points[good], moved[good], method=cv2.RANSAC, ransacReprojThreshold=1.5
                )
                if matrix is not None:
                    flat = points.reshape(-1, 2)
                    apart = flat @ (matrix[:, :2] - expected[:2, :2]).T + (matrix[:, 2] - expected[:2, 2])
                    if float(np.linalg.norm(apart, axis=1).mean()) <= KEY_AGREE:
                        measured = np.vstack([matrix, [0.0, 0.0, 1.0]]) @ obj.key_pose
        if measured is None:  # the previous frame becomes the key
            obj.key_gray, obj.key_points, obj.key_pose = (
                (self._gray, corners, obj.measured) if corners is not None else (None, None, obj.measured)
            )
            measured = predicted
        carried = step3 @ obj.shown
        shown = carried + KEY_BLEND * (measured - carried)
        frame = shown @ np.linalg.inv(obj.shown)
        obj.measured, obj.shown = measured, shown
        return frame[:2]

    def _follow(self, obj: Followed, gray, index, taken) -> tuple[np.ndarray | None, np.ndarray | None]:
        motion = self._motion(obj, gray)
        if motion is None or not np.isfinite(motion).all():
            obj.lost = True
            return None, None
        # The mask moves as a whole; the edge band is then re-decided by colour, which
        # takes up what moved on its own (a leg, the tail). All of it on the moved box and
        # a margin that holds the band and the surroundings ring: not on the whole frame.
        x0, y0, x1, y1 = self._reach(obj, motion)
        if x1 <= x0 or y1 <= y0:
            obj.lost = True
            return None, None
        rigid = _warp(
            obj.soft, np.array([[1, 0, -x0], [0, 1, -y0]]) @ np.vstack([motion, [0, 0, 1]]), (x1 - x0, y1 - y0)
        )
        colours = index[y0:y1, x0:x1]
        refined = self._refine(obj, rigid, colours) & ~taken[y0:y1, x0:x1]
        area = float(np.count_nonzero(refined))
        if area < max(4.0, LOST_FRACTION * obj.found_area) or self._unlike(obj, refined, colours):
            obj.lost = True
            return None, None
        taken[y0:y1, x0:x1] |= refined
        # The colour model drifts with the light; the soft mask is the next frame's prior.
        around = self._surroundings(refined, area)
        obj.foreground = (1 - MODEL_RATE) * obj.foreground + MODEL_RATE * _histogram(colours, refined)
        obj.background = (1 - MODEL_RATE) * obj.background + MODEL_RATE * _histogram(colours, around)
        obj.soft = np.zeros_like(obj.soft)
        obj.soft[y0:y1, x0:x1] = cv2.GaussianBlur(refined.astype(np.float32), (3, 3), 0.7)
        return self._full(obj.soft), self._to_full(motion)

    def _reach(self, obj: Followed, motion: np.ndarray) -> tuple[int, int, int, int]:
        """``(x0, y0, x1, y1)``: the object's box moved by ``motion``, with room for the edge
        band and the surroundings ring, on the working copy."""
        box = _box(obj.soft > 0.5)
        if box is None:
            return 0, 0, 0, 0
        bx0, by0, bx1, by1 = box
        corners = np.array([[bx0, by0], [bx1, by0], [bx0, by1], [bx1, by1]], np.float64)
        moved = corners @ motion[:, :2].T + motion[:, 2]
        room = int(0.35 * np.sqrt((bx1 - bx0) * (by1 - by0))) + 6
        width, height = self._work
        x0, y0 = np.floor(moved.min(axis=0)).astype(int) - room
        x1, y1 = np.ceil(moved.max(axis=0)).astype(int) + room
        return max(int(x0), 0), max(int(y0), 0), min(int(x1), width), min(int(y1), height)

    @staticmethod
    def _unlike(obj: Followed, mask: np.ndarray, index: np.ndarray) -> bool:
        """Whether most of ``mask`` has the colours of the object's surroundings rather
        than its own: what is left where an object went out of the frame or behind
        something is background."""
        colours = index[mask]
        fg, bg = obj.foreground[colours], obj.background[colours]
        return float(np.mean(fg >= bg)) < UNLIKE

    def _refine(self, obj: Followed, rigid: np.ndarray, index) -> np.ndarray:
        """The moved mask with its edge band re-decided by the colour model:
        outside the band around the rigidly moved mask nothing is the object, inside it all is."""
        inside = rigid > 0.5
        area = max(float(np.count_nonzero(inside)), 1.0)
        radius = max(2, int(round(BAND * np.sqrt(area))))
        kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1,) * 2)
        inside8 = inside.view(np.uint8)
        band = cv2.dilate(inside8, kernel).astype(bool) & ~cv2.erode(inside8, kernel).astype(bool)
        colours = index[band]
        fg, bg = obj.foreground[colours], obj.background[colours]
        likely = (fg + 1e-4) / (fg + bg + 2e-4)
        score = inside.astype(np.float32)
        score[band] = obj.prior * rigid[band] + (1 - obj.prior) * likely
        score = cv2.GaussianBlur(score, (5, 5), 1.0)  # neighbours agree: no speckle on the edge
        refined = score > 0.5
        refined = cv2.morphologyEx(refined.view(np.uint8), cv2.MORPH_OPEN, np.ones((3, 3), np.uint8)).astype(bool)
        return largest_component(refined)

    def _full(self, soft: np.ndarray) -> np.ndarray:
        if self._work == self._size:
            return soft > 0.5
        return cv2.resize(soft, self._size, interpolation=cv2.INTER_LINEAR) > 0.5

    def _to_full(self, motion: np.ndarray | None) -> np.ndarray | None:
        """A working-copy similarity in full-resolution pixels (centres at +0.5 in both)."""
        if motion is None:
            return None
        sx, sy = self._size[0] / self._work[0], self._size[1] / self._work[1]
        to_small = np.array([[1 / sx, 0, 0], [0, 1 / sy, 0], [0, 0, 1]])
        to_full = np.array([[sx, 0, 0], [0, sy, 0], [0, 0, 1]])
        full = to_full @ np.vstack([motion, [0, 0, 1]]) @ to_small
        return full[:2]


def _tracked_both_ways(
    before: np.ndarray, after: np.ndarray, points: np.ndarray, guess: np.ndarray, levels: int
) -> tuple[np.ndarray, np.ndarray]:
    """``points`` (``(N, 1, 2)`` float32) of the grey image ``before`` tracked into ``after``
    by pyramidal Lucas-Kanade from ``guess``: ``(where, good)``, ``good`` the points found
    that track back to within a pixel of where they started."""
    flags = cv2.OPTFLOW_USE_INITIAL_FLOW
    moved, found, _ = cv2.calcOpticalFlowPyrLK(
        before, after, points, guess.copy(), winSize=(15, 15), maxLevel=levels, flags=flags
    )
    back, found_back, _ = cv2.calcOpticalFlowPyrLK(
        after, before, moved, points.copy(), winSize=(15, 15), maxLevel=levels, flags=flags
    )
    apart = np.linalg.norm((back - points).reshape(-1, 2), axis=1)
    return moved, (found.ravel() == 1) & (found_back.ravel() == 1) & (apart < 1.0)


def _box(mask: np.ndarray) -> tuple[int, int, int, int] | None:
    """``(x0, y0, x1, y1)`` of a bool mask, None when empty."""
    if not mask.any():
        return None
    x, y, width, height = mask_box(mask)
    return x, y, x + width, y + height


def _shifted(matrix: np.ndarray, by: float) -> np.ndarray:
    """The 2x3 ``matrix`` between coordinates shifted by ``by`` on both axes: the same map
    between pixel centres at whole numbers (OpenCV's, ``by=0.5`` from them) and at +0.5."""
    shift = np.array([[1.0, 0.0, by], [0.0, 1.0, by], [0.0, 0.0, 1.0]])
    return (shift @ np.vstack([matrix, [0.0, 0.0, 1.0]]) @ np.linalg.inv(shift))[:2]


def _warp(soft: np.ndarray, motion: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """``soft`` moved by ``motion`` (2x3 between pixel-centre coordinates)."""
    matrix = _shifted(motion, -0.5)
    return cv2.warpAffine(soft, matrix, size, flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)


__all__ = ["CUT_DISTANCE", "FollowStep", "Follower", "WORK_SIDE"]
