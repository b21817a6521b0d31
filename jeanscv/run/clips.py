"""Jeans on a clip, frame by frame: :func:`apply_jeans_to_clip` (a generator of frames)
and :func:`write_jeans_clip` (a clip file in, a clip file and a report out).

A thin layer over the still-photo pipeline: the first frame is
:func:`jeanscv.pipeline.apply_jeans` itself (automatic finding, or the clicks, box or
mask of ``options``), so its picture is the photo's. Each later frame takes its masks from
:class:`jeanscv.subject.follow.Follower` (tracking and an edge re-segmentation), frames
them as a photo's silhouettes are framed, carries the previous frame's jeans by the
object's motion (their move as a whole blended with the last one's: :func:`carried_jeans`)
and settles them with :func:`jeanscv.fitting.follow.refit`, and paints them
with the photo's :func:`jeanscv.paint.figures.composite`. A scene cut finds the subject
afresh (as the first frame, automatically); an object that leaves the frame loses its
jeans, and is looked for again (automatically, once a second of clip) until it comes back.

With the detector (``detector="auto"``, the default), the followed objects are held to
its boxes every few frames (:mod:`jeanscv.subject._reanchor`), and cut again inside them
where the mask drifted; the jeans then glide onto a fresh fit of the new mask, as they do
when they have slid off the followed mask.

A clip larger than :data:`WORK_SIDE` is followed, held and fitted on a working copy of each
frame, and painted at full size (issue 48, "Large frames").
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import JeansError
from ..geometry import apply_affine
from ..io.clip import ClipFrame, ClipLimits, ClipReader, iter_frames
from ..io.write import on_white
from ..options import JeansOptions
from ..report import FittedObject
from ..subject.silhouettes import Silhouette
from ._working import rescaled, working_copy

#: Seconds of clip between two looks for a lost subject (a full automatic segmentation).
LOOK_AGAIN_SECONDS = 1.0
#: Most Bhattacharyya distance between a found object's colours and the lost one's for
#: the found one to be taken as the lost subject come back.
SAME_SUBJECT = 0.6
#: Shape agreement (IoU of the followed mask with the anchor frame's mask carried by the
#: motion since) at and above which the jeans are fully anchored: what the follower's edge
#: re-decision changes on a rigid subject (0.9 and more on bench.clips' clips) is taken as
#: segmentation noise, not as the subject's shape.
SHAPE_KEPT = 0.85
#: ... and at or below which the subject has changed shape (sat down, turned): the anchor
#: fades out between the two, and below this the jeans are anchored afresh where they are.
SHAPE_CHANGED = 0.7
#: While the detector holds the object (its last detection matched it), jeans whose share
#: on the followed mask fell by more than this since they were anchored are anchored on a
#: fresh fit of it (as after a cut afresh). Without it the jeans slid off the shared clips'
#: animals with the motion's errors (the cows' jeans 0.99 on the mask on frame 0, 0.3 to
#: 0.5 by frame 60); at 0.05, checked only on frames with a detection, a fresh fit moved
#: jeans that were fine elsewhere on bench.clips' moving dog (drift 1.2 -> 30 px over 150
#: frames). Checked on every frame the object is held rather than only on the frames with a
#: detection, the cows' jeans no longer wait up to 5 frames on a mask that has lost its
#: first frame's extra (their share on the mask 0.99 -> 0.77 by frame 4): bench.clips
#: --real, frames with the jeans >= 85% on the animal, camel and cows: 13% and 87% checked
#: on detections at 0.1; every frame 12% and 88% at 0.1, 17% and 91% at 0.07, 11% and 90%
#: at 0.05 (the camel's jeans then shook as a whole 1.41 px, over its own 1.38); the
#: synthetic clips the same at each.
JEANS_LEFT = 0.07
#: Frames over which the anchor's weight grows after a fresh fit, so the jeans start
#: moving gently: 1 gave a jitter (RMS second difference) of 3.1 and 2.2 px on the shared
#: camel and cows clips, 5 gives 2.0 and 1.4 (10: 1.9 and 1.3, but the camel's jeans on
#: the animal in 6% of frames against 9%: slower to arrive).
GLIDE_FRAMES = 5
#: The jeans move as a whole (their centroid) by this share of this frame's measured
#: motion and the rest of their move onto the frame before; they turn and scale as
#: measured (:func:`carried_jeans`). On a walking camel the measured motion moved its
#: jeans 1.4, 2.5, 6.9, 1.3 and 4.3 px on its first frames while it walked about 1.5 px
#: a frame (its swinging legs and the sand between them hold corners that move unlike its
#: body). The mask still moves by the measured motion; the jeans, settled on the mask and
#: held to their anchor, follow it within a frame or two. bench.clips --real, their
#: shake as a whole against the animal's own (1.38 and 1.36 px): camel 1.78 -> 1.23,
#: cows 1.31 -> 1.08; frames with the jeans on the animal 9% -> 13% and 87% either way;
#: masks unchanged (0.3: 1.07 and 1.00, 10% and 88%). bench.clips' synthetic clips: the
#: jeans follow the subject within 0.09 px a frame (0.11), drift as before. The whole
#: motion blended instead (a mean of the matrices) lagged a turning, growing 4K subject
#: (tests/test_clips.py's) off its edge.
CARRY_SHARE = 0.5
#: Iterations of such a fresh fit: 30, 50 and 100 gave the same figures; 30 takes 0.03 s,
#: 100 0.3 s.
FRESH_ITERATIONS = 30
#: Longest side (pixels) of the working copy a larger clip's later frames are followed,
#: held to the detector and fitted on (issue 48, "Large frames"); the jeans are painted on
#: the frame at full size. Clips up to this size are followed on their own frames.
WORK_SIDE = 1280


@dataclass
class ClipFrameResult:
    """One frame of :func:`apply_jeans_to_clip`: the picture and the objects that wear jeans.

    ``objects``: one entry per followed object, None where it is lost (out of the frame);
    ``event``: ``start`` (the first frame, the still-photo pipeline), ``follow``, ``cut`` (a
    scene cut: found afresh), ``key`` (a key frame of the clicks file: found from its
    clicks), ``found`` (a lost subject found again) or ``lost`` (no object wears jeans on
    this frame); ``original``: the frame as decoded.
    """

    index: int
    time: float
    duration: float
    image: np.ndarray
    objects: list[FittedObject | None]
    event: str
    original: np.ndarray | None = None  # the frame as decoded

    def report(self) -> dict:
        """This frame's entry in the clip report: per object its image vertices, box,
        posture and objective (None where lost)."""
        from ..fitting.posture import posture_name, tilt_degrees
        from ..subject.silhouettes import box_of

        entries: list[dict | None] = []
        for obj in self.objects:
            if obj is None:
                entries.append(None)
                continue
            vertices = obj.silhouette.framing.to_image(obj.fit.vertices)
            tilt = tilt_degrees(vertices, obj.fit.garment)
            entries.append(
                {
                    "vertices_image": np.round(vertices, 2).tolist(),
                    "box": list(box_of(obj.silhouette)),
                    "method": obj.silhouette.method,
                    "objective": float(f"{obj.fit.objective:.6g}"),
                    "tilt_degrees": round(tilt, 2),
                    "posture": posture_name(tilt),
                }
            )
        return {"frame": self.index, "time": round(self.time, 4), "event": self.event, "objects": entries}


@dataclass
class _Track:
    """One followed object: what its last frame wore (None once lost), and its anchor: the
    jeans and mask of the frame they were anchored on (image pixels) and the subject's
    motion since (2x3)."""

    fitted: FittedObject | None
    first: FittedObject  # as found: its fit's preset and garment serve every frame
    anchor: np.ndarray = None  # type: ignore[assignment]
    reference: np.ndarray = None  # type: ignore[assignment]
    moved: np.ndarray = dataclasses.field(default_factory=lambda: np.eye(3)[:2])
    ramp: int = GLIDE_FRAMES  # frames since the anchor was set on a fresh fit
    share: float = 1.0  # the share of the anchored jeans on their mask
    carry: np.ndarray | None = None  # the jeans' move as a whole onto the last frame (x, y)

    def __post_init__(self) -> None:
        if self.anchor is None and self.fitted is not None:
            self.anchor_on(self.fitted)

    def anchor_on(self, fitted: FittedObject) -> None:
        """Anchor the jeans where ``fitted`` has them."""
        self.anchor = fitted.silhouette.framing.to_image(fitted.fit.vertices)
        self.reference = np.asarray(fitted.silhouette.mask) >= 0.5
        self.moved = np.eye(3)[:2]
        self.ramp = GLIDE_FRAMES

    def anchor_at(self, vertices: np.ndarray, silhouette: Silhouette) -> None:
        """Anchor the jeans at ``vertices`` (image pixels, a fresh fit on ``silhouette``): the
        jeans glide there over the next frames, the anchor's weight growing over
        :data:`GLIDE_FRAMES` so they start moving gently."""
        self.anchor = np.asarray(vertices, np.float64)
        self.reference = np.asarray(silhouette.mask) >= 0.5
        self.moved = np.eye(3)[:2]
        self.ramp = 0
        self.share = _share_on(silhouette, self.anchor)

    def anchoring(self, mask: np.ndarray, motion: np.ndarray | None) -> tuple[np.ndarray, float]:
        """The anchor carried onto this frame by ``motion`` (image pixels) and its weight
        (:data:`~jeanscv.fitting.follow.FOLLOW_ANCHORING` while ``mask`` keeps the anchor
        frame's shape, fading to 0 as it changes shape)."""
        from ..fitting.follow import FOLLOW_ANCHORING
        from ..subject.consensus import iou

        if motion is not None:
            self.moved = (np.vstack([motion, [0.0, 0.0, 1.0]]) @ np.vstack([self.moved, [0.0, 0.0, 1.0]]))[:2]
        kept = iou(self._carried_reference(mask.shape), mask)
        share = float(np.clip((kept - SHAPE_CHANGED) / (SHAPE_KEPT - SHAPE_CHANGED), 0.0, 1.0))
        self.ramp += 1
        share *= min(1.0, self.ramp / GLIDE_FRAMES)
        return apply_affine(self.moved, self.anchor), FOLLOW_ANCHORING * share

    def _carried_reference(self, shape: tuple[int, int]) -> np.ndarray:
        """The anchor frame's mask moved by the motion since, ``shape`` (H, W) bool."""
        import cv2

        # OpenCV's warp has pixel centres at whole numbers, jeanscv's maps at +0.5.
        shift = np.array([[1.0, 0.0, 0.5], [0.0, 1.0, 0.5], [0.0, 0.0, 1.0]])
        warp = (np.linalg.inv(shift) @ np.vstack([self.moved, [0.0, 0.0, 1.0]]) @ shift)[:2]
        height, width = shape
        return cv2.warpAffine(self.reference.view(np.uint8), warp, (width, height), flags=cv2.INTER_NEAREST).view(bool)


def carried_jeans(
    vertices: np.ndarray, motion: np.ndarray, previous: np.ndarray | None, share: float = CARRY_SHARE
) -> tuple[np.ndarray, np.ndarray]:
    """The jeans ``vertices`` (``(N, 2)`` image pixels) carried onto this frame by the
    measured ``motion`` (2x3 affine), their move as a whole (their centroid's) being
    ``share`` of the measured one and the rest ``previous`` (their move onto the last
    frame; the measured one alone where None): ``(vertices, move)``. The turn and scale
    about their centroid are the measured ones."""
    vertices = np.asarray(vertices, np.float64)
    centre = vertices.mean(axis=0)
    measured = apply_affine(motion, centre[None])[0] - centre
    move = measured if previous is None else share * measured + (1.0 - share) * np.asarray(previous)
    return apply_affine(motion, vertices) + (move - measured), move


def _share_on(silhouette: Silhouette, vertices: np.ndarray) -> float:
    """The share of the jeans polygon (``vertices``, image pixels) on ``silhouette``'s
    canvas: how much of them its mask still holds."""
    import cv2

    canvas = np.asarray(silhouette.canvas) >= 0.5
    on_canvas = silhouette.framing.to_canvas(vertices)
    polygon = np.zeros(canvas.shape, np.uint8)
    cv2.fillPoly(polygon, [np.round((on_canvas - 0.5) * 16).astype(np.int32)], 1, lineType=cv2.LINE_8, shift=4)
    # The polygon's whole area (the shoelace formula): the canvas holds only the mask's
    # framing, and the jeans may reach beyond it.
    x, y = on_canvas[:, 0], on_canvas[:, 1]
    area = 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))
    inside = polygon.view(bool)
    return float(np.count_nonzero(inside & canvas)) / max(area, float(np.count_nonzero(inside)), 1.0)


