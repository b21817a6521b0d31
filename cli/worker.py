"""Process one input file: decode, fit, composite, and write its outputs.

Runs in the main process or in a worker process (``-j``), so everything here is
picklable and the heavy modules are imported on first use.
"""

from __future__ import annotations

import contextlib
import functools
import os
import signal
import time
import warnings
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

from jeanscv.options import JeansOptions
from jeanscv.run.runner import encode_picture, failure_reason, report_text

from .discover import Job
from .runs import claim, stop_with_parent


def _one_line_warnings() -> None:
    """jeanscv's own warnings (a skipped plugin, a detector that cannot be used) print as
    the one line they are, ``jeanscv: ...``, without Python's file and source line."""
    plain = warnings.formatwarning

    def formatted(message, category, filename, lineno, line=None) -> str:
        text = str(message)
        return f"{text}\n" if text.startswith("jeanscv: ") else plain(message, category, filename, lineno, line)

    warnings.formatwarning = formatted


_one_line_warnings()


@dataclass
class Outcome:
    """What happened to one input: ``status`` is ``ok``, ``failed`` or ``skipped``; or
    ``busy`` (another run holds it: put off, not reported, see :class:`runs.WorkQueue`)."""

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


def saved_clicks(job: Job, options: JeansOptions) -> Path | None:
    """The clicks saved beside a photo (``NAME.clicks.json``, by ``jeanscv serve``), which
    it uses unless ``--point``, ``--clicks`` or ``--mask`` say what the subject is."""
    from jeanscv.subject.clicks import sidecar_path

    if options.points or options.box is not None or options.clicks is not None or options.mask is not None:
        return None
    sidecar = sidecar_path(job.path)
    return sidecar if sidecar.is_file() else None


def wanted_outputs(job: Job, options: JeansOptions, overwrite: bool) -> dict[str, Path]:
    """The outputs to write: all with ``overwrite``, else those that do not exist yet or
    are older than the clicks saved beside the photo (the subject was fixed since)."""
    if overwrite:
        return dict(job.outputs)
    saved = saved_clicks(job, options)
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


def _ensure_folder(folder: Path) -> None:
    from jeanscv.errors import JeansError

    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise JeansError(f"cannot create output folder {folder}: {(exc.strerror or str(exc)).lower()}") from None


#: ``--top auto``: the caption names the subject's class where the detector is sure of it.
AUTO_CAPTION = "auto"


def _captions(options: JeansOptions, details: dict) -> tuple[str | None, str | None]:
    """The top and bottom captions of ``options``; ``--top auto``'s from what the detector
    said the subject is (a silhouette's ``details``), the bottom one unless given."""
    if options.top != AUTO_CAPTION:
        return options.top, options.bottom
    from jeanscv.subject.detected import captions

    top, bottom = captions(details)
    return top, options.bottom or bottom


def picture(result, options: JeansOptions):
    """The main output picture: the fit, captioned, optionally beside the original."""
    if not (options.top or options.bottom or options.side_by_side):
        return result.image  # no drawing: its imports (fonts, SVG escaping) are not free
    from .extras import add_captions, side_by_side

    image = add_captions(result.image, *_captions(options, result.silhouette.details))
    if options.side_by_side:
        if result.kind == "silhouette":
            from jeanscv.paint.figures import figure

            original = figure(result.silhouette)
        else:
            original = result.source.pixels
        image = side_by_side(original, image)
    return image


