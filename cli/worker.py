"""Process one input file: decode, fit, composite, and write its outputs.

Runs in the main process or in a worker process (``-j``), so everything here is
picklable and the heavy modules are imported on first use.
"""

from __future__ import annotations

import json
import os
import signal
import time
from dataclasses import dataclass, field
from pathlib import Path

from .discover import Job
from .runs import claim, stop_with_parent


@dataclass(frozen=True)
class Options:
    """The per-file settings from the command line (device already resolved)."""

    preset: str = "default"
    posture: str = "upright"
    garment: str = "jeans"
    iterations: int = 100
    seed: int = 0
    starts: int | None = None
    kind: str = "auto"
    silhouette: str = "auto"
    threshold: float | None = None
    mask: str | None = None
    rect: tuple[int, int, int, int] | None = None
    objects: str = "one"
    points: tuple[tuple[float, float], ...] = ()
    background_points: tuple[tuple[float, float], ...] = ()
    clicks: str | None = None  # a clicks file (--clicks)
    style: str = "denim"
    clip: bool = True
    max_pixels: int = 100_000_000
    raw_half_size: bool = False
    device: str = "cpu"
    backend: str | None = None  # resolved by the command: fast or torch
    overwrite: bool = False
    top: str | None = None
    bottom: str | None = None
    side_by_side: bool = False
    gif_frames: int = 50


@dataclass
class Outcome:
    """What happened to one input: ``status`` is ``ok``, ``failed`` or ``skipped``."""

    index: int
    input: str
    status: str
    output: str = ""
    written: list[str] = field(default_factory=list)
    error: str = ""  # why it failed or was skipped
    seconds: float = 0.0
    info: dict = field(default_factory=dict)  # kind, method, device, fit seconds, loss terms
    usage: bool = False  # failed because an option did not fit the input (exit status 2)

    def record(self) -> dict:
        """One line of ``--report``: ``error`` holds a failure's reason, ``reason`` a skip's."""
        record = {
            "status": self.status,
            "input": self.input,
            "output": self.output,
            "written": self.written,
            "error": self.error if self.status == "failed" else "",
            "seconds": round(self.seconds, 3),
            **self.info,
        }
        if self.status == "skipped":
            record["reason"] = self.error
        return record


class Terminated(BaseException):
    """Raised by the SIGTERM handler: unwinds like Ctrl-C, so temporary files are removed."""


def one_line(text: str) -> str:
    """Collapse whitespace (newlines included) so a message fits ``jeanscv: FILE: reason``."""
    return " ".join(str(text).split())


def failure_reason(exc: BaseException) -> str:
    """The user-facing reason for an exception raised while processing a file."""
    from jeanscv.errors import JeansError

    if isinstance(exc, JeansError):
        return one_line(exc) or "failed"
    if isinstance(exc, MemoryError):
        return "out of memory"
    detail = one_line(exc)
    return f"unexpected error ({type(exc).__name__}{': ' + detail if detail else ''})"


def clicks_file(job: Job, options: Options) -> Path | None:
    """The clicks file an input uses: ``--clicks``, else the clicks saved beside the photo
    (``NAME.clicks.json``, by ``jeanscv serve``) unless ``--point`` or ``--mask`` say
    what the subject is."""
    from jeanscv.clicks import sidecar_path

    if options.clicks is not None:
        return Path(options.clicks)
    if options.points or options.mask:
        return None
    sidecar = sidecar_path(job.path)
    return sidecar if sidecar.is_file() else None


def wanted_outputs(job: Job, options: Options) -> dict[str, Path]:
    """The outputs to write: all with ``overwrite``, else those that do not exist yet or
    are older than the clicks saved beside the photo (the subject was fixed since)."""
    if options.overwrite:
        return dict(job.outputs)
    saved = clicks_file(job, options) if options.clicks is None else None
    try:
        clicked = saved.stat().st_mtime if saved is not None else None
    except OSError:
        clicked = None
    wanted = {}
    for kind, path in job.outputs.items():
        try:
            done = path.stat().st_mtime
        except OSError:
            done = None
        if done is None or (clicked is not None and done < clicked):
            wanted[kind] = path
    return wanted


