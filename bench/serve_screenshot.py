"""Regenerate ``docs/serve.jpg``: the page in use, as the browser test leaves it
(a photo dropped, the dog clicked, a caption typed), ``docs/serve-folder.jpg``: folder
mode after a photo's clicks were saved, ``docs/serve-hover.jpg``: the hover preview
of the dog, before any click, and ``docs/serve-phone.jpg``: the page on a phone, in Remove mode.

    python -m bench.serve_screenshot [OUT.jpg|OUT.png] [--folder F.jpg] [--hover H.jpg] [--phone P.jpg]

Runs ``tests/test_serve_browser.py`` with ``JEANSCV_SCREENSHOT`` set (Debian's Chromium,
driven by Playwright, on a server bound to 127.0.0.1).
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
    parser.add_argument("--folder", type=Path, default=ROOT / "docs" / "serve-folder.jpg", help="folder mode's .jpg")
    parser.add_argument("--hover", type=Path, default=ROOT / "docs" / "serve-hover.jpg", help="hover preview's .jpg")
    parser.add_argument("--phone", type=Path, default=ROOT / "docs" / "serve-phone.jpg", help="the phone's .jpg")
    args = parser.parse_args()
    out, folder, hover, phone = (path.resolve() for path in (args.out, args.folder, args.hover, args.phone))
    env = {
        **os.environ,
        "JEANSCV_SCREENSHOT": str(out),
        "JEANSCV_FOLDER_SCREENSHOT": str(folder),
        "JEANSCV_HOVER_SCREENSHOT": str(hover),
        "JEANSCV_PHONE_SCREENSHOT": str(phone),
    }
    tests = [
        "tests/test_serve_browser.py::test_drop_click_caption_download",
        "tests/test_serve_browser.py::test_folder_mode_saves_reverts_and_shows_it_at_once",
        "tests/test_serve_browser.py::test_the_hover_preview_outlines_what_a_click_would_take",
        "tests/test_serve_browser.py::test_a_phone_by_touch_alone",
    ]
    done = subprocess.run([sys.executable, "-m", "pytest", "-q", *tests], cwd=ROOT, env=env)
    if done.returncode or not all(path.is_file() for path in (out, folder, hover, phone)):
        raise SystemExit(f"the browser tests failed; no screenshots (exit status {done.returncode})")
    for path in (out, folder, hover, phone):
        print(f"wrote {path} ({path.stat().st_size / 1024:.0f} KB)")


if __name__ == "__main__":
    main()
