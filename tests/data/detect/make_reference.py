"""Makes ``nanodet_reference.npz``: a small deterministic input and NanoDet's outputs for it
from the real tfjs runtime (``reference.js``), which ``tests/test_detect.py`` compares the
torch executor against. Documentation of how the fixture was made; never run by the tests.

    NODE_PATH=/tmp/detector-work/node_modules python tests/data/detect/make_reference.py

The input is ``sample_images/cat.jpg`` shrunk to 52 x 52 (stored in the fixture) and blown
up 8x by pixel repetition to 416 x 416, then fed as jeanscv feeds NanoDet. To stay small
(< 300 KB) the fixture keeps the stride-16 and stride-32 outputs whole (float16) and, of the
stride-8 ones, each cell's largest class score and largest box logit.
"""

from __future__ import annotations

import subprocess
import tempfile
from pathlib import Path

import cv2
import numpy as np

from jeanscv.detect import MODEL_DIR
from jeanscv.detect.nanodet import OUTPUTS, graph_input

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[2]


def seed_image() -> np.ndarray:
    """cat.jpg as a 52 x 52 RGB uint8 image."""
    bgr = cv2.imread(str(ROOT / "sample_images" / "cat.jpg"))
    return cv2.cvtColor(cv2.resize(bgr, (52, 52), interpolation=cv2.INTER_AREA), cv2.COLOR_BGR2RGB)


def reduce(outputs: list[np.ndarray]) -> dict[str, np.ndarray]:
    """The outputs kept in the fixture (see the module docstring), as float32."""
    return {
        "cls8_max": outputs[0][0].max(axis=1),
        "reg8_max": outputs[3][0].max(axis=1),
        "cls16": outputs[1][0],
        "cls32": outputs[2][0],
        "reg16": outputs[4][0],
        "reg32": outputs[5][0],
    }


def main() -> None:
    seed = seed_image()
    x = graph_input(np.repeat(np.repeat(seed, 8, axis=0), 8, axis=1)).numpy()
    with tempfile.TemporaryDirectory() as tmp:
        (Path(tmp) / "input.f32").write_bytes(x.astype("<f4").tobytes())
        shapes = subprocess.run(
            [
                "node",
                str(HERE / "reference.js"),
                str(MODEL_DIR / "nanodet.json"),
                f"{tmp}/input.f32",
                ",".join(map(str, x.shape)),
                tmp,
                *OUTPUTS,
            ],
            check=True,
            capture_output=True,
            text=True,
        ).stdout
        outputs = []
        for index, line in enumerate(shapes.strip().splitlines()):
            shape = [int(s) for s in line.split(" ", 1)[1].strip("[]").split(",")]
            outputs.append(np.fromfile(f"{tmp}/{index}.f32", "<f4").reshape(shape))
    kept = {name: value.astype(np.float16) for name, value in reduce(outputs).items()}
    np.savez_compressed(HERE / "nanodet_reference.npz", seed=seed, **kept)


if __name__ == "__main__":
    main()
