"""Outputs of a fixed corpus, to check that a refactoring changes no byte.

``write DIR`` runs the installed ``jeanscv`` command over the corpus, once per garment and
style, with the JSON, SVG and GIF sidecars, and puts every output under ``DIR``;
``compare A B`` compares two such folders file by file, ignoring the ``seconds`` fields
of the JSON reports (the only part of an output that depends on the clock).

The corpus: every file in ``sample_images/``, the shared silhouettes
(``../shared/silhouettes/*.svg`` and ``*.png``) and the first few shared real photos
(``--photos``), where ``../shared`` exists. Runs: every garment in both styles with
``--posture any``, and the default jeans upright.

    python -m bench.corpus_outputs write /tmp/before -j 2
    ... change the code ...
    python -m bench.corpus_outputs write /tmp/after -j 2
    python -m bench.corpus_outputs compare /tmp/before /tmp/after
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared"
GARMENTS = ("jeans", "shorts", "skirt")
STYLES = ("denim", "flat")
IMAGE_SUFFIXES = {".png", ".jpg", ".jpeg", ".dng", ".svg"}


def corpus(photos: int) -> list[Path]:
    """The corpus' input files, in a fixed order."""
    files = sorted(p for p in (ROOT / "sample_images").iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)
    silhouettes = SHARED / "silhouettes"
    if silhouettes.is_dir():
        files += sorted([*silhouettes.glob("*.svg"), *silhouettes.glob("*.png")])
    real = SHARED / "real_photos"
    if real.is_dir():
        files += sorted(p for p in real.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES and ".mask" not in p.name)[
            :photos
        ]
    return files


def runs() -> dict[str, list[str]]:
    """Name -> extra command-line options of every run over the corpus."""
    table = {
        f"{garment}-{style}-any": ["--garment", garment, "--style", style, "--posture", "any"]
        for garment in GARMENTS
        for style in STYLES
    }
    table["jeans-denim-upright"] = []
    return table


def write(folder: Path, photos: int, jobs: int, only: list[str] | None = None) -> None:
    """Run every run (or those named in ``only``) over the corpus, outputs under ``folder/RUN/``."""
    files = corpus(photos)
    # Inputs are copied into one flat folder and the command runs in ``folder`` with
    # relative paths, so the reports' file names do not depend on where things were.
    folder.mkdir(parents=True, exist_ok=True)
    inputs = folder / "_inputs"
    inputs.mkdir(exist_ok=True)
    for path in files:
        shutil.copyfile(path, inputs / f"{path.parent.name}__{path.name}")
    try:
        for name, extra in runs().items():
            if only and name not in only:
                continue
            command = ["jeanscv", inputs.name, "-o", name, "--json", "--svg", "--gif", "-j", str(jobs), "-q"]
            done = subprocess.run([*command, *extra], cwd=folder, check=False)
            print(f"{name}: {len(files)} inputs, exit status {done.returncode}", flush=True)
    finally:
        shutil.rmtree(inputs)


def _without_seconds(value):
    if isinstance(value, dict):
        return {k: _without_seconds(v) for k, v in value.items() if k not in ("seconds", "fit_seconds")}
    if isinstance(value, list):
        return [_without_seconds(v) for v in value]
    return value


def compare(before: Path, after: Path) -> int:
    """Print the differing, missing and extra files; the number of problems."""
    # Only the runs both folders hold are compared (a quick check may write only some).
    common = {p.name for p in before.iterdir() if p.is_dir()} & {p.name for p in after.iterdir() if p.is_dir()}
    names_before = {
        p.relative_to(before) for p in before.rglob("*") if p.is_file() and p.relative_to(before).parts[0] in common
    }
    names_after = {
        p.relative_to(after) for p in after.rglob("*") if p.is_file() and p.relative_to(after).parts[0] in common
    }
    problems = [f"missing: {name}" for name in sorted(names_before - names_after)]
    problems += [f"extra: {name}" for name in sorted(names_after - names_before)]
    same = 0
    for name in sorted(names_before & names_after):
        a, b = (before / name).read_bytes(), (after / name).read_bytes()
        if a != b and name.suffix == ".json":
            equal = _without_seconds(json.loads(a)) == _without_seconds(json.loads(b))
        else:
            equal = a == b
        if equal:
            same += 1
        else:
            problems.append(f"differs: {name}")
    for line in problems:
        print(line)
    print(f"runs compared: {', '.join(sorted(common))}")
    print(f"{same} identical, {len(problems)} problems ({len(names_before)} files before, {len(names_after)} after)")
    return len(problems)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    write_parser = sub.add_parser("write", help="write the corpus' outputs to a folder")
    write_parser.add_argument("folder", type=Path)
    write_parser.add_argument("--photos", type=int, default=4, help="shared real photos to include")
    write_parser.add_argument("-j", "--jobs", type=int, default=2)
    write_parser.add_argument("--runs", nargs="+", choices=list(runs()), help="only these runs (default: all)")
    compare_parser = sub.add_parser("compare", help="compare two folders, ignoring JSON 'seconds'")
    compare_parser.add_argument("before", type=Path)
    compare_parser.add_argument("after", type=Path)
    args = parser.parse_args()
    if args.command == "write":
        write(args.folder, args.photos, args.jobs, args.runs)
        return 0
    return 1 if compare(args.before, args.after) else 0


if __name__ == "__main__":
    sys.exit(main())