def _encode(path: Path, pixels, result):
    """Bytes of the picture for ``path``: its extension picks the format; photos keep
    their EXIF (orientation removed) and colour profile."""
    from jeanscv.io.write import encode_image, format_for_path

    from .extras import on_white

    fmt = format_for_path(path)
    if fmt == "JPEG":
        pixels = on_white(pixels)  # JPEG has no alpha: show transparency as white, not as raw colour
    meta = {}
    source = result.source
    if result.kind == "photo" and source is not None:
        meta = {"exif": source.exif, "icc_profile": source.icc_profile}
    return encode_image(pixels, fmt, quality=95, **meta)


def _ensure_folder(folder: Path) -> None:
    from jeanscv.errors import JeansError

    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise JeansError(f"cannot create output folder {folder}: {(exc.strerror or str(exc)).lower()}") from None


def picture(result, options: Options):
    """The main output picture: the fit, captioned, optionally beside the original."""
    from .extras import add_captions, side_by_side

    image = add_captions(result.image, options.top, options.bottom)
    if options.side_by_side:
        if result.kind == "silhouette":
            from jeanscv.figures import figure

            original = figure(result.silhouette)
        else:
            original = result.source.pixels
        image = side_by_side(original, image)
    return image


def report_json(result, job: Job) -> str:
    """The ``--json`` sidecar text: sorted keys, indent 2, newline at the end."""
    report = result.report(job.display, str(job.outputs["image"]))
    return json.dumps(report, sort_keys=True, indent=2) + "\n"


def _run(job: Job, options: Options, outcome: Outcome) -> None:
    from jeanscv import pipeline
    from jeanscv.io.write import atomic_write_bytes
    from jeanscv.silhouettes import load_mask, silhouette_contours

    from .extras import optimisation_gif, svg_document

    targets = wanted_outputs(job, options)
    mask = load_mask(options.mask, options.max_pixels) if options.mask else None
    clicks = None
    saved = clicks_file(job, options)
    if saved is not None:
        from jeanscv.clicks import read_clicks
        from jeanscv.errors import JeansError

        try:
            clicks = read_clicks(saved)
        except JeansError as exc:
            raise JeansError(f"clicks file {saved.name}: {exc}") from None
    result = pipeline.apply_jeans(
        job.path,
        garment=options.garment,
        preset=options.preset,
        iterations=options.iterations,
        seed=options.seed,
        device=options.device,
        starts=options.starts,
        kind=options.kind,
        silhouette_method=options.silhouette,
        threshold=options.threshold,
        rect=options.rect,
        mask=mask,
        style=options.style,
        clip=options.clip,
        max_pixels=options.max_pixels,
        raw_half_size=options.raw_half_size,
        objects=options.objects,
        points=list(options.points),
        background_points=list(options.background_points),
        clicks=clicks,
        posture=options.posture,
        backend=options.backend,
    )
    fit = result.fit
    outcome.info = {
        "kind": result.kind,
        "silhouette_method": result.silhouette.method,
        "device": fit.device,
        "fit_seconds": round(fit.seconds, 3),
        "objective": float(fit.objective),
        "terms": {k: float(v) for k, v in fit.terms.items()},
        "paper_total": float(fit.paper_total),
        "paper_terms": {k: float(v) for k, v in fit.paper_terms.items()},
        "objects": [_object_info(obj) for obj in result.objects],
    }
    subject = result.silhouette.details
    if subject.get("uncertain") and not options.points and clicks is None:
        outcome.info["note"] = (
            f"unsure which thing is the subject (the segmentation's hypotheses overlap by {subject['consensus']:.2f} "
            "on average); if the jeans missed it, click it with --point X,Y"
        )
    # Everything is encoded before the first write, so a failure leaves no outputs.
    data: dict[str, bytes] = {}
    if "image" in targets:
        data["image"] = _encode(targets["image"], picture(result, options), result)
    if "json" in targets:
        data["json"] = report_json(result, job).encode("utf-8")
    if "svg" in targets:
        polygons = [obj.silhouette.framing.to_image(obj.fit.vertices) for obj in result.objects]
        contours = [c for obj in result.objects for c in silhouette_contours(obj.silhouette)]
        size = tuple(int(v) for v in result.silhouette.framing.image_size)
        text = svg_document(polygons, contours, size, f"jeanscv: {job.path.name}")
        data["svg"] = text.encode("utf-8")
    if "gif" in targets:
        if getattr(fit, "trajectory", None) is None:
            raise RuntimeError("this jeanscv library gives no fit trajectory for --gif")
        data["gif"] = optimisation_gif(result, options.gif_frames)
    for kind, payload in data.items():
        path = targets[kind]
        _ensure_folder(path.parent)
        atomic_write_bytes(path, payload)
        outcome.written.append(str(path))


