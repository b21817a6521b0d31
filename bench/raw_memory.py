"""Time and peak memory of the command line on a large camera RAW file.

    python -m bench.raw_memory [--megapixels 24]

Makes a photo of about ``megapixels`` MP (an animal-like object on a real texture, as
``bench/batch_speed.py`` does), mosaics it into a 12-bit Bayer DNG (as the bundled
``sample_images/coffee.dng`` is made), and runs ``jeanscv BIG.dng -o OUT -q`` on it: at
the camera's full size (the default), with ``--raw-half-size``, and with ``--objects
all``. Prints the wall time, the peak resident memory of the CLI process and the
output's size for each.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

from bench.batch_speed import run

ROOT = Path(__file__).resolve().parents[1]

# Made in a child process, so this process stays small (see batch_speed.py).
_MAKE = (
    "import sys; from pathlib import Path\n"
    "import numpy as np; from PIL import Image\n"
    "from bench.batch_speed import make_photo; from sample_images.make_samples import write_dng\n"
    "jpeg = Path(sys.argv[1]).with_suffix('.jpg'); make_photo(jpeg, 7, float(sys.argv[2]))\n"
    "pixels = np.asarray(Image.open(jpeg).convert('RGB')); jpeg.unlink()\n"
    "write_dng(pixels[: pixels.shape[0] // 2 * 2, : pixels.shape[1] // 2 * 2], Path(sys.argv[1]))\n"
)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--megapixels", type=float, default=24.0)
    args = parser.parse_args()
    from PIL import Image

    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp) / "raw"
        folder.mkdir()
        dng = folder / "big.dng"
        subprocess.run(
            [
                sys.executable,
                "-c",
                _MAKE,
                str(dng),
                str(args.megapixels),
            ],
            check=True,
            cwd=ROOT,  # where ``bench`` and ``sample_images`` are importable
        )
        print(f"{dng.name}: {dng.stat().st_size / 1e6:.0f} MB DNG")
        print("| options | wall s | peak RSS (MB) | output size |")
        print("|---|---|---|---|")
        for label, options in (
            ("(default: full size)", []),
            ("--raw-half-size", ["--raw-half-size"]),
            ("--objects all", ["--objects", "all"]),
        ):
            out = Path(tmp) / f"out{len(options)}"
            wall, peak = run(dng, out, 1, options)
            with Image.open(out / "big.jeans.jpg") as image:
                size = f"{image.width}x{image.height}"
            print(f"| {label} | {wall:.1f} | {peak:.0f} | {size} |", flush=True)


if __name__ == "__main__":
    main()
