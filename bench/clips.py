"""Clips: frames a second, peak memory, mask IoU and jeans jitter on synthetic clips.

    python -m bench.clips [--frames 300] [--width 1280] [--only moving,still,...] [--strip PNG]
    python -m bench.clips --memory        peak memory, 300 frames against 1200 (smaller frames)
    python -m bench.clips --large [--frames 60] [--size 3840x2160]
                                          a 4K clip through the command: peak memory, frames a second
    python -m bench.clips --look CLIP     CLIP.strip.png: 8 of its frames, to look at
    python -m bench.clips --docs docs/clips   docs/clips.md's example clips and strip
    python -m bench.clips --real [--detector auto|none] [--only camel,...] [--strip DIR]
                                          the real clips of ../shared/clips, against their masks

Each case is a real pet cut out of ``../shared/pet_photos`` by its mask (a procedural
animal when that folder is absent) pasted on a real photo of ``../shared/real_photos``,
moving, turning and growing with an exact mask on every frame (:mod:`testkit.synthetic_clips`),
written as an H.264 MP4 (CRF 20: the codec's noise is in the input, as in a phone clip);
then ``write_jeans_clip`` runs on it end to end (decode, follow, fit, paint, encode) and
its own callback records each frame's masks and vertices. Figures:

- ``fps``: frames a second of the whole run, the first frame's full segmentation included
  (wall clock; the machine is shared, so the load average is printed beside it);
- ``IoU min/mean``: the followed mask of the (first) object against the true mask;
- ``follow`` and ``jitter`` (px): the mean and RMS distance of each frame's vertices from
  the previous frame's carried by the true motion: how closely the jeans move with the
  subject from frame to frame (on the still clip, their frame-to-frame shake);
- ``drift`` and ``worst`` (px): the mean and worst distance of the vertices from frame 0's
  jeans glued to the subject: what accumulates over the clip (motion errors, and the fit
  settling on the followed masks, which differ from the first frame's segmentation);
- ``flips``: frames whose posture differs from the first frame's.

``--strip`` writes a contact strip of frames (input, and output with the followed mask's
outline in green) to look at.

``--real``: each clip of ``../shared/clips`` (real footage, a reference mask on every
frame: :mod:`testkit.real_clip_set`) through ``apply_jeans_to_clip``, the subject found
automatically on frame 0 (``--detector``: with the shipped detector or classically).
Per clip: frames; the followed mask's mean (and worst) IoU against the reference; the
share of frames whose jeans have >= 85% of their pixels on the animal (as
``bench.real_photos``' "jeans on the subject"; a frame without jeans counts as off);
frames without jeans; ``jitter``, the RMS of the jeans vertices' second difference (px:
0 for a steady motion, a jump counts), ``whole``, the same of the jeans' centroid (their
shake as a whole), and ``own``, the same of the reference mask's centroid (the animal's
own motion, which the jeans' shake as a whole should stay under); seconds (wall) and CPU seconds a frame, the
machine's load beside them. ``--strip DIR`` writes ``DIR/NAME.strip.png``: 6 evenly
spaced output frames with the reference's outline in yellow and the followed mask's in
green; and ``DIR/real_clips.jpg``, those of every clip a row (docs/clips.md's figure).
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

from testkit import synthetic_clips as sc

ROOT = Path(__file__).resolve().parents[1]

#: name -> (pet photo, (background photo, its window as fractions x0, y0, x1, y1), motion:
#: travel as fractions of the frame, turn in degrees, grow as a fraction of the size).
CASES = {
    "moving": (
        "pet30-dog-hydrant",
        ("sailboat3.jpg", (0, 0.3, 0.33, 0.62)),
        dict(travel=(0.45, 0.08), turn=12.0, grow=0.15),
    ),
    "still": ("pet30-dog-hydrant", ("im_27.png", (0, 0.25, 0.35, 1.0)), dict(travel=(0.0, 0.0), turn=0.0, grow=0.0)),
    "cat": (
        "pet46-cat-suitcase",
        ("horse.jpg", (0.3, 0.78, 1.0, 1.0)),
        dict(travel=(-0.35, -0.05), turn=-8.0, grow=0.2),
    ),
    "bird": ("pet16-parrot-curtain", ("im_14.png", (0, 0, 0.5, 0.35)), dict(travel=(0.3, 0.1), turn=15.0, grow=-0.15)),
}


def make_clip(case: str, width: int, height: int, frames: int, path: Path):
    """Write the case's clip to ``path`` (MP4); returns ``(sprite, background, motion)``."""
    from jeanscv.io.clip import write_clip

    pet, (photo, window), moves = CASES[case]
    sprite = sc.pet_sprite(pet, long_side=int(0.42 * height)) or sc.texture_sprite(int(0.42 * height))
    ground = sc.background(width, height, photo, window)
    start = (0.28 * width if moves["travel"][0] >= 0 else 0.72 * width, 0.55 * height)
    motion = sc.Motion(
        start, (moves["travel"][0] * width, moves["travel"][1] * height), moves["turn"], moves["grow"], frames=frames
    )
    noise = 2.0 if case == "still" else 0.0
    made = (pixels for pixels, _, _ in sc.clip(sprite, ground, motion, noise=noise))
    write_clip(path, made, "mp4", fps=30.0)
    return sprite, ground, motion


