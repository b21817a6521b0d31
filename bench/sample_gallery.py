"""Run jeanscv on the bundled samples and write the README's before/after pictures.

    python -m bench.sample_gallery [--out docs]

Writes docs/samples/NAME.before.jpg and NAME.after.jpg (260 px tall), docs/hero.png,
and prints the markdown table for the README.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from PIL import Image

from jeanscv.api import apply_jeans

SAMPLES = Path(__file__).resolve().parents[1] / "sample_images"
NAMES = ["cat.jpg", "coffee.jpg", "astronaut.jpg", "rocket_exif6.jpg", "horse_cutout.png", "coffee.dng"]
HEIGHT = 260


def on_white(pixels: np.ndarray) -> Image.Image:
    image = Image.fromarray(pixels)
    if image.mode == "RGBA":
        ground = Image.new("RGBA", image.size, "white")
        ground.alpha_composite(image)
        image = ground
    image = image.convert("RGB")
    return image.resize((round(image.width * HEIGHT / image.height), HEIGHT), Image.LANCZOS)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", default="docs")
    args = parser.parse_args()
    out = Path(args.out)
    (out / "samples").mkdir(parents=True, exist_ok=True)
    print("| input | before | after | silhouette | rules | seconds |")
    print("|---|---|---|---|---|---|")
    afters = []
    for name in NAMES:
        began = time.perf_counter()
        result = apply_jeans(SAMPLES / name)
        seconds = time.perf_counter() - began
        stem = name.replace(".", "_")
        before, after = on_white(result.source.pixels), on_white(result.image)
        before.save(out / "samples" / f"{stem}.before.jpg", quality=85)
        after.save(out / "samples" / f"{stem}.after.jpg", quality=85)
        afters.append(after)
        rules = result.report()["rules"]
        print(
            f"| `{name}` | ![](docs/samples/{stem}.before.jpg) | ![](docs/samples/{stem}.after.jpg) "
            f"| {result.silhouette.method} | {'6/6' if rules['passed'] else 'fails a check'} | {seconds:.1f} |",
            flush=True,
        )
    chosen = [afters[NAMES.index(n)] for n in ("astronaut.jpg", "coffee.jpg", "cat.jpg")]
    hero = Image.new("RGB", (sum(a.width for a in chosen), HEIGHT), "white")
    x = 0
    for image in chosen:
        hero.paste(image, (x, 0))
        x += image.width
    hero.save(out / "hero.png")


if __name__ == "__main__":
    main()
