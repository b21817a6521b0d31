"""Every per-input option, declared once: :class:`JeansOptions`, and the lists of allowed
values that the command line's choices are made from.

The command line, :func:`jeanscv.pipeline.apply_jeans` and the Dask runner
(:mod:`jeanscv.run.distributed`) all build one :class:`JeansOptions` and pass it along.
A field is one line: its name, type and default, and for a fixed set of values its
``choices`` (checked when the options are made). Cheap to import (no numpy): the
command's ``--help`` reads the choices from here.
"""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from .device import BACKENDS
from .errors import JeansError

if TYPE_CHECKING:
    import numpy as np

    from .fitting.garments import Garment
    from .subject.clicks import Clicks

#: What an input is: ``auto`` tells silhouette drawings (and SVGs) from photos.
KINDS = ("auto", "silhouette", "photo")
#: ``one``: the main subject; ``all``: every separate object, each with its own garment.
OBJECTS = ("one", "all")
#: The COCO classes that are animals: the detector's names for what ``animal`` takes.
ANIMAL_CLASSES = ("bird", "cat", "dog", "horse", "sheep", "cow", "elephant", "bear", "zebra", "giraffe")
#: What a photo's subject is: ``auto`` prefers an animal beside a person, ``animal`` and
#: ``person`` say which, ``object`` takes the most salient thing whatever it is; an animal
#: class (``dog``) prefers that animal among those detected.
SUBJECTS = ("auto", "animal", "person", "object", *ANIMAL_CLASSES)
#: How automatic finding knows what is in a photo: ``auto``, the detector jeanscv ships
#: (:mod:`jeanscv.detect`); ``none``, classical cues alone.
DETECTORS = ("auto", "none")
#: How the garment is painted on a photo: a denim texture, or the paper's flat blue.
STYLES = ("denim", "flat")
#: ``upright``: the garment hangs down unless no upright fit passes the rule checks;
#: ``any``: every posture competes.
POSTURES = ("upright", "any")
#: The built-in ways to cut the object out of a photo, by name (plugins add more;
#: ``mask``, a given mask, is not one that can be named).
SILHOUETTE_METHODS = ("auto", "alpha", "threshold", "grabcut")


def _choice(default: str, choices: tuple[str, ...], label: str) -> Any:
    """A field whose value must be one of ``choices`` (``label`` names it in the error)."""
    return field(default=default, metadata={"choices": choices, "label": label})


@dataclass(frozen=True)
class JeansOptions:
    """How to put jeans on one input: fitting, silhouette, look and decoding.

    Fitting: ``garment`` (a name, a ``.toml`` path or a :class:`~jeanscv.fitting.garments.Garment`),
    ``preset``, ``posture``, ``iterations``, ``seed``, ``starts`` (None: the preset's),
    ``device`` (``cpu``, ``cuda``, ``auto``), ``backend`` (``fast``, ``torch``; None:
    :func:`jeanscv.device.resolve_backend` chooses).

    Silhouette: ``kind``, ``silhouette_method`` (a built-in or a plugin's name),
    ``threshold`` and ``rect`` (for the ``threshold`` and ``grabcut`` methods), ``mask``
    (an ``(H, W)`` array or an image file: the object, instead of segmenting), ``objects``,
    ``subject`` (what automatic finding looks for: ``auto``, ``animal``, ``person``, ``object``,
    or an animal class such as ``dog``), ``detector`` (``auto``: the shipped detector finds
    the subject's box; ``none``: classical finding alone);
    clicks that fix the subject (pixels of the photo as displayed; see
    :func:`jeanscv.subject.extraction.extract_silhouettes`): ``points`` and ``background_points``
    (one object's positive and negative clicks), ``box`` (``(x0, y0, x1, y1)``: that
    object lies inside it; with or without clicks) and ``clicks`` (several objects': a
    :class:`~jeanscv.subject.clicks.Clicks` or a clicks file).

    Look: ``style``, ``clip`` (paint only on the object); ``top`` and ``bottom``
    captions, ``side_by_side`` and ``gif_frames`` shape the command's pictures.

    Decoding: ``max_pixels`` (larger images are refused), ``raw_half_size`` (RAW files
    at half size, faster), ``max_frames`` (clips with more frames are refused).
    """

    # Fitting.
    garment: str | os.PathLike | Garment = "jeans"
    preset: str = "default"
    posture: str = _choice("upright", POSTURES, "posture")
    iterations: int = 100
    seed: int = 0
    starts: int | None = None
    device: str = "cpu"
    backend: str | None = None
    # Silhouette.
    kind: str = _choice("auto", KINDS, "input kind")
    silhouette_method: str = "auto"
    threshold: float | None = None
    rect: tuple[int, int, int, int] | None = None
    mask: np.ndarray | str | os.PathLike | None = None
    objects: str = _choice("one", OBJECTS, "objects")
    subject: str = _choice("auto", SUBJECTS, "subject")
    detector: str = _choice("auto", DETECTORS, "detector")
    points: tuple[tuple[float, float], ...] = ()
    background_points: tuple[tuple[float, float], ...] = ()
    box: tuple[float, float, float, float] | None = None
    clicks: Clicks | str | os.PathLike | None = None
    # Look.
    style: str = _choice("denim", STYLES, "style")
    clip: bool = True
    top: str | None = None
    bottom: str | None = None
    side_by_side: bool = False
    gif_frames: int = 50
    # Decoding.
    max_pixels: int = 100_000_000
    raw_half_size: bool = False
    max_frames: int = 18_000

    def __post_init__(self) -> None:
        # Lists and other sequences of points are kept as a tuple, so options stay immutable.
        object.__setattr__(self, "points", tuple(self.points or ()))
        object.__setattr__(self, "background_points", tuple(self.background_points or ()))
        if self.box is not None:
            object.__setattr__(self, "box", tuple(self.box))
        for option in dataclasses.fields(self):
            choices = option.metadata.get("choices")
            value = getattr(self, option.name)
            if choices is not None and value not in choices:
                label = option.metadata["label"]
                raise JeansError(f"unknown {label} {value!r} (use {', '.join(choices)})")
        if self.backend is not None and self.backend not in BACKENDS:
            raise JeansError(f"unknown backend {self.backend!r} (use {' or '.join(BACKENDS)})")
        if self.iterations < 0:
            raise JeansError("iterations must be >= 0")
        if self.max_frames < 1:
            raise JeansError("max_frames must be >= 1")

    def replace(self, **changes: Any) -> JeansOptions:
        """A copy with ``changes`` (option names as keywords); an unknown name is a TypeError."""
        return dataclasses.replace(self, **changes) if changes else self

    @classmethod
    def names(cls) -> tuple[str, ...]:
        """Every option's name, in declaration order."""
        return tuple(option.name for option in dataclasses.fields(cls))


__all__ = [
    "ANIMAL_CLASSES",
    "DETECTORS",
    "JeansOptions",
    "KINDS",
    "OBJECTS",
    "POSTURES",
    "SILHOUETTE_METHODS",
    "STYLES",
    "SUBJECTS",
]