def run_case(
    case: str, width: int, height: int, frames: int, strip: Path | None, auto: bool = False, detector: str = "auto"
) -> dict:
    from jeanscv.options import JeansOptions
    from jeanscv.run.clips import write_jeans_clip

    with tempfile.TemporaryDirectory() as folder:
        source, output = Path(folder, f"{case}.mp4"), Path(folder, f"{case}.jeans.mp4")
        sprite, ground, motion = make_clip(case, width, height, frames, source)
        ious, vertices, postures, shown = [], [], [], []
        every = max(1, frames // 8)

        spent = [0.0]  # seconds in this callback, taken out of the run's time

        def on_frame(result) -> None:
            began = time.perf_counter()
            true_mask = sc.true_mask(sprite, motion.transform(result.index, sprite), ground.shape[:2])
            obj = result.objects[0] if result.objects else None
            mask = obj.silhouette.mask >= 0.5 if obj is not None else np.zeros_like(true_mask)
            ious.append(sc.iou(mask, true_mask))
            vertices.append(None if obj is None else obj.silhouette.framing.to_image(obj.fit.vertices))
            postures.append(None if obj is None else result.report()["objects"][0]["posture"])
            if strip is not None and result.index % every == 0 and len(shown) < 8:
                shown.append(_outlined(result.image, mask))
            spent[0] += time.perf_counter() - began

        load = os.getloadavg()[0]
        began, cpu = time.perf_counter(), time.process_time()
        point = sc.inner_point(sc.frame(sprite, ground, motion.transform(0, sprite))[1])
        options = JeansOptions(detector=detector) if auto else JeansOptions(points=(point,), detector=detector)
        report = write_jeans_clip(source, output, options, on_frame=on_frame)
        seconds = time.perf_counter() - began - spent[0]
        cpu = time.process_time() - cpu - spent[0]
    follow, jitter, drift, worst = _motion_errors(vertices, motion, sprite)
    flips = sum(1 for p in postures if p is not None and p != postures[0])
    if strip is not None and shown:
        _write_strip(strip.with_name(f"{strip.stem}_{case}{strip.suffix}"), shown)
    return {
        "case": case,
        "frames": report["frames_written"],
        "seconds": seconds,
        "fps": report["frames_written"] / seconds,
        "cpu_ms": 1000 * cpu / report["frames_written"],
        "load": load,
        "iou_min": min(ious),
        "iou_mean": float(np.mean(ious)),
        "follow": follow,
        "drift": drift,
        "worst": worst,
        "jitter": jitter,
        "flips": flips,
        "lost": sum(v is None for v in vertices),
    }


def _motion_errors(vertices: list, motion: sc.Motion, sprite: sc.Sprite) -> tuple[float, float, float, float]:
    """``(follow, jitter, drift, worst drift)``: the mean and RMS distance of each frame's
    vertices from the previous frame's carried by the true motion (how well the jeans move
    with the subject, frame to frame), and the mean and worst distance from frame 0's
    jeans glued to the subject (what accumulates over the clip)."""
    m0 = motion.transform(0, sprite)
    steps, drift = [], []
    for index in range(1, len(vertices)):
        if vertices[index] is None or vertices[index - 1] is None:
            continue
        moved = sc.carried(vertices[index - 1], motion.transform(index - 1, sprite), motion.transform(index, sprite))
        steps.append(np.linalg.norm(vertices[index] - moved, axis=1))
        glued = sc.carried(vertices[0], m0, motion.transform(index, sprite))
        drift.append(np.linalg.norm(vertices[index] - glued, axis=1).mean())
    if not steps:
        return (float("nan"),) * 4
    steps = np.concatenate(steps)
    return float(steps.mean()), float(np.sqrt(np.mean(steps**2))), float(np.mean(drift)), float(np.max(drift))


def _outlined(image: np.ndarray, mask: np.ndarray, colour: tuple[int, int, int] = (0, 255, 0)) -> np.ndarray:
    out = np.ascontiguousarray(image[..., :3].copy())
    contours, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    cv2.drawContours(out, contours, -1, colour, 2)
    return out


def _write_strip(path: Path, images: list[np.ndarray], height: int = 180, across: int = 4) -> None:
    thumbs = [
        cv2.resize(im, (round(im.shape[1] * height / im.shape[0]), height), interpolation=cv2.INTER_AREA)
        for im in images
    ]
    rows = [np.hstack(thumbs[i : i + across]) for i in range(0, len(thumbs), across)]
    width = max(r.shape[1] for r in rows)
    rows = [np.pad(r, ((0, 0), (0, width - r.shape[1]), (0, 0))) for r in rows]
    cv2.imwrite(str(path), cv2.cvtColor(np.vstack(rows), cv2.COLOR_RGB2BGR))
    print(f"wrote {path}")


def run_real(folder: Path, detector: str, strip: Path | None, frames: int | None = None) -> dict:
    """One real clip (a folder of frames and masks) through ``apply_jeans_to_clip``,
    scored against its masks (:class:`testkit.real_clip_set.ClipScore`)."""
    from jeanscv.options import JeansOptions
    from jeanscv.run.clips import apply_jeans_to_clip
    from testkit import real_clip_set as rc

    paths = rc.frame_paths(folder)[:frames]
    picked = {round(k * (len(paths) - 1) / 5) for k in range(6)}
    score, shown, spent = rc.ClipScore(), [], 0.0
    load = os.getloadavg()[0]
    began, cpu = time.perf_counter(), time.process_time()
    for result in apply_jeans_to_clip(rc.read_frames(paths), JeansOptions(detector=detector), fps=24.0):
        start = time.perf_counter()
        truth = rc.reference(paths[result.index])
        mask = score.add(result, truth)
        if result.index in picked:
            shown.append(_outlined(_outlined(result.image, truth, (255, 230, 0)), mask))
        spent += time.perf_counter() - start
    seconds = time.perf_counter() - began - spent
    cpu = time.process_time() - cpu - spent
    if strip is not None:
        strip.mkdir(parents=True, exist_ok=True)
        _write_strip(strip / f"{folder.name}.strip.png", shown, height=150, across=3)
    count = len(paths)
    summary = score.summary()
    return {"case": folder.name, **summary, "s_frame": seconds / count, "cpu_frame": cpu / count, "load": load} | {
        "shown": shown
    }


def real(detector: str, only: str, strip: Path | None, frames: int | None) -> None:
    """``--real``: the table of :func:`run_real` over ``../shared/clips``."""
    from testkit import real_clip_set as rc

    folders = [f for f in rc.clip_folders() if not only or f.name in only.split(",")]
    if not folders:
        print(f"no clips in {rc.CLIPS}", file=sys.stderr)
        return
    print(f"detector {detector}")
    print(
        f"{'clip':8} {'frames':>6} {'IoU mean':>8} {'min':>6} {'>=85%':>6} {'no jeans':>8} {'jitter':>6} "
        f"{'whole':>5} {'own':>5} {'s/frame':>7} {'cpu/frame':>9} {'load':>5}"
    )
    rows = []
    for folder in folders:
        r = run_real(folder, detector, strip, frames)
        print(
            f"{r['case']:8} {r['frames']:6d} {r['iou_mean']:8.3f} {r['iou_min']:6.3f} {r['on_animal']:6.0%} "
            f"{r['without']:8d} {r['jitter']:6.2f} {r['centre_jitter']:5.2f} {r['own']:5.2f} {r['s_frame']:7.3f} {r['cpu_frame']:9.3f} "
            f"{r['load']:5.2f}",
            flush=True,
        )
        height = 110  # docs/clips.md's figure: one row of 6 frames a clip, small enough for the docs
        rows.append(
            np.hstack(
                [
                    cv2.resize(im, (round(im.shape[1] * height / im.shape[0]), height), cv2.INTER_AREA)
                    for im in r["shown"]
                ]
            )
        )
    if strip is not None and rows:
        width = max(row.shape[1] for row in rows)
        sheet = np.vstack([np.pad(row, ((0, 0), (0, width - row.shape[1]), (0, 0))) for row in rows])
        out = strip / "real_clips.jpg"
        cv2.imwrite(str(out), cv2.cvtColor(sheet, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, 80])
        print(f"wrote {out} ({out.stat().st_size / 1024:.0f} KiB)")


def look(path: Path, count: int = 8) -> Path:
    """A strip of ``count`` evenly spaced frames of the clip ``path`` (``PATH.strip.png``)."""
    from jeanscv.io.clip import ClipReader

    with ClipReader(path) as reader:
        frames = [frame.pixels for frame in reader.frames()]
    picked = [frames[round(i * (len(frames) - 1) / max(count - 1, 1))] for i in range(min(count, len(frames)))]
    out = path.with_name(path.name + ".strip.png")
    _write_strip(out, picked)
    return out


def docs_examples(folder: Path) -> None:
    """The examples of docs/clips.md: a textured animal (testkit, no photo of the shared
    set) walking, turning and growing over grass, as ``walk.gif`` and ``walk.mp4``, run
    through the command as a user would (automatic subject on the first frame), kept as
    ``walk_after.gif`` and ``walk_after.mp4``, and ``walk.strip.jpg``: input frames above,
    output frames below."""
    from click.testing import CliRunner

    from jeanscv.io.clip import write_clip
    from jeanscv_cli.main import cli

    folder.mkdir(parents=True, exist_ok=True)
    sprite = sc.texture_sprite(150, seed=7, name="gravel", tint=(1.0, 0.62, 0.32))  # a brown, furry animal
    ground = cv2.GaussianBlur(sc.background(320, 200, seed=4, name="grass", tint=(0.55, 0.85, 0.45)), (0, 0), 2.0)
    motion = sc.Motion((95.0, 105.0), (130.0, 10.0), 8.0, 0.12, frames=24)
    frames = [pixels for pixels, _, _ in sc.clip(sprite, ground, motion)]
    write_clip(folder / "walk.gif", frames, "gif", fps=12.0)
    write_clip(folder / "walk.mp4", frames, "mp4", fps=12.0)
    for name in ("walk.gif", "walk.mp4"):
        result = CliRunner().invoke(cli, [str(folder / name), "--overwrite", "-q"])
        assert result.exit_code == 0, result.output
    (folder / "walk.mp4").unlink()  # the strip shows the input
    # NAME.jeans.* is an output to git and to jeanscv itself: the docs keep them as walk_after.*
    for suffix in (".gif", ".mp4"):
        (folder / f"walk.jeans{suffix}").replace(folder / f"walk_after{suffix}")
    from jeanscv.io.clip import ClipReader

    with ClipReader(folder / "walk_after.gif") as reader:
        out = [frame.pixels for frame in reader.frames()]
    picked = [0, 6, 12, 18, 23]
    strip = np.vstack([np.hstack([frames[k] for k in picked]), np.hstack([out[k] for k in picked])])
    cv2.imwrite(str(folder / "walk.strip.jpg"), cv2.cvtColor(strip, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, 85])
    (folder / "walk.gif").unlink()  # the strip shows the input
    for path in sorted(folder.iterdir()):
        print(f"{path}: {path.stat().st_size / 1024:.0f} KiB")


def memory(frames: int, width: int, height: int) -> int:
    """Peak RSS (bytes) of a fresh process running the moving case for ``frames`` frames."""
    code = (
        "import resource, sys; from bench.clips import run_case; "
        f"run_case('moving', {width}, {height}, {frames}, None); "
        "print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)"
    )
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True)
    return int(out.stdout.split()[-1]) * 1024


