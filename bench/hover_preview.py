"""How often the web page's hover preview shows what a first click there takes.

    python -m bench.hover_preview                      # sample_images + ../shared/pet_photos
    python -m bench.hover_preview PHOTO [PHOTO ...] --points 12

For each photo: the click session, then its first-click map (the time it takes), then
``--points`` random points (fixed seed): the region the map shows there against the mask
a first click there takes (``ClickSession.working_mask``, its GrabCut and refinement
included; "nothing found" is an empty mask). Prints per photo and overall the mean IoU,
the share of points with IoU >= 0.8 and >= 0.5, and the map's time and size on the wire.
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import numpy as np

from jeanscv.io.image import load_image
from jeanscv.subject.consensus import iou
from jeanscv.subject.hover import first_click_map
from jeanscv.subject.interactive import ClickSession

ROOT = Path(__file__).resolve().parents[1]
DEFAULT = [
    *sorted((ROOT / "sample_images").glob("*.jpg")),
    *sorted((ROOT.parent / "shared" / "pet_photos").glob("*.jpg"))[::4],
]


def measure(path: Path, points: int, rng: np.random.Generator) -> tuple[list[float], float, int]:
    """IoUs at ``points`` random points, the map's time (s) and its bytes on the wire."""
    from jeanscv_cli.serve.engine import encode_hover_map

    pixels = np.ascontiguousarray(load_image(path).pixels[..., :3])
    session = ClickSession(pixels)
    began = time.perf_counter()
    found = first_click_map(session)
    seconds = time.perf_counter() - began
    wire = len(encode_hover_map(found, session.shape[::-1]))
    height, width = session.shape
    w, h = session.size
    scores = []
    for _ in range(points):
        wx, wy = int(rng.integers(w)), int(rng.integers(h))
        shown = found.mask(found.at(wx, wy))
        taken = session.working_mask([((wx + 0.5) * width / w, (wy + 0.5) * height / h)])
        if np.count_nonzero(taken) < session._smallest:  # segment() says "nothing found there"
            taken = np.zeros_like(taken)
        scores.append(iou(shown, taken))
    return scores, seconds, wire


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("photos", nargs="*", type=Path)
    parser.add_argument("--points", type=int, default=10)
    args = parser.parse_args()
    rng = np.random.default_rng(32)
    every, times = [], []
    for path in args.photos or DEFAULT:
        scores, seconds, wire = measure(path, args.points, rng)
        every += scores
        times.append(seconds)
        good = np.mean(np.array(scores) >= 0.8)
        print(f"{path.name:40s} IoU {np.mean(scores):.3f}  >=0.8 {good:.0%}  map {seconds:.2f} s  {wire / 1024:.0f} KB")
    scores = np.array(every)
    print(
        f"{'all':40s} IoU {scores.mean():.3f}  >=0.8 {np.mean(scores >= 0.8):.0%}  >=0.5 {np.mean(scores >= 0.5):.0%}"
        f"  ({len(scores)} points; map median {statistics.median(times):.2f} s)"
    )


if __name__ == "__main__":
    main()
