"""A folder of many small inputs through the command line: when the batch starts, when the
first result appears, peak memory, and whether the summary counts are right.

    nice -n 10 python bench/big_folder.py [--count 10000] [--jobs 2] [--iterations 1] [--limit K]

Makes ``count`` small silhouette PNGs (48x48, ellipses of seven sizes), runs
``jeanscv IN -o OUT -j JOBS --iterations N --starts 1`` and timestamps its stderr lines:
the header (printed once the folder is listed), when the first file started (its result
time less the seconds its line gives), its result, the summary. The memory of the whole
process tree (parent and workers) is sampled every 0.2 s from /proc. For comparison, one
input alone (no workers) and two inputs with the same ``-j``: their time to a result is
what start-up (imports, worker processes) and the first fit cost, whatever the folder size. ``--limit K`` stops after K
results (a quick look); the summary check then does not apply.
"""

from __future__ import annotations

import argparse
import os
import re
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path


def make_inputs(folder: Path, count: int) -> None:
    import numpy as np
    from PIL import Image

    yy, xx = np.mgrid[:48, :48]
    masks = []
    for r in range(10, 17):
        masks.append(((((xx - 24) ** 2 / (r * r) + (yy - 24) ** 2 / (2 * r * r)) < 1) * 255).astype(np.uint8))
    folder.mkdir(parents=True)
    for i in range(count):
        Image.fromarray(masks[i % len(masks)]).save(folder / f"s{i:05d}.png")


def _tree(pid: int) -> list[int]:
    parents: dict[int, int] = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                parents[int(entry.name)] = int((entry / "stat").read_text().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                pass
    tree, todo = [], [pid]
    while todo:
        current = todo.pop()
        tree.append(current)
        todo.extend(child for child, parent in parents.items() if parent == current)
    return tree


def _rss(pid: int) -> int:
    try:
        for line in (Path("/proc") / str(pid) / "status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) * 1024
    except OSError:
        pass
    return 0


def run(arguments: list[str], limit: int | None) -> dict:
    """Run jeanscv; times of its milestones, its last lines and peak memory."""
    began = time.perf_counter()
    process = subprocess.Popen(
        [sys.executable, "-m", "jeanscv", *arguments],
        stderr=subprocess.PIPE,
        stdout=subprocess.DEVNULL,
        text=True,
        start_new_session=True,  # --limit stops its workers too, before the folder is removed
    )
    peak = {"total": 0, "one": 0}
    stop = threading.Event()

    def sample() -> None:
        while not stop.wait(0.2):
            sizes = [_rss(pid) for pid in _tree(process.pid)]
            peak["total"] = max(peak["total"], sum(sizes))
            peak["one"] = max([peak["one"], *sizes])

    sampler = threading.Thread(target=sample, daemon=True)
    sampler.start()
    figures: dict = {"header": None, "first": None, "taken": None, "results": 0, "last": ""}
    assert process.stderr is not None
    for line in process.stderr:
        now = time.perf_counter() - began
        if line.startswith("jeanscv ") and figures["header"] is None:
            figures["header"] = now
        elif line.startswith("["):
            figures["results"] += 1
            if figures["first"] is None:
                figures["first"] = now
                took = re.search(r"\(([\d.]+) s\)$", line.strip())
                figures["taken"] = now - float(took.group(1)) if took else None
            if limit and figures["results"] >= limit:
                os.killpg(process.pid, signal.SIGKILL)
                break
        figures["last"] = line.strip()
    process.wait()
    stop.set()
    sampler.join()
    figures.update(seconds=time.perf_counter() - began, peak=peak, code=process.returncode)
    return figures


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--count", type=int, default=10_000)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--iterations", type=int, default=1)
    parser.add_argument("--limit", type=int, default=0, help="stop after this many results")
    args = parser.parse_args()

    with tempfile.TemporaryDirectory(prefix="jeanscv-big-") as tmp:
        folder = Path(tmp) / "in"
        began = time.perf_counter()
        make_inputs(folder, args.count)
        print(f"{args.count} inputs made in {time.perf_counter() - began:.1f} s")
        common = ["--iterations", str(args.iterations), "--starts", "1"]

        one = run([str(folder / "s00000.png"), "-o", str(Path(tmp) / "one"), *common], None)
        print(f"one input alone: first result after {one['first']:.2f} s (imports and the first fit)")
        two = [str(folder / "s00000.png"), str(folder / "s00001.png"), "-o", str(Path(tmp) / "two")]
        pair = run([*two, "-j", str(args.jobs), *common], None)
        print(f"two inputs, -j {args.jobs}: first result after {pair['first']:.2f} s (and worker start-up)")

        figures = run([str(folder), "-o", str(Path(tmp) / "out"), "-j", str(args.jobs), *common], args.limit or None)
        print(f"folder of {args.count}, -j {args.jobs}:")
        print(f"  batch header (folder listed) after {figures['header']:.2f} s")
        print(f"  first file started after {figures['taken']:.2f} s")
        print(
            f"  first result after {figures['first']:.2f} s ({figures['first'] - pair['first']:+.2f} s against "
            f"two inputs, {figures['first'] - one['first']:+.2f} s against one)"
        )
        print(
            f"  {figures['results']} results in {figures['seconds']:.1f} s "
            f"({figures['results'] / figures['seconds']:.1f} inputs/s)"
        )
        print(
            f"  peak memory: {figures['peak']['total'] / 2**20:.0f} MiB for the whole process tree, "
            f"{figures['peak']['one'] / 2**20:.0f} MiB for the largest process"
        )
        if not args.limit:
            match = re.match(r"(\d+) ok, (\d+) failed, (\d+) skipped", figures["last"])
            right = match is not None and match.groups() == (str(args.count), "0", "0") and figures["code"] == 0
            print(f"  summary: {figures['last']!r} -> counts {'right' if right else 'WRONG'}, exit {figures['code']}")


if __name__ == "__main__":
    main()
