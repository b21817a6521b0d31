"""Clicks that say what the subject is: the data model and the versioned clicks file.

A person fixes the subject of a photo with clicks: positive clicks on the thing that
should wear the jeans, negative clicks on what should not. The clicks of one object
are constraints on one mask (it holds every positive click and none of the negative
ones); several objects each have their own clicks.

Coordinates are ``(x, y)`` pixels of the photo *as displayed* (after its EXIF
orientation, at its full size even when a RAW file is decoded at half size), package
convention: pixel ``(c, r)`` covers ``[c, c+1) x [r, r+1)``, so a click at ``(10.5, 20.5)``
is the centre of pixel (10, 20).

The clicks file (``NAME.clicks.json``, written by the web page and by
:func:`write_clicks`, replayed by ``jeanscv --clicks FILE``)::

    {
      "format": "jeanscv-clicks",
      "version": 2,
      "image": {"width": 4032, "height": 3024},
      "objects": [
        {"positive": [[1210.5, 1877.0]], "negative": [[2410.0, 900.5]]},
        {"positive": [[3000.0, 2000.0]], "negative": [], "box": [2700, 1500, 3600, 2600]}
      ]
    }

An object may have a ``box`` ``[x0, y0, x1, y1]`` (version 2; a box alone, without
positive clicks, is enough), or negative clicks alone (version 2: the automatic subject
minus what they take away). A file whose objects all have a positive click and no box is
written as version 1, which older jeanscv reads; both versions are read. ``image``
records the size the clicks were made on; a file whose size does not match the photo it
is replayed on is refused (the clicks would land on the wrong things).
``image`` may be omitted by hand-written files: then only the bounds are checked.

For a clip, ``objects`` are the first frame's clicks, and ``frames`` may add key frames
where the subject changes: ``"frames": [{"frame": 45, "objects": [...]}]``, each frame's
objects as above (read by :func:`key_frames`; older jeanscv keeps the key as it is).
"""

from __future__ import annotations

import json
import math
import os
import reprlib
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import JeansError

FORMAT = "jeanscv-clicks"
#: The version written when an object has a box (version 2 added boxes); files without
#: boxes (and a positive click in every object) are written as version 1, which every
#: jeanscv reads.
VERSION = 2
READS = (1, 2)
#: The sidecar a folder's photo keeps its clicks in: ``cat.jpg`` -> ``cat.clicks.json``.
SIDECAR_SUFFIX = ".clicks.json"
#: Bigger clicks files are refused before parsing (a person makes a few dozen clicks).
MAX_FILE_BYTES = 1 << 20
#: Most objects, and most clicks of one object, a clicks file may hold.
MAX_OBJECTS = 64
MAX_CLICKS = 256

Point = tuple[float, float]


Box = tuple[float, float, float, float]


@dataclass(frozen=True)
class ObjectClicks:
    """The clicks of one object: ``positive`` on it, ``negative`` off it, and optionally
    a ``box`` ``(x0, y0, x1, y1)`` that holds it (image pixels; the object lies inside,
    everything outside is background). An object needs a positive click or a box."""

    positive: tuple[Point, ...]
    negative: tuple[Point, ...] = ()
    box: Box | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "positive", tuple(_point(p) for p in self.positive))
        object.__setattr__(self, "negative", tuple(_point(p) for p in self.negative))
        if self.box is not None:
            object.__setattr__(self, "box", _box(self.box))
        if not (self.positive or self.negative or self.box is not None):
            raise JeansError("an object needs a click or a box")
        if len(self.positive) + len(self.negative) > MAX_CLICKS:
            raise JeansError(f"an object has more than {MAX_CLICKS} clicks")
        taken = {_pixel(p) for p in self.positive}
        for point in self.negative:
            if _pixel(point) in taken:
                raise JeansError(f"negative click ({point[0]:g}, {point[1]:g}) is on top of a positive one")

    @property
    def edits_automatic(self) -> bool:
        """Negative clicks alone: the automatic subject minus what they take away."""
        return not self.positive and self.box is None

    @property
    def anchor(self) -> Point | None:
        """Where the object is: its first positive click, else its box's centre (None
        for negative clicks alone: the object is wherever the automatic subject is)."""
        if self.positive:
            return self.positive[0]
        if self.box is None:
            return None
        x0, y0, x1, y1 = self.box
        return ((x0 + x1) / 2, (y0 + y1) / 2)

    def to_json(self) -> dict:
        data = {"positive": [list(p) for p in self.positive], "negative": [list(p) for p in self.negative]}
        if self.box is not None:
            data["box"] = list(self.box)
        return data


