"""A :class:`Silhouette`: an object's shape at image resolution and on the fitting canvas,
and the ways to get one that need no segmentation (an alpha, an SVG, a mask file), its
boundary and its box.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np

from ..errors import JeansError
from ..geometry import CANVAS_SIZE, mask_box
from .framing import Framing, frame_mask, identity_framing

#: The auto segmentation's ``details`` that say which subject it took and how sure it is:
#: the winning hypothesis, why it won, its mean IoU with the others, the subject asked
#: for (``subject``: auto, animal, person, object) and the kind found, whether it may be
#: the wrong thing (``uncertain``) and why (``doubts``); where the detector found it, the
#: ``detection`` dressed and every one it made (``detections``: class, score, box in image
#: pixels). The report gives them as ``subject``; each object split from the subject keeps them.
SUBJECT_KEYS = ("chosen", "reason", "consensus", "subject", "kind", "uncertain", "doubts", "detection", "detections")


@dataclass
class Silhouette:
    """An object's silhouette at image resolution and on the canvas.

    ``mask``: ``(H, W)`` float32 alpha at image resolution (bool for one of several
    objects split from a photo, which saves memory on large photos); ``canvas``: the paper's
    ``S``, ``(256, 256)`` float32; ``framing`` maps canvas pixels to image pixels.
    """

    mask: np.ndarray
    canvas: np.ndarray
    framing: Framing
    method: str
    contour: np.ndarray | None = None  # (K, 2) image pixels, outer boundary
    details: dict = field(default_factory=dict)
    mask_is_canvas: bool = False  # an SVG's mask is drawn on the canvas, not in image units

    def to_mask(self, canvas_points: np.ndarray) -> np.ndarray:
        """Canvas pixels ``(..., 2)`` to pixels of ``mask``."""
        points = np.asarray(canvas_points, dtype=np.float64)
        return points.copy() if self.mask_is_canvas else self.framing.to_image(points)


def silhouette_from_alpha(alpha: np.ndarray, method: str) -> Silhouette:
    """Frame a soft alpha ``(H, W)``: a 256x256 one is the canvas, others are framed."""
    alpha = np.clip(np.asarray(alpha, dtype=np.float32), 0.0, 1.0)
    if alpha.sum() < 1.0:
        raise JeansError("silhouette is empty")
    if alpha.shape == (CANVAS_SIZE, CANVAS_SIZE):
        return Silhouette(alpha, alpha, identity_framing(), method)
    canvas, framing = frame_mask(alpha)
    return Silhouette(alpha, canvas, framing, method)


def read_svg(path: str | os.PathLike) -> Silhouette:
    """An SVG silhouette: its 256 canvas is the viewBox, fitted with aspect kept."""
    from ..io.files import open_regular
    from ..io.svg import read_svg_silhouette

    try:
        open_regular(path).close()
    except FileNotFoundError:
        raise JeansError("file not found") from None
    except IsADirectoryError:
        raise JeansError("not a file") from None
    except OSError as exc:  # a FIFO, a device, a symlink loop, no permission
        raise JeansError(f"cannot read file: {(exc.strerror or str(exc)).lower()}") from None
    svg = read_svg_silhouette(path)
    framing = Framing(
        (float(svg.canvas_to_image[0, 2]), float(svg.canvas_to_image[1, 2])),
        float(svg.canvas_to_image[0, 0] * CANVAS_SIZE),
        (int(round(svg.width)), int(round(svg.height))),
    )
    return Silhouette(svg.alpha, svg.alpha, framing, "svg", mask_is_canvas=True)


def load_mask(path: str | os.PathLike, max_pixels: int = 100_000_000) -> np.ndarray:
    """A ``(H, W)`` bool mask from an image file: its alpha when it has some, else grey >= 128."""
    from ..io.image import load_image

    try:
        loaded = load_image(path, max_pixels=max_pixels)
    except JeansError as exc:
        raise JeansError(f"cannot read mask {path}: {exc}") from None
    pixels = loaded.pixels
    if loaded.alpha_meaningful:
        return pixels[..., 3] >= 128
    return pixels[..., :3].mean(axis=-1) >= 128


def silhouette_contours(silhouette: Silhouette) -> list[np.ndarray]:
    """Boundary polylines ``[(K, 2)]`` of a silhouette in image pixels.

    Photos carry their outer contour (``Silhouette.contour``); for drawings and SVGs
    every boundary (holes included, for an even-odd fill) is traced as the 0.5
    iso-line of the mask, between pixel centres.
    """
    if silhouette.contour is not None and len(silhouette.contour) >= 3:
        return [np.asarray(silhouette.contour, dtype=np.float64)]
    from skimage.measure import find_contours

    # Padding closes the contours of shapes that touch the border.
    padded = np.pad(np.asarray(silhouette.mask, dtype=np.float32), 1)
    contours = []
    for rc in find_contours(padded, 0.5):
        if len(rc) < 3:
            continue
        xy = rc[:, ::-1] - 1.0 + 0.5  # (row, col) of padded centres -> (x, y) of pixel centres
        contours.append(silhouette.framing.to_image(xy) if silhouette.mask_is_canvas else xy)
    return contours


def box_of(silhouette: Silhouette) -> tuple[int, int, int, int]:
    """The object's bounding box ``(x, y, w, h)`` in image pixels (an SVG's, through its framing)."""
    if "box" in silhouette.details:
        return tuple(silhouette.details["box"])

    x, y, w, h = mask_box(silhouette.mask)
    if not silhouette.mask_is_canvas:
        return x, y, w, h
    (x0, y0), (x1, y1) = silhouette.framing.to_image(np.array([[x, y], [x + w, y + h]], np.float64))
    return int(np.floor(x0)), int(np.floor(y0)), int(np.ceil(x1) - np.floor(x0)), int(np.ceil(y1) - np.floor(y0))
