"""How often the web page's hover preview shows what a first click there takes.

    python -m bench.hover_preview                      # sample_images + ../shared/pet_photos
    python -m bench.hover_preview PHOTO [PHOTO ...] --points 12
    python -m bench.hover_preview --browser PHOTO      # the page's update time, in Chromium

For each photo: the click session, then its first-click map (the time it takes), then
``--points`` random points (fixed seed): the region the map shows there against the mask
a first click there takes (``ClickSession.working_mask``, its GrabCut and refinement
included; "nothing found" is an empty mask). Prints per photo and overall the mean IoU,
the share of points with IoU >= 0.8 and >= 0.5, and the map's time and size on the wire. With ``--browser``: ``jeanscv serve`` and Debian's
Chromium (Playwright); each photo is opened on the page and the pointer moved over a
12x12 grid, twice; prints the median and the longest update (the page's own
``performance.now()`` around its lookup and drawing).
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
        if np.count_nonzero(taken) < session._smallest:  # segment() says "nothing clear there"
            taken = np.zeros_like(taken)
        scores.append(iou(shown, taken))
    return scores, seconds, wire


def browser_times(paths: list[Path]) -> None:
    """The page's hover updates, timed by the page, over a grid of pointer positions."""
    import threading

    import uvicorn
    from playwright.sync_api import sync_playwright

    from jeanscv_cli.serve.app import Config, create_app

    port = 8731
    server = uvicorn.Server(uvicorn.Config(create_app(Config(port=port)), port=port, log_level="error"))
    threading.Thread(target=server.run, daemon=True).start()
    while not server.started:
        time.sleep(0.05)
    try:
        with sync_playwright() as playwright:
            chromium = playwright.chromium.launch(executable_path="/usr/bin/chromium", args=["--no-sandbox"])
            page = chromium.new_page(viewport={"width": 1280, "height": 860})
            page.goto(f"http://127.0.0.1:{port}/")
            for path in paths:
                page.set_input_files("#file", str(path))
                page.wait_for_function(
                    "() => document.getElementById('frame').dataset.hover === 'ready'", timeout=120_000
                )
                box = page.locator("#result").bounding_box()
                times = []
                for _ in range(2):  # the second pass draws from the page's cache of regions
                    for fy in np.linspace(0.05, 0.95, 12):
                        for fx in np.linspace(0.05, 0.95, 12):
                            page.mouse.move(box["x"] + fx * box["width"], box["y"] + fy * box["height"])
                            times.append(float(page.evaluate("() => document.getElementById('frame').dataset.hoverMs")))
                print(f"{path.name:40s} update median {statistics.median(times):.1f} ms, longest {max(times):.1f} ms")
            chromium.close()
    finally:
        server.should_exit = True


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("photos", nargs="*", type=Path)
    parser.add_argument("--points", type=int, default=10)
    parser.add_argument("--browser", action="store_true", help="time the page's updates in Chromium")
    args = parser.parse_args()
    if args.browser:
        browser_times(args.photos or DEFAULT[:4])
        return
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