@dataclass(frozen=True)
class Clicks:
    """The clicks of every object of one photo, and the photo's size ``(width, height)``
    they were made on (None when unknown)."""

    objects: tuple[ObjectClicks, ...]
    image_size: tuple[int, int] | None = None
    extra: dict = field(default_factory=dict, compare=False)  # unknown keys, kept on rewrite

    def __post_init__(self) -> None:
        object.__setattr__(self, "objects", tuple(self.objects))
        if len(self.objects) > MAX_OBJECTS:
            raise JeansError(f"more than {MAX_OBJECTS} objects")

    @classmethod
    def single(cls, positive: Iterable[Point], negative: Iterable[Point] = (), image_size=None) -> Clicks:
        """One object's clicks."""
        return cls((ObjectClicks(tuple(positive), tuple(negative)),), image_size)

    def check(self, size: tuple[int, int]) -> None:
        """JeansError unless the clicks fit a photo of ``size`` = (width, height)."""
        width, height = size
        if self.image_size is not None and tuple(self.image_size) != (width, height):
            w, h = self.image_size
            raise JeansError(f"the clicks were made on a {w}x{h} image, this one is {width}x{height}")
        for index, obj in enumerate(self.objects):
            which = f"object {index + 1}: " if len(self.objects) > 1 else ""
            for x, y in obj.positive + obj.negative:
                if not (0 <= x < width and 0 <= y < height):
                    raise JeansError(f"{which}click ({x:g}, {y:g}) is outside the {width}x{height} image")
            if obj.box is not None:
                x0, y0, x1, y1 = obj.box
                if x0 < 0 or y0 < 0 or x1 > width or y1 > height:
                    raise JeansError(
                        f"{which}box ({x0:g}, {y0:g}, {x1:g}, {y1:g}) is not inside the {width}x{height} image"
                    )
                for x, y in obj.positive:
                    if not (x0 <= x < x1 and y0 <= y < y1):
                        raise JeansError(f"{which}click ({x:g}, {y:g}) is outside its object's box")

    def scaled(self, size: tuple[int, int]) -> Clicks:
        """The clicks in pixels of a copy of the image at ``size`` = (width, height)
        (a RAW file decoded at half size); needs ``image_size`` or raises."""
        if self.image_size is None:
            raise JeansError("the clicks' image size is unknown")
        sx, sy = size[0] / self.image_size[0], size[1] / self.image_size[1]

        def scale(points):
            return tuple((x * sx, y * sy) for x, y in points)

        def scale_box(box):
            return None if box is None else (box[0] * sx, box[1] * sy, box[2] * sx, box[3] * sy)

        objects = tuple(ObjectClicks(scale(o.positive), scale(o.negative), scale_box(o.box)) for o in self.objects)
        return Clicks(objects, tuple(size), self.extra)

    def to_json(self) -> dict:
        """The clicks file's JSON object."""
        # Version 1 where every object has a positive click and no box: older jeanscv
        # reads those files.
        version = VERSION if any(obj.box is not None or obj.edits_automatic for obj in self.objects) else 1
        data: dict = {"format": FORMAT, "version": version}
        if self.image_size is not None:
            data["image"] = {"width": int(self.image_size[0]), "height": int(self.image_size[1])}
        data["objects"] = [obj.to_json() for obj in self.objects]
        return {**self.extra, **data}

    def dumps(self) -> str:
        return json.dumps(self.to_json(), indent=2) + "\n"


