"""GrabCut for the photo methods: seeds from the scene's border colours and saliency,
the coarse cut and its variants, and the refinement at working resolution.

The first pass runs on the :class:`~jeanscv.subject.scene.Scene`'s coarse copy (long
side <= 320; auto's hypotheses on its smaller copy) in three variants, "colour",
"texture" and "rect" (:func:`grabcut_coarse_best`); the winner is refined in a band
around its boundary at working resolution (:func:`refine`). :func:`grabcut` is the
``grabcut`` method of :func:`jeanscv.subject.photo.segment`; :func:`run_grabcut`, one
repeatable ``cv2.grabCut``, also serves the click sessions (:mod:`.interactive`).

Arrays: images are ``(H, W, 3)`` RGB ``uint8``; masks ``(H, W) bool`` with True on the
object; GrabCut labels ``(H, W) uint8`` ``cv2.GC_*`` values. Rects are ``(x, y, w, h)``.
"""

from __future__ import annotations

from concurrent.futures import Future, ThreadPoolExecutor

import cv2
import numpy as np

from jeanscv.errors import JeansError

from .masks import clean, disk, resize
from .scene import Scene, spectral_saliency

_COARSE_ITERATIONS = 5  # GrabCut iterations of the first pass
# auto's hypotheses are cut on the scene's small copy (scene.HYPOTHESIS_SIZE) with fewer
# iterations than the first pass. Two instead of three save 15% and leave the real
# photos' mean IoU as it is, but lose a low-contrast synthetic photo (IoU 0.85).
HYPOTHESIS_ITERATIONS = 3
# A colour GrabCut scoring this high is not second-guessed by the texture variant,
# which saves a third of GrabCut's time: on 48 synthetic photos the texture variant
# only ever won against colour scores under 0.77.
_CONFIDENT_SCORE = 0.8
_REFINE_MODEL_STEP = 4  # the refinement learns its colour models on a copy this many times smaller
_COMPONENTS = 5  # Gaussians in each of GrabCut's colour models (OpenCV's fixed number)
_MODEL_SAMPLES = 20000  # colours a side's starting model is clustered from, at most


class _Inline:
    """An executor that runs each job at once on the calling thread."""

    def __enter__(self) -> _Inline:
        return self

    def __exit__(self, *exc) -> None:
        return None

    def submit(self, job, *args, **kwargs) -> Future:
        future: Future = Future()
        try:
            future.set_result(job(*args, **kwargs))
        except BaseException as error:  # raised by result(), as from a thread
            future.set_exception(error)
        return future


def cut_pool() -> ThreadPoolExecutor | _Inline:
    """Threads for GrabCuts cut side by side (auto's hypotheses, a box's two starts):
    as many as OpenCV may use, 2 to 4; none when it may use one (OpenCV releases the
    GIL, and :func:`run_grabcut` seeds each thread's RNG, so the cuts are the same
    either way). One worker beside the caller only competes with it for the core: on
    12-MP copies of the 18 real photos with OpenCV on one thread, auto's median CPU
    time was 0.634 s with a worker and 0.554 s inline."""
    threads = min(4, cv2.getNumThreads())
    return ThreadPoolExecutor(threads) if threads > 1 else _Inline()


def run_grabcut(
    image: np.ndarray, labels: np.ndarray, iterations: int, rect=None, models=None, start=None
) -> np.ndarray:
    """cv2.grabCut from a label mask (or a rect); returns the bool object mask.

    ``models``: a (background, foreground) pair of (1, 65) float64 colour models. Zero
    ones are filled with the models the cut learns; given ones are kept fixed (one
    graph cut with them, ``iterations`` unused). ``start``: such a pair to start from
    instead of OpenCV's k-means of the labels (:func:`orchard_bouman_models`); GrabCut
    learns them again from its answer after each cut, as always.
    """
    background, foreground = models if models is not None else (np.zeros((1, 65)), np.zeros((1, 65)))
    labels = labels.copy()
    if rect is not None:
        mode = cv2.GC_INIT_WITH_RECT
    elif start is not None:
        background, foreground = (model.copy() for model in start)
        mode = cv2.GC_EVAL
    elif background.any() and foreground.any():
        mode = cv2.GC_EVAL_FREEZE_MODEL
    else:
        mode = cv2.GC_INIT_WITH_MASK
    cv2.setRNGSeed(2023)  # grabCut's k-means draws from OpenCV's global RNG: be repeatable
    try:
        cv2.grabCut(image, labels, rect, background, foreground, iterations, mode)
    except cv2.error as error:  # e.g. no foreground or no background samples
        raise JeansError("grabcut could not separate an object") from error
    return (labels == cv2.GC_FGD) | (labels == cv2.GC_PR_FGD)


