"""Regenerate ``docs/serve.jpg``: the page in use, as the browser test leaves it
(a photo dropped, the dog clicked, a caption typed), ``docs/serve-folder.png``: folder
mode with the unsure photo first and open, ``docs/serve-hover.jpg``: the hover preview
of the dog, before any click, and ``docs/serve-phone.png``: the page on a phone, the
owner boxed with one finger in Box mode.

    python -m bench.serve_screenshot [OUT.jpg|OUT.png] [--folder F.png] [--hover H.jpg] [--phone P.png]

Runs the browser tests that take them (``tests/test_serve_browser.py`` and
``tests/test_serve_browser_touch.py``, Debian's Chromium driven by Playwright, on a
server bound to 127.0.0.1) with the variables that ask for the pictures set.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("out", nargs="?", type=Path, default=ROOT / "docs" / "serve.jpg", help="a .jpg or .png")
    parser.add_argument("--folder", type=Path, default=ROOT / "docs" / "serve-folder.png", help="folder mode's .png")
    parser.add_argument("--hover", type=Path, default=ROOT / "docs" / "serve-hover.jpg", help="hover preview's .jpg")
    parser.add_argument("--phone", type=Path, default=ROOT / "docs" / "serve-phone.png", help="the phone's .png")
    args = parser.parse_args()
    out, folder, hover, phone = (path.resolve() for path in (args.out, args.folder, args.hover, args.phone))
    env = {
        **os.environ,
        "JEANSCV_SCREENSHOT": str(out),
        "JEANSCV_FOLDER_PNG": str(folder),
        "JEANSCV_HOVER_SCREENSHOT": str(hover),
        "JEANSCV_PHONE_PNG": str(phone),
    }
    tests = [
        "tests/test_serve_browser.py::test_drop_click_caption_download",
        "tests/test_serve_browser_touch.py::test_folder_marks_unsure_photos_as_their_answers_come",
        "tests/test_serve_browser.py::test_the_hover_preview_outlines_what_a_click_would_take",
        "tests/test_serve_browser_touch.py::test_a_box_drawn_with_one_finger_in_box_mode",
    ]
    done = subprocess.run([sys.executable, "-m", "pytest", "-q", *tests], cwd=ROOT, env=env)
    if done.returncode or not all(path.is_file() for path in (out, folder, hover, phone)):
        raise SystemExit(f"the browser tests failed; no screenshots (exit status {done.returncode})")
    for path in (out, folder, hover, phone):
        print(f"wrote {path} ({path.stat().st_size / 1024:.0f} KB)")


if __name__ == "__main__":
    main()