def _point(value) -> Point:
    """A click as two finite floats of a plausible size, else JeansError."""
    if isinstance(value, (str, bytes)) or not isinstance(value, Sequence) or len(value) != 2:
        raise JeansError(f"a click must be two numbers [x, y], got {_shown(value)}")
    try:
        x, y = (float(v) for v in value)
    except (TypeError, ValueError):
        raise JeansError(f"a click must be two numbers [x, y], got {_shown(value)}") from None
    except OverflowError:  # an integer of hundreds of digits
        raise JeansError(f"a click's coordinates are too large to be pixels, got {_shown(value)}") from None
    if isinstance(value[0], bool) or isinstance(value[1], bool) or not (math.isfinite(x) and math.isfinite(y)):
        raise JeansError(f"a click must be two finite numbers [x, y], got {_shown(value)}")
    return x, y


def _shown(value) -> str:
    """A short repr of what a clicks file held: never raises (Python refuses the repr
    of an integer of over 4300 digits) and never grows with the input."""
    try:
        text = reprlib.repr(value)
    except (ValueError, RecursionError):
        text = f"a {type(value).__name__}"
    return text[:80]


def _box(value) -> Box:
    """A box ``(x0, y0, x1, y1)`` of finite floats with ``x0 < x1`` and ``y0 < y1``, else JeansError."""
    if isinstance(value, (str, bytes)) or not isinstance(value, Sequence) or len(value) != 4:
        raise JeansError(f"a box must be four numbers [x0, y0, x1, y1], got {_shown(value)}")
    x0, y0 = _point(value[:2])
    x1, y1 = _point(value[2:])
    if not (x1 - x0 >= 2 and y1 - y0 >= 2):
        raise JeansError(f"a box must be at least 2x2 pixels with x0 < x1 and y0 < y1, got {_shown(value)}")
    return x0, y0, x1, y1


def _pixel(point: Point) -> tuple[int, int]:
    return math.floor(point[0]), math.floor(point[1])


def parse_clicks(data) -> Clicks:
    """A :class:`Clicks` from the clicks file's JSON value, else JeansError saying why."""
    if not isinstance(data, dict):
        raise JeansError("not a clicks file (expected a JSON object)")
    if data.get("format") != FORMAT:
        raise JeansError(f'not a clicks file (no "format": "{FORMAT}")')
    version = data.get("version")
    if version not in READS or isinstance(version, bool):
        raise JeansError(f"clicks file version {version!r} is not supported (this jeanscv reads versions 1 and 2)")
    image_size = None
    if "image" in data:
        image = data["image"]
        try:
            width, height = image["width"], image["height"]
        except (TypeError, KeyError):
            raise JeansError('"image" must be {"width": W, "height": H}') from None
        if not all(isinstance(v, int) and not isinstance(v, bool) and v > 0 for v in (width, height)):
            raise JeansError('"image" width and height must be positive integers')
        image_size = (width, height)
    objects = data.get("objects")
    if not isinstance(objects, list) or not objects:
        raise JeansError('"objects" must be a non-empty list')
    if len(objects) > MAX_OBJECTS:
        raise JeansError(f"more than {MAX_OBJECTS} objects")
    parsed = []
    for index, obj in enumerate(objects):
        if not isinstance(obj, dict):
            raise JeansError(f"object {index + 1} must be a JSON object")
        positive, negative = obj.get("positive", []), obj.get("negative", [])
        if not isinstance(positive, list) or not isinstance(negative, list):
            raise JeansError(f'object {index + 1}: "positive" and "negative" must be lists of [x, y]')
        box = obj.get("box")
        if box is not None and version < 2:
            raise JeansError(f'object {index + 1}: "box" needs a version 2 clicks file')
        if not positive and box is None and version < 2:
            raise JeansError(
                f"object {index + 1}: an object needs a positive click (negative clicks alone need version 2)"
            )
        try:
            parsed.append(ObjectClicks(tuple(positive), tuple(negative), box))
        except JeansError as exc:
            raise JeansError(f"object {index + 1}: {exc}") from None
    extra = {k: v for k, v in data.items() if k not in ("format", "version", "image", "objects")}
    return Clicks(tuple(parsed), image_size, extra)