def _run(job: Job, options: JeansOptions, overwrite: bool, outcome: Outcome, shared=None) -> None:
    from jeanscv import pipeline
    from jeanscv.io.clip import is_clip
    from jeanscv.io.write import atomic_write_bytes
    from jeanscv.subject.silhouettes import silhouette_contours

    targets = wanted_outputs(job, options, overwrite)
    saved = saved_clicks(job, options)
    if saved is not None:
        options = options.replace(clicks=saved)
    if is_clip(job.path):
        _run_clip(job, options, targets, outcome)
        return
    result = pipeline.apply_jeans(job.path, options, shared=shared)
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
    if "detection" in subject:  # what the detector said the subject is: "cat 0.82"
        outcome.info["detected"] = f"{subject['detection']['class']} {subject['detection']['score']:.2f}"
    clicked = bool(options.points or options.box is not None or options.clicks is not None)
    if "uncertain" in subject and not clicked:
        # The report's line says whether the subject may be the wrong thing (a folder's
        # summary counts them; `jeanscv serve` lists them first).
        outcome.info["uncertain"] = bool(subject["uncertain"])
    if outcome.info.get("uncertain"):
        why = "; ".join(subject.get("doubts") or ()) or f"the hypotheses overlap by {subject['consensus']:.2f}"
        outcome.info["note"] = (
            f"unsure which thing is the subject ({why}); if the jeans missed it, click it with --point X,Y"
        )
    # Everything is encoded before the first write, so a failure leaves no outputs.
    data: dict[str, bytes] = {}
    if "image" in targets:
        if targets["image"].suffix.lower() in (".gif", ".mp4"):  # --format gif or mp4: a one-frame clip
            from jeanscv.io.clip import clip_bytes

            data["image"] = clip_bytes([picture(result, options)], targets["image"].suffix[1:].lower())
        else:
            data["image"] = encode_picture(targets["image"], picture(result, options), result)
    if "json" in targets:
        data["json"] = report_text(result, job.display, str(job.outputs["image"])).encode("utf-8")
    if "svg" in targets:
        from .extras import svg_document

        polygons = [obj.silhouette.framing.to_image(obj.fit.vertices) for obj in result.objects]
        contours = [c for obj in result.objects for c in silhouette_contours(obj.silhouette)]
        size = tuple(int(v) for v in result.silhouette.framing.image_size)
        text = svg_document(polygons, contours, size, f"jeanscv: {job.path.name}")
        data["svg"] = text.encode("utf-8")
    if "gif" in targets:
        from .extras import optimisation_gif

        if getattr(fit, "trajectory", None) is None:
            raise RuntimeError("this jeanscv library gives no fit trajectory for --gif")
        data["gif"] = optimisation_gif(result, options.gif_frames)
    for kind, payload in data.items():
        path = targets[kind]
        _ensure_folder(path.parent)
        atomic_write_bytes(path, payload)
        outcome.written.append(str(path))


def _run_clip(job: Job, options: JeansOptions, targets: dict[str, Path], outcome: Outcome) -> None:
    """A clip: its frames painted into ``NAME.jeans.EXT`` as they are decoded, and the
    ``--json`` report with every frame's vertices. The clip is made whenever any of its
    outputs is wanted (the report comes from the same run); SVG and GIF sidecars are
    not made for clips."""
    import json

    from jeanscv.errors import JeansError
    from jeanscv.io.clip import CLIP_FORMATS, ClipLimits
    from jeanscv.io.write import atomic_write_bytes
    from jeanscv.run.clips import write_jeans_clip

    image = job.outputs["image"]
    fmt = image.suffix[1:].lower()
    if fmt not in CLIP_FORMATS:
        raise JeansError(f"an animation cannot be written as {image.suffix}: use --format gif, mp4, webp or png")
    _ensure_folder(image.parent)
    limits = ClipLimits(max_frames=options.max_frames)
    report = write_jeans_clip(job.path, image, options, fmt=fmt, limits=limits, decorate=clip_decorate(options))
    outcome.written.append(str(image))
    frames = report["frames"]
    first = next((obj for obj in frames[0]["objects"] if obj is not None), None) if frames else None
    outcome.info = {
        "kind": "clip",
        "frames": report["frames_written"],
        "fps": report["fps"],
        "silhouette_method": first["method"] if first else "",
        "frames_without_jeans": sum(all(obj is None for obj in frame["objects"]) for frame in frames),
        "objects": [],
    }
    if "stopped" in report:  # frames lost to a truncated or damaged file: said, though the clip is written
        from jeanscv.io.clip import ClipStop

        written = report["frames_written"]
        outcome.info["note"] = f"{ClipStop(**report['stopped'])}; the {written} frames decoded were written"
    if "json" in targets:
        text = json.dumps({"input": job.display, "output": str(image), **report}, sort_keys=True) + "\n"
        _ensure_folder(targets["json"].parent)
        atomic_write_bytes(targets["json"], text.encode("utf-8"))
        outcome.written.append(str(targets["json"]))


