"""The public API in one namespace, for ``from jeanscv.api import ...``.

Each name lives in the module of its topic: :mod:`jeanscv.pipeline` (decode, segment,
fit and composite: :func:`apply_jeans`), :mod:`jeanscv.subject.silhouettes` (the
:class:`Silhouette` and the inputs that need no segmentation), :mod:`jeanscv.subject.drawing`
(whether an image is a silhouette drawing), :mod:`jeanscv.subject.extraction` (the objects of a
photo), :mod:`jeanscv.paint.figures` (pictures of a fit), :mod:`jeanscv.report` (the result and
its JSON report) and :mod:`jeanscv.device` (where a fit runs); :mod:`jeanscv.options`
(:class:`JeansOptions`, every per-input option).
"""

from __future__ import annotations

from .device import resolve_device
from .fitting.garments import JEANS
from .options import KINDS, OBJECTS, JeansOptions
from .paint.figures import composite, draw_figure, draw_garment, figure
from .pipeline import apply_jeans, fit, load_image, prepare_input
from .report import SUBJECT_KEYS, FittedObject, JeansResult
from .subject.drawing import silhouette_from_drawing
from .subject.extraction import extract_silhouette, extract_silhouettes
from .subject.silhouettes import Silhouette, load_mask, read_svg, silhouette_contours, silhouette_from_alpha

__all__ = [
    "JEANS",
    "KINDS",
    "JeansOptions",
    "JeansResult",
    "Silhouette",
    "SUBJECT_KEYS",
    "apply_jeans",
    "composite",
    "extract_silhouette",
    "extract_silhouettes",
    "FittedObject",
    "OBJECTS",
    "draw_figure",
    "draw_garment",
    "figure",
    "fit",
    "load_image",
    "load_mask",
    "silhouette_contours",
    "silhouette_from_alpha",
    "silhouette_from_drawing",
    "prepare_input",
    "read_svg",
    "resolve_device",
]
