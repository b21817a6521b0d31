"""``jeanscv serve`` latency through its HTTP interface: page load, drop to jeans, click to jeans.

    python -m bench.serve_latency                 # 4 shared real photos, upscaled to 12 MP
    python -m bench.serve_latency --photos 8 --clicks 5 --think 1.0
    python -m bench.serve_latency --page          # the page's load time and weight alone

A fresh server (its own process, 127.0.0.1, the fit kernels already compiled on this
installation) is started; then:

* page: ``GET /`` with its script and style, 20 times: median seconds and total bytes;
* drop: each photo (a ``../shared/real_photos`` photo upscaled to 12 MP, JPEG q92) is
  uploaded and its preview fetched: seconds until the page has its jeans;
* clicks: after ``--think`` seconds (a person looks before clicking; the server builds
  the photo's click session meanwhile), the simulated-click protocol of
  ``bench/clicks.py`` (the next click in the largest error region of the outline the
  server drew) sends ``--clicks`` clicks, each a render plus the preview fetch.

Prints per photo and the medians, the first click after each drop on its own (it waits
for the click session when the person clicks before its set-up is done; ``--think 0``
clicks the moment the jeans appear) and the drop to the first click's jeans (drop,
think and first click); targets: page < 0.1 s and < 300 KB, drop < 3 s, click median
< 0.5 s.
"""

from __future__ import annotations

import argparse
import io
import json
import statistics
import time

import cv2
import numpy as np
from PIL import Image

from bench.clicks import SHARED, photo_pairs, upscale
from bench.serve_client import Server
from jeanscv.subject.interactive import simulated_click
from jeanscv_cli.serve.app import _SCRIPTS


def outline_mask(objects: list, size: tuple[int, int]) -> np.ndarray:
    """The server's outlines (photo pixels) filled: the mask the page shows."""
    width, height = size
    mask = np.zeros((height, width), np.uint8)
    for obj in objects:
        for ring in obj["outline"]:
            cv2.fillPoly(mask, [np.round(np.asarray(ring) * 8).astype(np.int32)], 1, shift=3)
    return mask.astype(bool)


#: What the page loads: the HTML, its ES modules (app.js and those it imports), the style.
PAGE = ("/", *(f"/static/{name}" for name in _SCRIPTS), "/static/style.css")


def page_load(server: Server, rounds: int = 20) -> tuple[float, int]:
    seconds, size = [], 0
    for _ in range(rounds):
        began = time.perf_counter()
        size = 0
        for path in PAGE:
            status, _, body = server.request("GET", path)
            assert status == 200, path
            size += len(body)
        seconds.append(time.perf_counter() - began)
    return statistics.median(seconds), size


def page_line(load: float, weight: int) -> str:
    """The page's figures as printed: its load time and its weight as served."""
    return f"page: {load * 1000:.1f} ms (median of 20: /, {len(_SCRIPTS)} scripts, style.css), {weight / 1024:.1f} KB"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--photos", type=int, default=4)
    parser.add_argument("--clicks", type=int, default=5)
    parser.add_argument("--megapixels", type=float, default=12.0)
    parser.add_argument("--think", type=float, default=1.0, help="seconds between the jeans and the first click")
    parser.add_argument("--page", action="store_true", help="only the page's load time and weight (no photos needed)")
    args = parser.parse_args()
    if args.page:
        server = Server()
        try:
            print(page_line(*page_load(server)))
        finally:
            server.stop()
            server.remove()
        return
    pairs = photo_pairs([SHARED])[: args.photos]
    if not pairs:
        raise SystemExit(f"no photos with masks in {SHARED}")
    photos = []
    for name, photo_path, mask_path in pairs:
        pixels = np.asarray(Image.open(photo_path).convert("RGB"))
        reference = np.asarray(Image.open(mask_path).convert("L")) >= 128
        big, mask = upscale(pixels, reference, args.megapixels)
        buffer = io.BytesIO()
        Image.fromarray(big).save(buffer, "JPEG", quality=92)
        photos.append((name, buffer.getvalue(), mask))

    server = Server()
    try:
        print(page_line(*page_load(server)))
        drops, clicks, firsts, to_first = [], [], [], []
        for name, data, reference in photos:
            dropped = began = time.perf_counter()
            status, _, body = server.upload(f"{name}.jpg", data)
            answer = json.loads(body)
            assert status == 200, answer
            server.request("GET", answer["preview"])
            drop = time.perf_counter() - began
            drops.append(drop)
            time.sleep(args.think)
            size = (answer["width"], answer["height"])
            positive, negative, mine = [], [], []
            predicted = None
            for _ in range(args.clicks):
                sign, point = simulated_click(reference, predicted)
                (positive if sign else negative).append([round(point[0], 1), round(point[1], 1)])
                began = time.perf_counter()
                status, _, body = server.render(answer["photo"], [{"positive": positive, "negative": negative}])
                result = json.loads(body)
                assert status == 200, result
                if "nothing" in result:  # nothing clear there: the page takes the click back
                    (positive if sign else negative).pop()
                else:
                    server.request("GET", result["preview"])
                    predicted = outline_mask(result["objects"], size)
                mine.append(time.perf_counter() - began)
                if len(mine) == 1:
                    to_first.append(time.perf_counter() - dropped)
            clicks += mine
            firsts.append(mine[0])
            print(
                f"{name}: {size[0]}x{size[1]} drop {drop:.2f} s, clicks "
                + " ".join(f"{s:.2f}" for s in mine)
                + f" s (median {statistics.median(mine):.2f})"
            )
        print(
            f"drop to jeans: median {statistics.median(drops):.2f} s, max {max(drops):.2f} s; "
            f"click to jeans: median {statistics.median(clicks):.2f} s over {len(clicks)} clicks; "
            f"first click: median {statistics.median(firsts):.2f} s, max {max(firsts):.2f} s; "
            f"drop to the first click's jeans: median {statistics.median(to_first):.2f} s (think {args.think:g} s)"
        )
    finally:
        code, seconds = server.stop()
        print(f"Ctrl-C: exit status {code} in {seconds:.1f} s; temporary files left: {len(server.leftovers())}")
        server.remove()


if __name__ == "__main__":
    main()
