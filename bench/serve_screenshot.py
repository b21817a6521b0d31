"""Regenerate ``docs/serve.jpg``: the page in use, as the browser test leaves it
(a photo dropped, the dog clicked, a caption typed), and ``docs/serve-folder.jpg``: folder
mode after a photo's clicks were saved.

    python -m bench.serve_screenshot [OUT.jpg|OUT.png] [--folder FOLDER_OUT.jpg]

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
    args = parser.parse_args()
    out, folder = args.out.resolve(), args.folder.resolve()
    env = {**os.environ, "JEANSCV_SCREENSHOT": str(out), "JEANSCV_FOLDER_SCREENSHOT": str(folder)}
    tests = [
        "tests/test_serve_browser.py::test_drop_click_caption_download",
        "tests/test_serve_browser.py::test_folder_mode_saves_reverts_and_shows_it_at_once",
    ]
    done = subprocess.run([sys.executable, "-m", "pytest", "-q", *tests], cwd=ROOT, env=env)
    if done.returncode or not out.is_file() or not folder.is_file():
        raise SystemExit(f"the browser tests failed; no screenshots (exit status {done.returncode})")
    for path in (out, folder):
        print(f"wrote {path} ({path.stat().st_size / 1024:.0f} KB)")


if __name__ == "__main__":
    main()
