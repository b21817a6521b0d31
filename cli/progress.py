"""Progress and messages on stderr.

On a terminal: one self-updating line (count, percentage, ETA, current file). Otherwise
(pipes, logs, CI): one plain line per finished file, ``[3/10] in -> out (1.2 s)``.
Errors are always printed, one line each: ``jeanscv: FILE: reason``.
"""

from __future__ import annotations

import shutil
import sys
import time
from typing import TextIO


def _clock(seconds: float) -> str:
    seconds = int(round(seconds))
    if seconds >= 3600:
        return f"{seconds // 3600}:{seconds % 3600 // 60:02d}:{seconds % 60:02d}"
    return f"{seconds // 60}:{seconds % 60:02d}"


class Progress:
    """Reports per-file progress and the summary on ``stream`` (stderr by default)."""

    def __init__(
        self,
        total: int,
        quiet: bool = False,
        verbose: bool = False,
        stream: TextIO | None = None,
        tty: bool | None = None,
    ):
        self.stream = stream or sys.stderr
        self.total = total
        self.quiet = quiet
        self.verbose = verbose and not quiet
        self.tty = (self.stream.isatty() if tty is None else tty) and not quiet
        self.done = 0
        self.counts = {"ok": 0, "failed": 0, "skipped": 0}
        self.unsure = 0  # finished photos whose subject may be the wrong thing
        self.serve_hint = "jeanscv serve FOLDER"  # how to look at them (the command sets the folder)
        self.began = time.perf_counter()
        self._work_seconds = 0.0
        self._worked = 0
        self._status = ""

    # -- low level

    def _write(self, line: str) -> None:
        if self._status:
            self.stream.write("\r\x1b[K")
        self.stream.write(line + "\n")
        if self._status:
            self.stream.write(self._status)
        self.stream.flush()

    def _redraw(self, current: str = "") -> None:
        if not self.tty:
            return
        pct = 100 * self.done // max(self.total, 1)
        eta = ""
        if self._worked and self.done < self.total:
            per_file = (time.perf_counter() - self.began) / max(self.done, 1)
            eta = f" ETA {_clock(per_file * (self.total - self.done))}"
        status = f"[{self.done}/{self.total}] {pct}%{eta}"
        if current:
            width = shutil.get_terminal_size((80, 20)).columns
            room = max(10, width - len(status) - 4)
            shown = current if len(current) <= room else "…" + current[-(room - 1) :]
            status += f"  {shown}"
        self.stream.write("\r\x1b[K" + status)
        self.stream.flush()
        self._status = status

    # -- events

    def info(self, line: str) -> None:
        """A plain message, unless quiet."""
        if not self.quiet:
            self._write(line)

    def error(self, what: str, reason: str) -> None:
        """``jeanscv: WHAT: reason``, always shown."""
        self._write(f"jeanscv: {what}: {reason}")

    def start(self, display: str) -> None:
        """A file is being processed (shown on the terminal's status line)."""
        self._redraw(display)

    def finish(self, outcome) -> None:
        """Count a finished file and report it."""
        self.done += 1
        self.counts[outcome.status] += 1
        if outcome.status != "skipped":
            self._worked += 1
            self._work_seconds += outcome.seconds
        prefix = f"[{self.done}/{self.total}]"
        if outcome.status == "failed":
            self.error(outcome.input, outcome.error)
        elif not self.quiet and (not self.tty or self.verbose):
            if outcome.status == "skipped":
                self._write(f"{prefix} {outcome.input}: skipped ({outcome.error})")
            else:
                self._write(f"{prefix} {outcome.input} -> {outcome.output} ({outcome.seconds:.1f} s)")
        if outcome.status == "ok" and outcome.info.get("uncertain"):
            self.unsure += 1
        if outcome.status == "ok" and outcome.info.get("note") and not self.quiet:
            self._write(f"jeanscv: {outcome.input}: note: {outcome.info['note']}")
        if self.verbose and outcome.status == "ok" and outcome.info.get("kind") == "clip":
            info = outcome.info
            self._write(
                f"    clip: {info['frames']} frames, first frame's silhouette: {info['silhouette_method'] or 'none'}, "
                f"{info['frames_without_jeans']} frames without jeans"
            )
        elif self.verbose and outcome.status == "ok" and outcome.info:
            info = outcome.info
            terms = " ".join(f"{k}={v:.4g}" for k, v in info.get("terms", {}).items())
            self._write(
                f"    {info.get('kind')} (silhouette: {info.get('silhouette_method')}"
                f"{', ' + info['detected'] if 'detected' in info else ''}), device {info.get('device')}, "
                f"fit {info.get('fit_seconds', 0):.2f} s, objective {info.get('objective', 0):.6g}, "
                f"paper total {info.get('paper_total', 0):.6g}"
            )
            self._write(f"    terms: {terms}")
            objects = info.get("objects", [])
            for obj in objects[:1]:
                self._write(
                    f"    posture: {obj['posture']} (tilt {obj['tilt_degrees']:.0f} degrees), "
                    f"rules {'passed' if obj['rules_passed'] else 'failed'}"
                )
            for number, obj in enumerate(objects if len(objects) > 1 else [], 1):
                x, y, w, h = obj["box"]
                self._write(
                    f"    object {number}: {obj['method']}, box {x},{y} {w}x{h}, "
                    f"objective {obj['objective']:.6g}, {obj['posture']}, "
                    f"rules {'passed' if obj['rules_passed'] else 'failed'}"
                )
        self._redraw()

    def skip_quietly(self, count: int) -> None:
        """Files that were not images: only counted."""
        self.counts["skipped"] += count

    def close(self) -> None:
        """Clear the status line."""
        if self._status:
            self.stream.write("\r\x1b[K")
            self.stream.flush()
            self._status = ""

    def summary(self, note: str = "") -> str:
        """``N ok, N failed, N skipped in T s`` (printed unless quiet), after a line saying
        how many photos may have the wrong subject, when any, and how to look at them."""
        self.close()
        c = self.counts
        line = f"{c['ok']} ok, {c['failed']} failed, {c['skipped']} skipped in {time.perf_counter() - self.began:.1f} s"
        if note:
            line += f" ({note})"
        if self.unsure and not self.quiet:
            unsure = f"jeanscv: {self.unsure} of {c['ok']} may have the wrong subject"
            if c["ok"] > 1:
                unsure += f": `{self.serve_hint}` shows them first"
            self._write(unsure)
        if not self.quiet:
            self._write(line)
        return line