def _object_info(obj) -> dict:
    """One object's line of ``-v`` and of ``--report``: method, box, objective, rules passed, posture."""
    entry = obj.report()
    return {
        "method": entry["method"],
        "box": entry["box"],
        "objective": entry["objective"],
        "rules_passed": entry["rules"]["passed"],
        "posture": entry["posture"],
        "tilt_degrees": entry["tilt_degrees"],
    }


# Worker processes: whether a file is being processed, for the SIGTERM handler.
_BUSY = False


def process(job: Job, options: Options) -> Outcome:
    """Process one job; never raises for a bad input (the outcome says ``failed``).

    KeyboardInterrupt and :class:`Terminated` propagate, after the atomic writers
    have removed their temporary files.
    """
    global _BUSY
    began = time.perf_counter()
    outcome = Outcome(job.index, job.display, "ok", output=str(job.outputs["image"]))
    _BUSY = True
    try:
        # Another jeanscv run on the same folder may be making this file's outputs: wait
        # for it, then skip what it made (the job was pending when this run began).
        with claim(job.path):
            if wanted_outputs(job, options):
                _run(job, options, outcome)
            else:
                outcome.status, outcome.error = "skipped", "made by another jeanscv run meanwhile"
    except Exception as exc:  # noqa: BLE001 - every failure becomes one line for this file
        from jeanscv.errors import OptionError

        outcome.status, outcome.error = "failed", failure_reason(exc)
        outcome.output = ""
        outcome.usage = isinstance(exc, OptionError)
    finally:
        _BUSY = False
    outcome.seconds = time.perf_counter() - began
    return outcome


def _worker_sigterm(signum, frame) -> None:
    if _BUSY:
        raise Terminated()
    os._exit(128 + signum)  # idle: nothing to clean up, and no traceback to print


# glibc mallopt parameters (malloc.h).
_M_TRIM_THRESHOLD, _M_MMAP_MAX = -1, -4


def reuse_freed_memory() -> bool:
    """Keep freed memory in the process heap for the next file (glibc only).

    Every photo allocates and frees dozens of 10-100 MB arrays. By default glibc maps
    each from fresh pages and unmaps it on free, so the kernel zeroes every page again
    on first touch: on 12-MP photos with ``-j 2`` that was 10% of the CPU time, all of
    it system time. Serving them from a heap that is never trimmed lets the next
    photo reuse the same pages. Peak memory is unchanged: the heap only holds what
    the largest photo needed. Returns whether the setting took effect.
    """
    import ctypes
    import platform

    if platform.system() != "Linux" or platform.libc_ver()[0] != "glibc":
        return False
    try:
        libc = ctypes.CDLL("libc.so.6")
        return bool(libc.mallopt(_M_MMAP_MAX, 0)) and bool(libc.mallopt(_M_TRIM_THRESHOLD, 2**31 - 1))
    except (OSError, AttributeError):
        return False


def init_worker(threads: int) -> None:
    """Worker process setup: share the cores, leave Ctrl-C to the parent, stop cleanly on SIGTERM."""
    import sys

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, _worker_sigterm)
    stop_with_parent()
    reuse_freed_memory()
    import cv2

    # OpenCV sizes its thread pool to every core too: N workers would each run
    # N-core OpenCV calls and oversubscribe the machine. Torch likewise, where a
    # torch fit loads it (the fast path never does).
    cv2.setNumThreads(max(1, threads))
    if "torch" in sys.modules:
        sys.modules["torch"].set_num_threads(max(1, threads))


def process_in_worker(job: Job, options: Options) -> Outcome:
    """:func:`process` for a worker process: a SIGTERM mid-file reports nothing and exits."""
    try:
        return process(job, options)
    except Terminated:
        os._exit(128 + signal.SIGTERM)