def _framed(mask: np.ndarray, method: str) -> Silhouette:
    """A followed mask as a photo's object is framed (``details['box']`` like a photo's)."""
    from ..geometry import mask_box
    from ..subject.framing import frame_mask

    canvas, framing = frame_mask(mask)
    return Silhouette(mask, canvas, framing, method, None, {"box": list(mask_box(mask))})


def _automatic(options: JeansOptions) -> JeansOptions:
    """The options without anything that names frame 0's pixels: for a frame found afresh."""
    return options.replace(points=(), background_points=(), box=None, clicks=None, mask=None)


class _ClipRun:
    """The state of one clip's run: the follower, the tracks, the options."""

    def __init__(self, options: JeansOptions, detect: Callable | None = None) -> None:
        from ..device import resolve_backend, resolve_device
        from ..subject.follow import Follower

        self.options = options
        self.reanchor = None  # holds the followed objects to the detector's boxes
        if options.detector != "none":
            from ..detect import detect as shipped
            from ..subject._reanchor import Reanchor

            self.reanchor = Reanchor(detect or shipped, options.subject)
        self.device = resolve_device(options.device)
        self.backend = resolve_backend(options.backend, self.device)
        self.follower = Follower()
        self.tracks: list[_Track] = []
        self.kind = "photo"
        self.looked_at = -np.inf
        self.missed = ""  # why the last automatic look found nothing
        self.fresh = 0  # fresh fits made to anchor the jeans again (for the benches)
        # The working copy's size against the frame's, (sx, sy): 1 for frames up to
        # WORK_SIDE; the tracks, the follower and the detector's hold live on that copy.
        self.scale = (1.0, 1.0)

    # ------------------------------------------------------------ working size
    def _working(self, pixels: np.ndarray) -> np.ndarray:
        """``pixels`` at most :data:`WORK_SIDE` long (the frame itself when it fits, or for
        a drawing); sets :attr:`scale`."""
        if self.kind != "photo":
            self.scale = (1.0, 1.0)
            return pixels
        pixels, self.scale = working_copy(pixels, WORK_SIDE)
        return pixels

    def _rescaled(self, fitted: FittedObject, to_work: bool, shape: tuple[int, int]) -> FittedObject:
        """``fitted`` on the working copy (``to_work``) or back on the frame at full size."""
        sx, sy = self.scale if to_work else (1.0 / self.scale[0], 1.0 / self.scale[1])
        return rescaled(fitted, (sx, sy), to_work, shape)

    # ------------------------------------------------------------ finding afresh
    def find(self, frame: ClipFrame, options: JeansOptions, event: str) -> ClipFrameResult:
        """The still-photo pipeline on ``frame``: its picture, and new tracks from its objects."""
        from ..pipeline import apply_jeans

        result = apply_jeans(frame.pixels, options)
        self.kind = result.kind
        # A large frame's objects are followed on its working copy (the picture is the photo's).
        pixels = self._working(frame.pixels)
        objects = list(result.objects)
        if self.scale != (1.0, 1.0):
            objects = [self._rescaled(obj, True, pixels.shape[:2]) for obj in objects]
        self.tracks = [_Track(obj, obj) for obj in objects]
        for track in self.tracks:
            if self.kind == "photo":
                track.share = _share_on(track.first.silhouette, track.anchor)
        # The follower sees a transparent clip's clear pixels as white (their RGB is whatever the palette had).
        self.follower.start(on_white(pixels), [obj.silhouette.mask for obj in objects])
        if self.reanchor is not None and self.kind == "photo":
            given = bool(
                options.points or options.box is not None or options.clicks is not None or options.mask is not None
            )
            details = [obj.silhouette.details or {} for obj in objects]
            masks = [obj.silhouette.mask for obj in objects]
            self.reanchor.start(pixels, masks, details, given, self.follower)
        return ClipFrameResult(frame.index, frame.time, frame.duration, result.image, list(result.objects), event)

    def start(self, frame: ClipFrame, options: JeansOptions, event: str = "start") -> ClipFrameResult:
        """The first frame, or a frame while nothing has been found yet: the still-photo
        pipeline. With the subject given (clicks, a box, a mask) its failure is the clip's;
        found automatically, a frame with nothing to find goes by without jeans, and the
        next look is :data:`LOOK_AGAIN_SECONDS` later."""
        given = options.points or options.box is not None or options.clicks is not None or options.mask is not None
        if frame.index == 0 and given:
            return self.find(frame, options, "start")
        if frame.time - self.looked_at < LOOK_AGAIN_SECONDS:
            return ClipFrameResult(frame.index, frame.time, frame.duration, frame.pixels, [], "lost")
        self.looked_at = frame.time
        try:
            return self.find(frame, options if frame.index == 0 else _automatic(options), event)
        except JeansError as exc:
            self.missed = str(exc)
            self.tracks = []  # nothing to follow: the next frames look again
            return ClipFrameResult(frame.index, frame.time, frame.duration, frame.pixels, [], "lost")

    def look_again(self, frame: ClipFrame) -> ClipFrameResult | None:
        """Every :data:`LOOK_AGAIN_SECONDS` while every object is lost: the subject found
        automatically, if it looks like the one that left; else None."""
        if frame.time - self.looked_at < LOOK_AGAIN_SECONDS:
            return None
        self.looked_at = frame.time
        lost_models = [obj.foreground for obj in self.follower.objects]
        previous = self.tracks, self.follower.objects
        try:
            found = self.find(frame, _automatic(self.options), "found")
        except JeansError:
            return None
        import cv2

        # The colours of what was found against those of what was lost.
        models = [obj.foreground for obj in self.follower.objects]
        same = not lost_models or any(
            cv2.compareHist(lost.astype(np.float32), new.astype(np.float32), cv2.HISTCMP_BHATTACHARYYA) < SAME_SUBJECT
            for lost in lost_models
            for new in models
        )
        if not same:
            self.tracks, self.follower.objects = previous
            return None
        return found

    # ------------------------------------------------------------ following
    def follow(self, frame: ClipFrame) -> ClipFrameResult:
        """A frame after the first: its masks followed, its jeans carried and settled."""
        if self.kind == "silhouette":
            return self._follow_drawing(frame)
        pixels = self._working(frame.pixels)  # a large frame: its working copy
        step = self.follower.step(on_white(pixels))
        if step.cut:  # found afresh; a scene with nothing to find goes by without jeans
            self.looked_at = -np.inf
            return self.start(frame, _automatic(self.options), "cut")
        image = frame.pixels
        masks, recut, held = step.masks, [False] * len(step.masks), [False] * len(step.masks)
        if self.reanchor is not None:
            masks, recut = self.reanchor.step(on_white(pixels), self.follower, step.masks, step.motions)
            held = self.reanchor.holding()
        objects: list[FittedObject | None] = []
        for index, (track, mask, motion) in enumerate(zip(self.tracks, masks, step.motions)):
            if mask is None or track.fitted is None or not mask.any():
                track.fitted = None
                objects.append(None)
                continue
            silhouette = _framed(mask, "follow")
            before = track.fitted.silhouette.framing.to_image(track.fitted.fit.vertices)
            carried, track.carry = (before, None) if motion is None else carried_jeans(before, motion, track.carry)
            fresh = None
            if recut[index] or (held[index] and _share_on(silhouette, carried) < track.share - JEANS_LEFT):
                # Cut afresh, or the jeans have left the followed mask: anchored on a fresh
                # fit of this frame's silhouette, where they glide over the next frames.
                fresh = self._fresh(track, silhouette, carried)
                if fresh is not None:
                    track.anchor_at(fresh, silhouette)
            anchor, anchoring = track.anchoring(mask, motion if fresh is None else None)
            track.fitted = self._settle(track, silhouette, carried, anchor, anchoring)
            if anchoring == 0.0:  # a new shape: the jeans are anchored afresh on it
                track.anchor_on(track.fitted)
                track.share = _share_on(silhouette, track.anchor)
            shown = track.fitted
            if self.scale != (1.0, 1.0):  # painted on the frame at full size
                shown = self._rescaled(shown, False, frame.pixels.shape[:2])
            objects.append(shown)
            image = self._paint(image, shown, index)
        if all(obj is None for obj in objects):
            found = self.look_again(frame)
            if found is not None:
                return found
            return ClipFrameResult(frame.index, frame.time, frame.duration, frame.pixels, objects, "lost")
        return ClipFrameResult(frame.index, frame.time, frame.duration, image, objects, "follow")

    def _settle(
        self,
        track: _Track,
        silhouette: Silhouette,
        carried: np.ndarray,
        anchor: np.ndarray | None = None,
        anchoring: float = 0.0,
    ) -> FittedObject:
        """The garment ``carried`` (image pixels) settled on ``silhouette``, pulled towards
        ``anchor`` (image pixels) by ``anchoring``."""
        from ..fitting.follow import refit

        first = track.first.fit
        start = silhouette.framing.to_canvas(carried)
        vertices, objective, terms = refit(
            silhouette.canvas,
            start,
            first.preset,
            first.garment,
            backend=self.backend,
            device=self.device,
            anchor=None if anchor is None else silhouette.framing.to_canvas(anchor),
            anchoring=anchoring,
        )
        fit = dataclasses.replace(
            first,
            vertices=vertices,
            vertices_image=silhouette.framing.to_image(vertices),
            objective=objective,
            terms=terms,
            history=first.history[:0],
            trajectory=vertices[None],
            seconds=0.0,
        )
        return FittedObject(silhouette, fit)

    def _fresh(self, track: _Track, silhouette: Silhouette, carried: np.ndarray) -> np.ndarray | None:
        """A still fit of ``silhouette`` (image pixels), None where its posture is not the
        jeans' (``carried``, image pixels): they do not flip."""
        from ..fitting.posture import posture_name, tilt_degrees
        from ..pipeline import fit

        options = self.options
        garment = track.first.fit.garment
        self.fresh += 1
        result = fit(
            silhouette,
            garment,
            options.preset,
            min(options.iterations, FRESH_ITERATIONS),
            options.seed,
            self.device,
            options.starts,
            options.posture,
            self.backend,
        )
        before = posture_name(tilt_degrees(carried, garment))
        if posture_name(tilt_degrees(result.vertices, garment)) == before:
            return silhouette.framing.to_image(result.vertices)
        return None

    def _paint(self, image: np.ndarray, fitted: FittedObject, index: int) -> np.ndarray:
        from ..paint.figures import composite

        options = self.options
        return composite(
            image, fitted.fit, fitted.silhouette, style=options.style, clip=options.clip, seed=options.seed + index
        )

    def _follow_drawing(self, frame: ClipFrame) -> ClipFrameResult:
        """A silhouette drawing's clip: each frame's shape is exact; only the fit follows."""
        from ..paint.figures import figure
        from ..subject.drawing import silhouette_from_drawing
        from ..subject.silhouettes import silhouette_from_alpha

        alpha = silhouette_from_drawing(on_white(frame.pixels))
        track = self.tracks[0]
        if alpha is None or alpha.sum() < 1.0 or track.fitted is None:
            track.fitted = None
            return ClipFrameResult(frame.index, frame.time, frame.duration, frame.pixels, [None], "lost")
        silhouette = silhouette_from_alpha(alpha, "drawing")
        track.fitted = self._settle(
            track, silhouette, track.fitted.silhouette.framing.to_image(track.fitted.fit.vertices)
        )
        image = figure(silhouette, track.fitted.fit)
        return ClipFrameResult(frame.index, frame.time, frame.duration, image, [track.fitted], "follow")