#: Most key frames a clicks file may hold.
MAX_KEY_FRAMES = 256


def key_frames(clicks: Clicks) -> dict[int, Clicks]:
    """A clip's key frames: frame index (from 1; frame 0's clicks are ``clicks.objects``)
    -> that frame's :class:`Clicks` (the file's image size), from the file's ``frames``;
    JeansError saying what is wrong."""
    entries = clicks.extra.get("frames", [])
    if not isinstance(entries, list) or len(entries) > MAX_KEY_FRAMES:
        raise JeansError(f'"frames" must be a list of at most {MAX_KEY_FRAMES} {{"frame": N, "objects": [...]}}')
    found: dict[int, Clicks] = {}
    for entry in entries:
        index = entry.get("frame") if isinstance(entry, dict) else None
        if not isinstance(index, int) or isinstance(index, bool) or index < 1:
            raise JeansError('each of "frames" needs "frame": a whole number from 1 (frame 0 is "objects")')
        if index in found:
            raise JeansError(f"key frame {index} is given twice")
        try:
            found[index] = parse_clicks({"format": FORMAT, "version": VERSION, "objects": entry.get("objects")})
        except JeansError as exc:
            raise JeansError(f"key frame {index}: {exc}") from None
        found[index] = Clicks(found[index].objects, clicks.image_size)
    return found


def loads_clicks(text: str | bytes) -> Clicks:
    """Parse the clicks file's text."""
    if len(text) > MAX_FILE_BYTES:
        raise JeansError(f"clicks file is larger than {MAX_FILE_BYTES // 1024} KiB")
    try:
        data = json.loads(text)
    except (ValueError, RecursionError) as exc:  # JSONDecodeError and bad UTF-8
        raise JeansError(f"clicks file is not valid JSON ({str(exc).splitlines()[0][:120]})") from None
    return parse_clicks(data)


def read_clicks(path: str | os.PathLike) -> Clicks:
    """Read a clicks file; JeansError naming the reason when it cannot be used."""
    from ..io.files import open_regular

    path = Path(path)
    try:
        with open_regular(path) as file:  # a FIFO would block the read forever
            data = file.read(MAX_FILE_BYTES + 1)
        if len(data) > MAX_FILE_BYTES:
            raise JeansError(f"clicks file is larger than {MAX_FILE_BYTES // 1024} KiB")
    except FileNotFoundError:
        raise JeansError("clicks file not found") from None
    except IsADirectoryError:
        raise JeansError("clicks file is a folder") from None
    except OSError as exc:
        raise JeansError(f"cannot read the clicks file ({exc.strerror or exc})") from None
    return loads_clicks(data)


def write_clicks(path: str | os.PathLike, clicks: Clicks) -> None:
    """Write a clicks file atomically (a crash leaves the old file or the new one)."""
    from ..io.write import write_text

    write_text(Path(path), clicks.dumps())


def sidecar_path(photo: str | os.PathLike) -> Path:
    """Where a folder's photo keeps its clicks: ``dir/cat.jpg`` -> ``dir/cat.clicks.json``."""
    photo = Path(photo)
    return photo.with_name(photo.stem + SIDECAR_SUFFIX)


__all__ = [
    "FORMAT",
    "SIDECAR_SUFFIX",
    "VERSION",
    "Clicks",
    "ObjectClicks",
    "loads_clicks",
    "parse_clicks",
    "read_clicks",
    "sidecar_path",
    "write_clicks",
]
