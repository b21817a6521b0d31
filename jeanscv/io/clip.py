"""Decode and encode clips (GIF, animated WebP and PNG, MP4/MOV/WebM/MKV) frame by frame.

A clip is read as a stream of upright RGB frames (:class:`ClipReader`) and written as one
(:class:`ClipWriter`), so memory holds a frame or two, whatever the clip's length. PyAV
(FFmpeg's libraries inside its wheel) does the work; animated WebP, which FFmpeg's
decoder does not read, is read with Pillow, one frame at a time. Outputs are written to a
temporary file and renamed (:func:`jeanscv.io.write.atomic_file`), so a failure or Ctrl-C
leaves no half-written clip.

Every way a clip can be bad ends in a one-line ``JeansError``: no video stream (audio
only), no frame at all, too many frames, too long, too many pixels per frame, not a clip
(a file whose first bytes say it is text, or a still picture named as a clip:
:mod:`jeanscv.io._clip_probe`). A clip that stops decoding part way (a truncated download,
damaged packets near the end) keeps the frames that decoded: :attr:`ClipReader.stopped`
says where it ended (a :class:`ClipStop`), against the header's frame count or duration.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path
from typing import BinaryIO

import numpy as np

from jeanscv.errors import JeansError

from ._clip_probe import (
    HEAD_BYTES,
    ClipStop,
    check_content,
    gif_loop,
    gif_screen,
    is_animated,
    sniff,
    stop_of,
    video_seconds,
)
from .clip_names import CLIP_EXTENSIONS, CLIP_FORMATS, MAYBE_ANIMATED_EXTENSIONS, clip_format, is_clip_path
from .write import on_white


@dataclass(frozen=True)
class ClipLimits:
    """Caps on what is decoded: frames, seconds, and pixels per frame (``width x height``).
    A clip over one gets a one-line ``JeansError`` naming the cap. The defaults take a
    10-minute clip at 30 fps, in 4K at most."""

    max_frames: int = 18_000
    max_seconds: float = 600.0
    max_frame_pixels: int = 3840 * 2160


@dataclass(frozen=True)
class ClipFrame:
    """One decoded frame: ``pixels`` ``(H, W, 3)`` uint8 RGB upright (``(H, W, 4)`` RGBA
    in a clip with transparency: :attr:`ClipInfo.alpha`), its ``index`` from 0, and its
    start ``time`` and ``duration`` in seconds."""

    index: int
    time: float
    duration: float
    pixels: np.ndarray


@dataclass
class ClipInfo:
    """What a clip's header says: upright ``size`` (width, height), ``fps`` (average;
    None when unknown), ``frames`` and ``seconds`` (None when the header does not say),
    ``rotation`` (degrees counter-clockwise applied to make frames upright), ``loop``
    (GIF/WebP/PNG: 0 forever, N times, None: play once), ``audio`` (an audio stream is
    present), the container ``format``, and ``alpha``: the first frame has transparent
    pixels, so every frame is RGBA (known once the first frame is decoded)."""

    size: tuple[int, int]
    fps: float | None
    frames: int | None
    seconds: float | None
    rotation: int = 0
    loop: int | None = 0
    audio: bool = False
    format: str = ""
    alpha: bool = False
    extra: dict = field(default_factory=dict)


def is_clip(path: str | os.PathLike) -> bool:
    """Whether ``path`` is a clip: a clip extension, or an animated PNG/WebP (several
    frames; only the header is read). An unreadable file is not (the still decoder
    reports why)."""
    suffix = Path(path).suffix.lower()
    if suffix in CLIP_EXTENSIONS:
        return True
    if suffix not in MAYBE_ANIMATED_EXTENSIONS:
        return False
    from .files import open_regular

    try:
        with open_regular(path) as file:
            return is_animated(file)
    except OSError:  # the still decoder gives the one-line reason
        return False


def _rotated(pixels: np.ndarray, rotation: int) -> np.ndarray:
    """Frames upright: ``rotation`` is the display matrix's counter-clockwise angle."""
    turns = (rotation // 90) % 4
    return np.ascontiguousarray(np.rot90(pixels, turns)) if turns else pixels


def _rgba(pixels: np.ndarray) -> np.ndarray:
    """RGB -> RGBA, opaque; RGBA as it is."""
    if pixels.shape[2] == 4:
        return pixels
    return np.dstack([pixels, np.full(pixels.shape[:2], 255, np.uint8)])


def _reason(exc: BaseException) -> str:
    text = getattr(exc, "strerror", None) or str(exc) or type(exc).__name__
    return " ".join(str(text).split()).rstrip(".").lower()


class ClipReader:
    """Frames of a clip file, decoded one at a time (a context manager; :meth:`frames`).

    The header is read on opening: a file that is no clip by its first bytes, a clip with
    no video stream, or over ``limits`` by its header, raises ``JeansError`` at once. With
    ``keep_audio``, ``audio_packets`` collects the audio stream's packets as the frames are
    demuxed, for a :class:`ClipWriter` to copy (and empties as it takes them); without,
    they are dropped (memory stays flat).
    """

    def __init__(self, path: str | os.PathLike, limits: ClipLimits | None = None, keep_audio: bool = False) -> None:
        from .image import _open_nonempty

        self.path = Path(path)
        self.limits = limits or ClipLimits()
        self.stopped: ClipStop | None = None  # where decoding ended before the clip's end
        self.audio_packets: list = []
        self.audio_stream = None
        self.keep_audio = keep_audio
        self._file: BinaryIO = _open_nonempty(self.path)
        self._container = None
        self._pillow = None
        self._video_seconds: float | None = None  # the video's duration as its header states it
        try:
            self.info = self._open()
            self._check_header()
        except BaseException:
            self.close()
            raise

    # -------------------------------------------------------------- opening
    def _open(self) -> ClipInfo:
        head = self._file.read(HEAD_BYTES)
        self._file.seek(0)
        kind = sniff(head)
        check_content(self.path, kind, kind in ("png", "webp") and is_animated(self._file))
        if kind == "gif":  # FFmpeg decodes no GIF whose screen it will not allocate (it says 0x0)
            self._check_pixels(*gif_screen(head))
        if self.path.suffix.lower() == ".webp" or kind == "webp":
            return self._open_pillow()
        import av

        try:
            container = av.open(self._file, "r", metadata_errors="replace")
        except av.EOFError:
            raise JeansError("the clip has no frames (the file ends before the first)") from None
        except (av.FFmpegError, UnicodeError, ValueError) as exc:
            raise JeansError(f"not a video or animation this build can read ({_reason(exc)})") from None
        self._container = container
        if not container.streams.video:
            raise JeansError("no video stream (an audio-only file?)")
        stream = container.streams.video[0]
        stream.thread_type = "AUTO"  # frame threads: decoding overlaps the fitting's other core
        if container.streams.audio:
            self.audio_stream = container.streams.audio[0]
        context = stream.codec_context
        if context is None:  # a stream no decoder of this build reads
            raise JeansError("its video stream cannot be decoded by this build")
        width, height = context.width, context.height
        rate = stream.average_rate or stream.guessed_rate
        seconds = None
        if stream.duration is not None and stream.time_base:
            seconds = float(stream.duration * stream.time_base)
        elif container.duration is not None:
            seconds = container.duration / 1_000_000
        fmt = container.format.name.split(",")[0]
        loop = gif_loop(self._file) if fmt == "gif" else 0
        self._video_seconds = video_seconds(container, stream, fmt)
        return ClipInfo(
            (width, height),
            float(rate) if rate else None,
            stream.frames or None,
            seconds,
            0,  # the frames carry the display matrix: set from the first one
            loop,
            self.audio_stream is not None,
            fmt,
        )

    def _open_pillow(self) -> ClipInfo:
        from PIL import Image, UnidentifiedImageError

        try:
            image = Image.open(self._file)
            image.load()
        except Image.DecompressionBombError:  # Pillow's own cap, before ours is asked
            raise JeansError("its frames are too large (more pixels than any clip this reads)") from None
        except (UnidentifiedImageError, OSError, ValueError, SyntaxError) as exc:
            raise JeansError(f"not a WebP animation this build can read ({_reason(exc)})") from None
        self._pillow = image
        frames = getattr(image, "n_frames", 1)
        loop = image.info.get("loop", 0)
        return ClipInfo(image.size, None, frames, None, 0, loop, False, "webp")

    def _check_pixels(self, width: int, height: int) -> None:
        if width * height > self.limits.max_frame_pixels:
            raise JeansError(
                f"frames are {width}x{height}, over the limit of {self.limits.max_frame_pixels:,} pixels a frame"
            )

    def _check_header(self) -> None:
        info, limits = self.info, self.limits
        width, height = info.size
        self._check_pixels(width, height)
        if width < 2 or height < 2:
            raise JeansError(f"frames too small: {width}x{height} pixels")
        if info.frames is not None and info.frames > limits.max_frames:
            raise JeansError(f"clip has {info.frames} frames, over the limit of {limits.max_frames} (--max-frames)")
        if info.seconds is not None and info.seconds > limits.max_seconds:
            raise JeansError(f"clip lasts {info.seconds:.1f} s, over the limit of {limits.max_seconds:g} s")

    # -------------------------------------------------------------- frames
    def frames(self) -> Iterator[ClipFrame]:
        """The frames, upright RGB, in order. Past the caps: ``JeansError``. A decoding
        error after the first frame ends the clip there; before it, ``JeansError``. Once
        the last frame is given, :attr:`stopped` says whether decoding ended before the
        header's frame count or duration (a truncated file), or at an error."""
        source = self._pillow_frames() if self._pillow is not None else self._av_frames()
        count, self._last_duration = 0, 0.1
        previous: tuple[int, float, np.ndarray] | None = None  # held back until its duration is known
        first_time, reason = 0.0, None
        while True:
            try:
                item = next(source)
            except StopIteration:
                break
            except JeansError:
                raise
            except Exception as exc:  # noqa: BLE001 - FFmpeg's and Pillow's many decoding errors
                if count == 0:
                    raise JeansError(f"cannot decode the clip ({_reason(exc)})") from None
                reason = _reason(exc)
                break
            count += 1
            if count > self.limits.max_frames:
                raise JeansError(f"clip has more than {self.limits.max_frames} frames (--max-frames)")
            time, duration, pixels = item
            if count == 1:  # a clip with transparency is one whose first frame has some
                self.info.alpha = pixels.shape[2] == 4 and bool((pixels[..., 3] < 255).any())
                first_time = time
            pixels = _rgba(pixels) if self.info.alpha else on_white(pixels)
            if time > self.limits.max_seconds:
                raise JeansError(f"clip lasts more than {self.limits.max_seconds:g} s")
            if previous is not None:
                index, start, held = previous
                yield ClipFrame(index, start, max(time - start, 1e-3), held)
            previous = (count - 1, time, pixels)
            self._last_duration = duration
        if previous is None:
            raise JeansError("the clip has no frames")
        index, start, held = previous
        info = self.info
        end = start + self._last_duration - first_time
        self.stopped = stop_of(count, end, reason, info.frames, self._video_seconds, info.fps)
        yield ClipFrame(index, start, self._last_duration, held)

    def _av_frames(self) -> Iterator[tuple[float, float, np.ndarray]]:
        container = self._container
        video = container.streams.video[0]
        streams = [video] + ([self.audio_stream] if self.audio_stream is not None else [])
        fallback = 1.0 / self.info.fps if self.info.fps else 0.1
        last_time = -1.0
        for packet in container.demux(streams):
            if packet.stream.type == "audio":
                if self.keep_audio and packet.dts is not None:
                    self.audio_packets.append(packet)
                continue
            for frame in packet.decode():
                time = float(frame.time) if frame.time is not None else last_time + fallback
                if time <= last_time:  # a repeated or missing timestamp: keep them increasing
                    time = last_time + 1e-3
                last_time = time
                duration = float(frame.duration * frame.time_base) if frame.duration and frame.time_base else fallback
                pixels = frame.to_ndarray(format="rgba" if frame.format.name in _ALPHA_FORMATS else "rgb24")
                rotation = int(round((frame.rotation or 0) / 90)) * 90 % 360
                if rotation != self.info.rotation:
                    self.info.rotation = rotation
                    self.info.size = (frame.height, frame.width) if rotation % 180 else (frame.width, frame.height)
                yield time, duration, _rotated(pixels, rotation)

    def _pillow_frames(self) -> Iterator[tuple[float, float, np.ndarray]]:
        image = self._pillow
        time = 0.0
        for index in range(getattr(image, "n_frames", 1)):
            image.seek(index)
            image.load()
            duration = float(image.info.get("duration") or 100) / 1000
            yield time, duration, np.asarray(image.convert("RGBA"))
            time += duration

    def take_audio(self) -> list:
        """The audio packets demuxed so far, removed from the reader."""
        packets, self.audio_packets = self.audio_packets, []
        return packets

    def close(self) -> None:
        if self._container is not None:
            self._container.close()
            self._container = None
        if self._pillow is not None:
            self._pillow.close()
            self._pillow = None
        self._file.close()

    def __enter__(self) -> ClipReader:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


#: Pixel formats with alpha, decoded as RGBA and flattened over white.
_ALPHA_FORMATS = frozenset({"bgra", "rgba", "argb", "abgr", "yuva420p", "yuva444p", "pal8", "ya8", "gbrap"})


def iter_frames(frames, fps: float = 25.0) -> Iterator[ClipFrame]:
    """``ClipFrame`` s from arrays (``(H, W, 3)`` uint8 RGB or ``(H, W, 4)`` RGBA, kept
    as they are, or already frames), ``fps`` apart."""
    for index, item in enumerate(frames):
        if isinstance(item, ClipFrame):
            yield item
            continue
        pixels = np.asarray(item)
        if pixels.dtype != np.uint8 or pixels.ndim != 3 or pixels.shape[2] not in (3, 4):
            raise JeansError(f"frame {index} must be an (H, W, 3) uint8 array, got {pixels.dtype} {pixels.shape}")
        yield ClipFrame(index, index / fps, 1.0 / fps, pixels)


# ------------------------------------------------------------------------- writing


class ClipWriter:
    """Write frames as a clip ``fmt`` (``gif``, ``mp4``, ``webp``, ``png``) into an open
    binary file (see :func:`write_clip`), one :meth:`write` per frame.

    MP4: H.264 (yuv420p, sizes made even by repeating the last row or column), ``audio``
    (a reader's audio stream) copied packet by packet when the container takes it. GIF: a
    palette per frame, ``loop`` kept (0 forever, N times, None once). Frame times are
    kept, so a variable frame rate stays variable. RGBA frames keep their transparency in
    GIF (pixels under half opaque are the palette's clear colour), WebP and PNG when the
    first frame is RGBA; MP4, and frames after an RGB first one, show them on white.
    """

    def __init__(self, file: BinaryIO, fmt: str, *, fps: float | None = None, loop: int | None = 0, audio=None) -> None:
        import av

        if fmt not in CLIP_FORMATS:
            raise JeansError(f"cannot write a clip as {fmt!r} (use {', '.join(CLIP_FORMATS)})")
        self.fmt = fmt
        self.fps = fps or 25.0
        options = {}
        if fmt in ("gif", "webp"):
            options["loop"] = "-1" if loop is None else str(loop)  # FFmpeg: -1 plays once
        elif fmt == "png":
            options["plays"] = "1" if loop is None else str(loop)
        muxer = {"png": "apng"}.get(fmt, fmt)
        self._container = av.open(file, "w", format=muxer, options=options)
        self._stream = None
        self._audio_in = audio
        self._audio_out = None
        self._last_pts = -1
        self._size: tuple[int, int] | None = None
        self._alpha = False  # the stream keeps transparency

    def _start(self, width: int, height: int, alpha: bool = False) -> None:
        import av

        if self.fmt == "mp4":
            # H.264 in yuv420p needs even sizes; rate: the container's nominal frame rate.
            width, height = width + width % 2, height + height % 2
            rate = Fraction(self.fps).limit_denominator(1001)
            stream = self._container.add_stream("libx264", rate=rate)
            stream.pix_fmt = "yuv420p"
            stream.options = {"crf": "20", "preset": "veryfast"}
            self._time_base = Fraction(1, 90000)
            if self._audio_in is not None:
                try:
                    self._audio_out = self._container.add_stream_from_template(self._audio_in)
                except (ValueError, av.FFmpegError):
                    self._audio_out = None  # a codec MP4 cannot hold: the clip goes silent
        else:
            codec, pix_fmt = {"gif": ("gif", "pal8"), "webp": ("libwebp_anim", "yuv420p"), "png": ("apng", "rgb24")}[
                self.fmt
            ]
            self._alpha = alpha
            if alpha and self.fmt != "gif":
                pix_fmt = {"webp": "yuva420p", "png": "rgba"}[self.fmt]
            self._time_base = Fraction(1, 100) if self.fmt == "gif" else Fraction(1, 1000)
            stream = self._container.add_stream(codec, rate=Fraction(1, self._time_base))
            stream.pix_fmt = pix_fmt
            if self.fmt == "webp":
                stream.options = {"quality": "85"}
        stream.width, stream.height = width, height
        stream.time_base = self._time_base
        stream.codec_context.time_base = self._time_base
        self._stream = stream
        self._size = (width, height)

    def write(self, pixels: np.ndarray, time: float, duration: float | None = None) -> None:
        """Encode one ``(H, W, 3)`` uint8 frame shown from ``time`` (seconds) for
        ``duration`` (the last frame's length; later frames start where it ends)."""
        import av

        pixels = np.asarray(pixels)
        if self._stream is None:
            self._start(pixels.shape[1], pixels.shape[0], pixels.shape[2] == 4)
        pixels = _rgba(pixels) if self._alpha else on_white(pixels)
        width, height = self._size
        if pixels.shape[:2] != (height, width):
            pixels = _padded(pixels, width, height)
        pts = max(int(round(time / self._time_base)), self._last_pts + 1)
        self._last_pts = pts
        frame = self._frame(pixels)
        frame.pts = pts
        frame.time_base = self._time_base
        if duration is not None:
            frame.duration = max(1, int(round(duration / self._time_base)))
        try:
            for packet in self._stream.encode(frame):
                if not packet.duration and frame.duration and self.fmt == "gif":
                    packet.duration = frame.duration  # the GIF muxer's delay of the last frame
                self._container.mux(packet)
        except av.FFmpegError as exc:
            raise JeansError(f"cannot encode the clip ({_reason(exc)})") from None

    def _frame(self, pixels: np.ndarray):
        import av

        if self.fmt != "gif":
            layout = "rgba" if pixels.shape[2] == 4 else "rgb24"
            return av.VideoFrame.from_ndarray(np.ascontiguousarray(pixels), format=layout)
        from PIL import Image

        # A palette of this frame's own colours (GIF allows one per frame); with
        # transparency, 255 of them and the last entry the clear one (FFmpeg's GIF encoder
        # writes an entry of alpha 0 as the frame's transparent index, disposal 'restore
        # to background', so a moving subject leaves no trail).
        clear = pixels[..., 3] < 128 if pixels.shape[2] == 4 else None
        colours = 255 if clear is not None else 256
        rgb = np.ascontiguousarray(pixels[..., :3])
        quantised = Image.fromarray(rgb).quantize(colours, method=Image.Quantize.FASTOCTREE, dither=Image.Dither.NONE)
        palette = np.asarray(quantised.getpalette()[: 3 * colours], np.uint8).reshape(-1, 3)
        argb = np.zeros((256, 4), np.uint8)
        argb[:, 0] = 255
        argb[: len(palette), 1:] = palette
        indices = np.asarray(quantised)
        if clear is not None:
            argb[255] = 0
            indices = np.where(clear, np.uint8(255), indices)
        return av.VideoFrame.from_ndarray((np.ascontiguousarray(indices), argb), format="pal8")

    def copy_audio(self, packets: list) -> None:
        """Mux a reader's audio packets (nothing when the output carries no audio)."""
        if self._audio_out is None:
            return
        for packet in packets:
            packet.stream = self._audio_out
            self._container.mux(packet)

    def close(self) -> None:
        """Flush the encoder and finish the container."""
        import av

        if self._stream is None:  # nothing was written: the output is thrown away
            try:
                self._container.close()
            except (av.FFmpegError, ValueError, OSError):
                pass
            return
        try:
            if self._stream is not None:
                for packet in self._stream.encode():
                    self._container.mux(packet)
        except av.FFmpegError as exc:
            raise JeansError(f"cannot encode the clip ({_reason(exc)})") from None
        finally:
            self._container.close()


def _padded(pixels: np.ndarray, width: int, height: int) -> np.ndarray:
    """``pixels`` cropped or edge-padded to ``width x height`` (even sizes for H.264)."""
    pixels = pixels[:height, :width]
    pad = ((0, height - pixels.shape[0]), (0, width - pixels.shape[1]), (0, 0))
    return np.pad(pixels, pad, mode="edge") if any(p[1] for p in pad) else pixels


def write_clip(
    path: str | os.PathLike,
    frames,
    fmt: str | None = None,
    *,
    fps: float | None = None,
    loop: int | None = 0,
    reader: ClipReader | None = None,
) -> int:
    """Write ``frames`` (``ClipFrame`` s or ``(H, W, 3)`` arrays ``1/fps`` apart) to
    ``path`` atomically as ``fmt`` (default: from the extension); with ``reader``, its
    audio is copied as the frames go. Returns how many frames were written; none raises
    ``JeansError`` and writes nothing."""
    from .write import atomic_file

    fmt = fmt or clip_format(path)
    count = 0
    with atomic_file(path) as file:
        writer = ClipWriter(file, fmt, fps=fps, loop=loop, audio=reader.audio_stream if reader else None)
        try:
            for frame in iter_frames(frames, fps or 25.0):
                writer.write(frame.pixels, frame.time, frame.duration)
                if reader is not None:
                    writer.copy_audio(reader.take_audio())
                count += 1
            if count == 0:
                raise JeansError("no frames to write")
            if reader is not None:
                writer.copy_audio(reader.take_audio())  # what was demuxed after the last frame
        finally:
            writer.close()
    return count


def clip_bytes(frames, fmt: str, fps: float = 25.0) -> bytes:
    """``frames`` (arrays ``1/fps`` apart) encoded as a clip ``fmt``, in memory (a photo
    written as a one-frame GIF or MP4)."""
    import io

    buffer = io.BytesIO()
    writer = ClipWriter(buffer, fmt, fps=fps)
    try:
        for frame in iter_frames(frames, fps):
            writer.write(frame.pixels, frame.time, frame.duration)
    finally:
        writer.close()
    return buffer.getvalue()


__all__ = [
    "CLIP_EXTENSIONS",
    "CLIP_FORMATS",
    "ClipFrame",
    "ClipInfo",
    "ClipLimits",
    "ClipReader",
    "ClipStop",
    "ClipWriter",
    "clip_bytes",
    "clip_format",
    "is_clip",
    "is_clip_path",
    "iter_frames",
    "write_clip",
]