def apply_jeans_to_clip(
    source: str | os.PathLike | ClipReader | Iterable[np.ndarray | ClipFrame],
    options: JeansOptions | None = None,
    *,
    fps: float = 25.0,
    limits: ClipLimits | None = None,
    detect: Callable[[np.ndarray], list] | None = None,
    **overrides: Any,
) -> Iterator[ClipFrameResult]:
    """Jeans on every frame of a clip, as the frames come (a generator).

    ``source``: a clip file (GIF, animated WebP/PNG, MP4/MOV/WebM/MKV), an open
    :class:`~jeanscv.io.clip.ClipReader`, or any iterable of ``(H, W, 3)`` uint8 frames
    (``fps`` apart) or :class:`~jeanscv.io.clip.ClipFrame` s: a generator you feed your
    own frames to. ``options`` and ``overrides`` as for :func:`jeanscv.pipeline.apply_jeans`;
    clicks, a box or a mask refer to the first frame; a clicks file's ``frames`` add key
    frames (:func:`jeanscv.subject.clicks.key_frames`), where the subject is found afresh
    from their clicks. ``limits``: the decoding caps for a file. ``detect``: the detector
    that holds the followed objects to their boxes on later frames (a callable ``(H, W, 3)``
    uint8 -> list of :class:`jeanscv.detect.Detection`; default the shipped one, none with
    ``detector="none"``; frame 0 and frames found afresh use ``options.detector``).
    Yields a :class:`ClipFrameResult` per frame; the first frame's picture is
    ``apply_jeans(first_frame, options).image``.
    """
    options = (options or JeansOptions()).replace(**overrides)
    keys = {}
    if options.clicks is not None:
        options, keys = _with_key_frames(options)
    if isinstance(source, (str, os.PathLike)):
        with ClipReader(source, limits) as reader:
            yield from apply_jeans_to_clip(reader, options, fps=fps, detect=detect)
        return
    frames = source.frames() if isinstance(source, ClipReader) else iter_frames(source, fps)
    run = _ClipRun(options, detect)
    found = False
    for frame in frames:
        if frame.index in keys:
            result = run.find(frame, _automatic(options).replace(clicks=keys[frame.index]), "key")
        elif frame.index == 0 or not run.tracks:
            result = run.start(frame, options)
        else:
            result = run.follow(frame)
        found = found or any(obj is not None for obj in result.objects)
        result.original = frame.pixels
        yield result
    if not found:  # as a photo with nothing in it: the clip fails (a file writer keeps nothing)
        raise JeansError(f"{run.missed or 'no object found'} on any frame")


