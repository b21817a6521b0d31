"""Pictures of a fit: the garment painted onto the photo (:func:`composite`), or the
paper's figure of a silhouette (:func:`figure`). OpenCV is imported on first use."""

from __future__ import annotations

import numpy as np

from ..fitting.fitter import FitResult
from ..fitting.garments import JEANS, Garment
from ..subject.silhouettes import Silhouette


def composite(
    image: np.ndarray,
    fit_result: FitResult,
    silhouette: Silhouette,
    style: str = "denim",
    clip: bool = True,
    seed: int = 0,
) -> np.ndarray:
    """Paint the fitted garment onto ``image`` (the photo the silhouette came from)."""
    from .compositing import composite_jeans

    vertices = silhouette.to_mask(fit_result.vertices)
    return composite_jeans(
        image, vertices, fit_result.garment, silhouette.mask if clip else None, style=style, clip=clip, seed=seed
    )


def draw_garment(
    image: np.ndarray, vertices_image: np.ndarray, garment: Garment = JEANS, style: str = "flat"
) -> np.ndarray:
    """Paint a garment polygon given in image pixels onto ``image`` (no clipping):
    for drawing intermediate states, such as the frames of an optimisation animation."""
    from .compositing import composite_jeans

    return composite_jeans(image, vertices_image, garment, None, style=style, clip=False)


def draw_figure(mask: np.ndarray, vertices_mask: np.ndarray | None, garment: Garment = JEANS) -> np.ndarray:
    """The paper's figure of a ``(H, W)`` alpha with a garment polygon in its pixels."""
    from .compositing import render_silhouette_figure

    return render_silhouette_figure(mask, vertices_mask, garment)


def figure(silhouette: Silhouette, fit_result: FitResult | None = None) -> np.ndarray:
    """The paper's figure style at the mask's resolution: black shape, blue jeans, white ground.

    Without a fit, the silhouette alone.
    """
    from .compositing import render_silhouette_figure

    if fit_result is None:
        return render_silhouette_figure(silhouette.mask, None)
    return render_silhouette_figure(silhouette.mask, silhouette.to_mask(fit_result.vertices), fit_result.garment)
