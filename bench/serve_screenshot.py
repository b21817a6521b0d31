"""Regenerate ``docs/serve.jpg``: the page in use, as the browser test leaves it
(a photo dropped, the dog clicked, a caption typed).

    python -m bench.serve_screenshot [OUT.jpg|OUT.png]

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
    out = parser.parse_args().out.resolve()
    env = {**os.environ, "JEANSCV_SCREENSHOT": str(out)}
    test = "tests/test_serve_browser.py::test_drop_click_caption_download"
    done = subprocess.run([sys.executable, "-m", "pytest", "-q", test], cwd=ROOT, env=env)
    if done.returncode or not out.is_file():
        raise SystemExit(f"the browser test failed; no screenshot (exit status {done.returncode})")
    print(f"wrote {out} ({out.stat().st_size / 1024:.0f} KB)")


if __name__ == "__main__":
    main()
