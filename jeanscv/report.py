"""What :func:`jeanscv.pipeline.apply_jeans` gives back (:class:`JeansResult`, one
:class:`FittedObject` per object) and its JSON report, the CLI's ``--json`` sidecar."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from .fitting.checks import rule_report
from .fitting.fitter import FitResult
from .fitting.posture import posture_name, tilt_degrees
from .geometry import CANVAS_SIZE
from .subject.silhouettes import SUBJECT_KEYS, Silhouette, box_of

if TYPE_CHECKING:  # decoding imports Pillow; a result only holds what it decoded
    from .io.image import LoadedImage


@dataclass
class FittedObject:
    """One object of a result: its silhouette and the garment fitted to it."""

    silhouette: Silhouette
    fit: FitResult

    def report(self) -> dict:
        """The object's entry in the report's ``objects`` list; ``tilt_degrees`` and
        ``posture`` are measured on its ``vertices_image`` as reported."""
        framing = self.silhouette.framing
        rules = rule_report(self.fit.vertices, self.silhouette.canvas, self.fit.garment)
        vertices_image = _rounded(framing.to_image(self.fit.vertices))
        tilt = tilt_degrees(np.asarray(vertices_image), self.fit.garment)
        entry = {
            "box": list(box_of(self.silhouette)),
            "method": self.silhouette.method,
            "vertices_canvas": _rounded(self.fit.vertices),
            "vertices_image": vertices_image,
            "canvas_to_image": _rounded(framing.canvas_to_image),
            "objective": _round(self.fit.objective),
            "tilt_degrees": _round(tilt),
            "posture": posture_name(tilt),
            "rules": {k: (_round(v) if isinstance(v, float) else v) for k, v in rules.to_json().items()},
        }
        if "point" in self.silhouette.details:
            entry["point"] = [_round(v) for v in self.silhouette.details["point"]]
        if "clicks" in self.silhouette.details:
            entry["clicks"] = self.silhouette.details["clicks"]
        if "detection" in self.silhouette.details:  # the detected object it is (found, or clicked on)
            entry["detection"] = self.silhouette.details["detection"]
        return entry


@dataclass
class JeansResult:
    """Everything :func:`apply_jeans` produced.

    ``silhouette`` and ``fit`` are the main (first) object's; ``objects`` lists every
    object that got a garment, the main one first.
    """

    image: np.ndarray  # the output picture, uint8
    silhouette: Silhouette
    fit: FitResult
    kind: str  # "silhouette" or "photo"
    source: LoadedImage | None = None  # for files that were decoded
    objects: list[FittedObject] = field(default_factory=list)

    def __post_init__(self) -> None:
        if not self.objects:
            self.objects = [FittedObject(self.silhouette, self.fit)]

    def report(self, input_name: str = "", output_name: str = "") -> dict:
        """The JSON-able report (the CLI's ``--json`` sidecar): the top-level fields
        describe the main object, ``objects`` every object."""
        fit_result = self.fit
        framing = self.silhouette.framing
        entries = [obj.report() for obj in self.objects]
        report = {
            "input": input_name,
            "output": output_name,
            "kind": self.kind,
            "garment": fit_result.garment.name,
            "preset": fit_result.preset.name,
            "iterations": fit_result.iterations,
            "seed": fit_result.seed,
            "device": fit_result.device,
            "canvas_size": CANVAS_SIZE,
            "silhouette_method": self.silhouette.method,
            "vertices_canvas": entries[0]["vertices_canvas"],
            "vertices_image": entries[0]["vertices_image"],
            "canvas_to_image": entries[0]["canvas_to_image"],
            "image_size": list(framing.image_size),
            "tilt_degrees": entries[0]["tilt_degrees"],
            "posture": entries[0]["posture"],
            "paper_terms": _rounded_dict(fit_result.paper_terms),
            "paper_total": _round(fit_result.paper_total),
            "objective": _round(fit_result.objective),
            "terms": _rounded_dict(fit_result.terms),
            "weights": dict(fit_result.preset.weights),
            "inter_pairs": fit_result.preset.inter_pairs,
            "starts": fit_result.num_starts,
            "finished_starts": fit_result.start_ids,
            "start_index": fit_result.start_index,
            "start_objectives": [_round(v) for v in fit_result.start_objectives],
            "rules": entries[0]["rules"],
            "objects": entries,
            "seconds": round(fit_result.seconds, 3),
        }
        # Why auto segmentation took this subject, and whether it may be the wrong thing.
        subject = {key: self.silhouette.details[key] for key in SUBJECT_KEYS if key in self.silhouette.details}
        if subject:
            report["subject"] = subject
        clicked = [entry["clicks"] for entry in entries if "clicks" in entry]
        if clicked:
            # The clicks used, as a clicks file holds them (pixels of the decoded photo).
            report["clicks"] = {"objects": clicked}
        return report


def _round(value: float) -> float:
    return float(f"{float(value):.6g}")


def _rounded(array: np.ndarray) -> list:
    return np.vectorize(_round, otypes=[float])(np.asarray(array, dtype=np.float64)).tolist()


def _rounded_dict(values: dict[str, float]) -> dict[str, float]:
    return {k: _round(v) for k, v in values.items()}