def _with_key_frames(options: JeansOptions) -> tuple[JeansOptions, dict]:
    """The options with their clicks file read, and its key frames (frame -> Clicks)."""
    from ..subject.clicks import Clicks, key_frames, read_clicks

    clicks = options.clicks
    if isinstance(clicks, (str, os.PathLike)):
        try:
            read = read_clicks(clicks)
            keys = key_frames(read)
        except JeansError as exc:
            raise JeansError(f"clicks file {os.path.basename(clicks)}: {exc}") from None
        return options.replace(clicks=read), keys
    return options, key_frames(clicks) if isinstance(clicks, Clicks) else {}


def write_jeans_clip(
    source: str | os.PathLike,
    output: str | os.PathLike,
    options: JeansOptions | None = None,
    *,
    fmt: str | None = None,
    limits: ClipLimits | None = None,
    on_frame=None,
    decorate=None,
) -> dict:
    """Jeans on the clip ``source``, written to ``output`` as ``fmt`` (default: from
    ``output``'s extension) with the source's timing, looping and audio, atomically.

    ``on_frame(ClipFrameResult)`` is called after each frame (progress);
    ``decorate(image, original) -> image`` changes each frame before it is encoded (the
    command's captions and side by side). Returns the clip
    report: the clip's size, frames, fps and duration, where decoding stopped if it ended
    before the clip did (``stopped``: :meth:`jeanscv.io.clip.ClipStop.to_json`, e.g.
    ``{"after": 26, "of": 60}``; ``str(ClipStop(**stopped))`` says it in words), and
    ``frames``, each frame's :meth:`ClipFrameResult.report`.
    """
    from ..io.clip import clip_format, write_clip

    options = options or JeansOptions()
    fmt = fmt or clip_format(output)
    frames: list[dict] = []
    with ClipReader(source, limits, keep_audio=fmt == "mp4") as reader:

        def painted() -> Iterator[ClipFrame]:
            for result in apply_jeans_to_clip(reader, options):
                frames.append(result.report())
                if on_frame is not None:
                    on_frame(result)
                image = result.image
                if decorate is not None:  # captions and side by side: on white
                    image = decorate(on_white(image), on_white(result.original))
                yield ClipFrame(result.index, result.time, result.duration, image)

        write_clip(output, painted(), fmt, fps=reader.info.fps, loop=reader.info.loop, reader=reader)
        info = reader.info
        stopped = reader.stopped
    report = {
        "kind": "clip",
        "format": fmt,
        "size": list(info.size),
        "fps": info.fps,
        "frames_written": len(frames),
        "seconds": round(frames[-1]["time"], 4) if frames else 0.0,
        "audio": info.audio and fmt == "mp4",
        "frames": frames,
    }
    if stopped is not None:
        report["stopped"] = stopped.to_json()
    return report


__all__ = ["ClipFrameResult", "apply_jeans_to_clip", "write_jeans_clip"]