def orchard_bouman_models(image: np.ndarray, labels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """GrabCut's (background, foreground) colour models, ``(1, 65)`` float64 each, for
    ``image`` ``(H, W, 3)`` uint8 and its ``labels``: each side's colours split into
    five clusters by Orchard and Bouman's method (1991; the GrabCut paper's own), then a
    Gaussian fitted to each. No randomness: OpenCV's own start, k-means++, draws its
    first centres at random, so pixels a level apart can send GrabCut to another local
    optimum (a box on a photo and on its 4000-pixel copy: 8 of the 52 shared photos
    moved by more than 0.05, against 1 with this start; see docs/clicks.md)."""
    fg = (labels == cv2.GC_FGD) | (labels == cv2.GC_PR_FGD)
    if np.count_nonzero(fg) < _COMPONENTS or np.count_nonzero(~fg) < _COMPONENTS:
        raise JeansError("grabcut could not separate an object")
    return _side_model(image[~fg]), _side_model(image[fg])


def orchard_bouman(colours: np.ndarray, clusters: int = _COMPONENTS) -> np.ndarray:
    """Cluster labels ``(N,)`` int32 of ``colours`` ``(N, 3)``: starting from one
    cluster, the one with the largest variance along its principal axis (eigenvalue
    times size) is cut in two at its mean, across that axis, until there are
    ``clusters`` (fewer where none has two colours left to cut)."""
    colours = np.asarray(colours, np.float64)  # no copy where it already is
    labels = np.zeros(len(colours), np.int32)
    for new in range(1, clusters):
        widest, cut = -1.0, None
        for cluster in range(new):
            members = colours[labels == cluster]
            if len(members) < 2:
                continue
            mean = members.mean(axis=0)
            values, vectors = np.linalg.eigh(np.cov((members - mean).T, bias=True))
            if values[-1] * len(members) > widest:
                widest, cut = values[-1] * len(members), (cluster, mean, vectors[:, -1])
        if cut is None:
            break
        cluster, mean, axis = cut
        members = np.flatnonzero(labels == cluster)
        labels[members[(colours[members] - mean) @ axis > 0]] = new
    return labels


def _side_model(colours: np.ndarray) -> np.ndarray:
    """One side's colour model: :func:`orchard_bouman` on at most ``_MODEL_SAMPLES`` of
    its colours (evenly spaced), a weight, a mean and a covariance for each cluster,
    with 0.01 added to its diagonal so that none is flat (OpenCV adds as much where one
    is)."""
    colours = colours.reshape(-1, 3)
    if len(colours) > _MODEL_SAMPLES:
        colours = colours[np.linspace(0, len(colours) - 1, _MODEL_SAMPLES).astype(int)]
    colours = colours.astype(np.float64)
    labels = orchard_bouman(colours)
    weights, means, covariances = np.zeros(_COMPONENTS), np.zeros((_COMPONENTS, 3)), np.zeros((_COMPONENTS, 3, 3))
    for cluster in range(_COMPONENTS):
        members = colours[labels == cluster]
        if len(members) == 0:
            continue
        weights[cluster] = len(members) / len(colours)
        means[cluster] = members.mean(axis=0)
        spread = np.cov(members.T, bias=True) if len(members) > 1 else np.zeros((3, 3))
        covariances[cluster] = spread + 0.01 * np.eye(3)
    return np.concatenate([weights, means.ravel(), covariances.ravel()])[None]


def _band_labels(mask: np.ndarray, band: int) -> np.ndarray:
    """GrabCut labels that leave only a band of ``band`` pixels either side of
    ``mask``'s boundary to decide: probable subject or background there as ``mask``
    says, definite elsewhere."""
    eight = mask.astype(np.uint8)
    kernel = disk(band)
    near = cv2.dilate(eight, kernel).astype(bool) & ~cv2.erode(eight, kernel).astype(bool)
    labels = np.where(mask, cv2.GC_FGD, cv2.GC_BGD).astype(np.uint8)
    labels[near & mask] = cv2.GC_PR_FGD
    labels[near & ~mask] = cv2.GC_PR_BGD
    return labels


def _seed_labels(scene: Scene, scale: str) -> np.ndarray | None:
    """GrabCut labels from the border model and the saliency map.

    prior = likelihood x (0.5 + 0.5 saliency); probable foreground where it exceeds its
    Otsu threshold (at least 0.25), eroded by a pixel; the border ring is definite
    background except on the seeds (objects may leave the frame); probable background
    elsewhere. None when there is no seed.
    """
    prior = scene.likelihood[scale] * (0.5 + 0.5 * spectral_saliency(scene.rgb))
    prior8 = np.clip(prior * 255, 0, 255).astype(np.uint8)
    otsu, _ = cv2.threshold(prior8, 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
    seed = (prior8 > max(float(otsu), 0.25 * 255)).astype(np.uint8)
    # Edge pixels mix object and background colours: keep them out of the object model.
    seed = cv2.erode(seed, disk(1)).astype(bool)
    if not seed.any() or seed.all():
        return None
    labels = np.full(seed.shape, cv2.GC_PR_BGD, np.uint8)
    labels[seed] = cv2.GC_PR_FGD
    labels[scene.ring & ~seed] = cv2.GC_BGD
    return labels


def _grabcut_coarse(scene: Scene, variant: str, rect=None, hypothesis: bool = False) -> np.ndarray | None:
    """One GrabCut at coarse resolution, cleaned; None if it cannot start.

    Variants: "colour" (seeds and cut on the image), "texture" (on the texture-blurred
    image, where regions differing in mean colour under a texture separate) and "rect"
    (``rect`` = (x, y, w, h) in coarse pixels). ``hypothesis``: cut the scene's small
    copy (:meth:`Scene.hypothesis`) and return the mask upsampled to coarse size.
    """
    if variant == "rect":
        labels = np.zeros(scene.rgb.shape[:2], np.uint8)
        return clean(run_grabcut(scene.rgb, labels, _COARSE_ITERATIONS, rect=rect))
    scale = "fine" if variant == "colour" else "texture"
    labels = _seed_labels(scene, scale)
    if labels is None:
        return None
    image = scene.rgb if scale == "fine" else scene.images["texture"]
    if not hypothesis:
        return clean(run_grabcut(image, labels, _COARSE_ITERATIONS))
    small = scene.hypothesis_size
    cut = run_grabcut(
        resize(image, small, cv2.INTER_AREA), resize(labels, small, cv2.INTER_NEAREST), HYPOTHESIS_ITERATIONS
    )
    return scene.from_hypothesis(cut)


def refine(
    rgb: np.ndarray, coarse: np.ndarray, scene: Scene, variant: str, source_width: int | None = None
) -> np.ndarray:
    """Redo a coarse GrabCut mask at working resolution in a band around its boundary.

    Pixels farther than ~1.5 source pixels from the upsampled boundary keep their label
    (definite); the band is re-labelled by a short GrabCut on the bounding box crop.
    ``source_width``: width of the image the mask was cut at (default: coarse), which
    sets how uncertain its boundary is.
    """
    width, height = scene.working_size
    upsampled = resize(coarse.astype(np.float32), (width, height), cv2.INTER_LINEAR) >= 0.5
    if scene.factor <= 1.0 or not upsampled.any():
        return upsampled
    band = max(2, int(np.ceil(1.5 * width / (source_width or scene.size[0]))))
    rows, cols = np.nonzero(upsampled)
    y0, y1 = max(rows.min() - 2 * band, 0), min(rows.max() + 2 * band + 1, height)
    x0, x1 = max(cols.min() - 2 * band, 0), min(cols.max() + 2 * band + 1, width)
    labels = _band_labels(upsampled[y0:y1, x0:x1], band)
    image = rgb[y0:y1, x0:x1]
    if variant == "texture":
        image = cv2.GaussianBlur(image, (0, 0), scene.texture_sigma * scene.factor)
    image = np.ascontiguousarray(image)
    # The colour models are learnt (k-means and two iterations) on a copy reduced
    # _REFINE_MODEL_STEP times, and cut once at working size with them: the same
    # masks within 0.01 IoU on the real and synthetic photos, for a third of the time.
    step = (max(2, image.shape[1] // _REFINE_MODEL_STEP), max(2, image.shape[0] // _REFINE_MODEL_STEP))
    models = np.zeros((1, 65)), np.zeros((1, 65))
    refined = upsampled.copy()
    try:
        run_grabcut(resize(image, step, cv2.INTER_AREA), resize(labels, step, cv2.INTER_NEAREST), 2, models=models)
        refined[y0:y1, x0:x1] = run_grabcut(image, labels, 1, models=models)
    except JeansError:  # one class missing from the crop: keep the coarse answer
        return upsampled
    return clean(refined)


def grabcut_coarse_best(scene: Scene, rect_work=None, hypothesis: bool = False) -> tuple[str, np.ndarray, dict]:
    """GrabCut variants at coarse resolution: ``(chosen variant, its mask, variant
    scores)``. With ``rect_work`` (x, y, w, h, working pixels) only the rect variant
    runs, else "colour" and, unless colour scored at least ``_CONFIDENT_SCORE``,
    "texture". ``hypothesis``: cut on the scene's small copy (see :func:`_grabcut_coarse`),
    and the texture variant only where colour found nothing or the scene is scored at
    its texture scale: elsewhere it never won (18 real and 96 synthetic photos give the
    same masks without it) and cost up to 0.7 s on a real photo."""
    if rect_work is not None:
        x, y, w, h = (v / scene.factor for v in rect_work)
        rect = (int(np.floor(x)), int(np.floor(y)), max(2, int(np.ceil(w))), max(2, int(np.ceil(h))))
        jobs = {"rect": dict(rect=rect)}
    else:
        jobs = {"colour": {}, "texture": {}}
    variants = {}
    for variant, kwargs in jobs.items():
        if (
            variant == "texture"
            and "colour" in variants
            and (variants["colour"][1]["score"] >= _CONFIDENT_SCORE or (hypothesis and scene.scale == "fine"))
        ):
            continue
        try:
            mask = _grabcut_coarse(scene, variant, hypothesis=hypothesis, **kwargs)
        except JeansError:
            mask = None
        if mask is not None and mask.any():
            variants[variant] = (mask, scene.features(mask))
    if not variants:
        raise JeansError("no object found to segment")
    chosen = max(variants, key=lambda name: variants[name][1]["score"])
    return chosen, variants[chosen][0], {name: features["score"] for name, (_, features) in variants.items()}


def grabcut(rgb: np.ndarray, scene: Scene, rect_work=None) -> tuple[np.ndarray, dict]:
    """The best GrabCut variant (:func:`grabcut_coarse_best`) refined at working resolution."""
    chosen, coarse, scores = grabcut_coarse_best(scene, rect_work)
    refined = refine(rgb, coarse, scene, chosen)
    info = {
        "variant": chosen,
        "coarse_shape": scene.rgb.shape[:2],
        "variant_scores": scores,
        "features": scene.features(refined),
    }
    if rect_work is not None:
        info["rect"] = tuple(int(v) for v in rect_work)
    return refined, info


def grabcut_or_none(image: np.ndarray, labels: np.ndarray, iterations: int) -> np.ndarray | None:
    """:func:`run_grabcut` for hypotheses that may fail: None instead of an error."""
    try:
        return run_grabcut(image, labels, iterations)
    except JeansError:
        return None