def large(frames: int, size: str) -> dict:
    """The moving case at ``size`` (``WxH``, default 4K), ``frames`` long, through the
    command (``jeanscv CLIP -o DIR``, the subject found automatically) in a child process:
    its peak RSS (MiB), its wall seconds and frames a second, startup included."""
    width, height = (int(v) for v in size.lower().split("x"))
    with tempfile.TemporaryDirectory() as folder:
        source = Path(folder, "large.mp4")
        make_clip("moving", width, height, frames, source)
        load = os.getloadavg()[0]
        began = time.perf_counter()
        command = [sys.executable, "-m", "jeanscv", str(source), "-o", str(Path(folder, "out")), "--json"]
        subprocess.run(command, cwd=ROOT, capture_output=True, text=True, check=True)
        seconds = time.perf_counter() - began
        peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024  # the largest child: the command
    return {
        "size": f"{width}x{height}",
        "frames": frames,
        "seconds": seconds,
        "fps": frames / seconds,
        "peak_mib": peak,
        "load": load,
    }


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--frames", type=int, default=300)
    parser.add_argument("--width", type=int, default=1280)
    parser.add_argument("--only", default=",".join(CASES))
    parser.add_argument("--strip", type=Path)
    parser.add_argument("--memory", action="store_true")
    parser.add_argument("--large", action="store_true", help="a large clip through the command: peak memory, fps")
    parser.add_argument("--size", default="3840x2160", help="--large's frame size, WxH")
    parser.add_argument("--docs", type=Path, metavar="FOLDER", help="only write docs/clips.md's examples there")
    parser.add_argument("--look", type=Path, metavar="CLIP", help="only write CLIP.strip.png: 8 of its frames")
    parser.add_argument(
        "--auto", action="store_true", help="find the pet automatically on frame 0 (default: a click on it)"
    )
    parser.add_argument("--real", action="store_true", help="the real clips of ../shared/clips, against their masks")
    parser.add_argument(
        "--detector",
        choices=("auto", "none"),
        default="auto",
        help="the detector (frame 0, and holding the subject) or not",
    )
    args = parser.parse_args(argv)
    height = round(args.width * 9 / 16)
    if args.real:
        only = "" if args.only == ",".join(CASES) else args.only
        real(args.detector, only, args.strip, args.frames if "--frames" in (argv or sys.argv) else None)
        return
    if args.look:
        look(args.look)
        return
    if args.docs:
        docs_examples(args.docs)
        return
    if args.large:
        frames = args.frames if "--frames" in (argv or sys.argv) else 60
        r = large(frames, args.size)
        print(
            f"{r['size']}, {r['frames']} frames: peak RSS {r['peak_mib']:.0f} MiB, {r['seconds']:.1f} s, "
            f"{r['fps']:.2f} fps (load {r['load']:.2f})"
        )
        return
    if args.memory:
        short, long = memory(300, 640, 360), memory(1200, 640, 360)
        print(
            f"peak RSS 640x360: 300 frames {short / 2**20:.0f} MiB, 1200 frames {long / 2**20:.0f} MiB ({long / short:.2f}x)"
        )
        return
    print(
        f"{'case':8} {'frames':>6} {'s':>6} {'fps':>6} {'cpu ms':>6} {'load':>5} {'IoU min':>8} {'mean':>6} "
        f"{'follow':>6} {'jitter':>6} {'drift':>6} {'worst':>6} {'flips':>5} {'lost':>4}"
    )
    for case in args.only.split(","):
        r = run_case(case, args.width, height, args.frames, args.strip, args.auto, args.detector)
        print(
            f"{r['case']:8} {r['frames']:6d} {r['seconds']:6.1f} {r['fps']:6.1f} {r['cpu_ms']:6.0f} {r['load']:5.2f} {r['iou_min']:8.3f} "
            f"{r['iou_mean']:6.3f} {r['follow']:6.2f} {r['jitter']:6.2f} {r['drift']:6.2f} {r['worst']:6.2f} {r['flips']:5d} {r['lost']:4d}",
            flush=True,
        )
    print(f"peak RSS of this process: {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MiB")


if __name__ == "__main__":
    main()