def clip_decorate(options):
    """``decorate(painted, original)`` for :func:`jeanscv.run.clips.write_jeans_clip`: the
    captions and side by side of ``options`` on every frame (None when there are none)."""
    if not (options.top or options.bottom or options.side_by_side):
        return None
    from .extras import add_captions, side_by_side

    # Decided before the clip's first frame is found (no detector's class yet): "how would this".
    top, bottom = _captions(options, {})

    def decorate(painted, original):
        captioned = add_captions(painted, top, bottom)
        return side_by_side(original, captioned) if options.side_by_side else captioned

    return decorate


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


def process(job: Job, options: JeansOptions, overwrite: bool = False, wait: bool = True, shared=None) -> Outcome:
    """Process one job; never raises for a bad input (the outcome says ``failed``).

    Another jeanscv run may be making this file's outputs: with ``wait``, wait for it and
    then skip what it made; without, leave the file to it for now (``busy``). ``shared``:
    a :class:`~jeanscv.subject.photo.SharedHypotheses` of this photo (``jeanscv serve``
    cuts a folder photo's once for its page and its outputs; the outputs are the same).

    KeyboardInterrupt and :class:`Terminated` propagate, after the atomic writers
    have removed their temporary files.
    """
    global _BUSY
    began = time.perf_counter()
    outcome = Outcome(job.index, job.display, "ok", output=str(job.outputs["image"]))
    _BUSY = True
    try:
        with claim(job.path, wait) as ours:
            if not ours:
                outcome.status, outcome.error = "busy", "another jeanscv run is making it"
            elif wanted_outputs(job, options, overwrite):
                _run(job, options, overwrite, outcome, shared)
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


@functools.cache  # once a process: the command may run several times in one (tests, a program)
def skip_exit_collection() -> None:
    """Skip the garbage collections of the interpreter's exit.

    At exit Python collects garbage while it tears the modules down, traversing every
    object the imports made (numba's typing tables, numpy, the library): about 0.25 s of
    CPU at the end of every command and worker (measured when scipy was imported too), for memory the process is about to return
    anyway. Frozen objects are left out of every collection; the outputs are written
    (and their files closed) before exit, and atexit handlers still run.
    """
    import atexit
    import gc

    atexit.register(gc.freeze)


@contextlib.contextmanager
def fewer_collections(threshold: int = 10_000) -> Iterator[None]:
    """Collect young garbage after ``threshold`` new objects instead of Python's 700.

    A command's imports (numpy, numba, the library; scipy too when this was measured) make
    some 300,000 objects in a second; with the default threshold that set off about 235 collections, 0.15 s of CPU
    in a fresh process that handles one 12-MP photo, and 16 collections (0.06 s) with
    this one. Memory is the same (the peak is the photo's arrays); the threshold is
    restored afterwards, for a program that runs the command in process.
    """
    import gc

    previous = gc.get_threshold()
    gc.set_threshold(threshold, *previous[1:])
    try:
        yield
    finally:
        gc.set_threshold(*previous)


def init_worker(threads: int, parent: int | None = None) -> None:
    """Worker process setup: share the cores, leave Ctrl-C to the parent, stop cleanly on
    SIGTERM and once the run ``parent`` (default: the parent process) is gone."""
    import sys

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, _worker_sigterm)
    stop_with_parent(parent)
    reuse_freed_memory()
    skip_exit_collection()
    import cv2

    # OpenCV sizes its thread pool to every core too: N workers would each run
    # N-core OpenCV calls and oversubscribe the machine. Torch likewise, where a
    # torch fit loads it (the fast path never does).
    cv2.setNumThreads(max(1, threads))
    if "torch" in sys.modules:
        sys.modules["torch"].set_num_threads(max(1, threads))


def process_in_worker(job: Job, options: JeansOptions, overwrite: bool = False, wait: bool = True) -> Outcome:
    """:func:`process` for a worker process: a SIGTERM mid-file reports nothing and exits."""
    try:
        return process(job, options, overwrite, wait)
    except Terminated:
        os._exit(128 + signal.SIGTERM)
