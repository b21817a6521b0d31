"""Turn the command line's PATH arguments into jobs: which files, and where their outputs go.

Kept free of numpy, torch and Pillow so that ``--help`` and ``--version`` stay fast;
the extension lists come from :mod:`jeanscv.io.image`, imported only when inputs are
actually collected.
"""

from __future__ import annotations

import glob
import os
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

from jeanscv.subject.clicks import SIDECAR_SUFFIX

OUTPUT_FORMATS = ("png", "jpg", "webp", "gif", "mp4")

# Output extension kept for photos whose format the writers can encode; everything
# else becomes PNG (lossless, keeps alpha), and RAW becomes JPEG like a camera would.
_GLOB_CHARS = frozenset("*?[")


@dataclass
class Job:
    """One input file and the paths of everything written for it.

    ``display``: the input path as shown to the user (the argument, or the folder
    argument joined with the path found under it). ``outputs``: output kind
    (``image``, ``json``, ``svg``, ``gif``) -> path.
    """

    index: int
    path: Path
    display: str
    outputs: dict[str, Path] = field(default_factory=dict)


@dataclass
class Problem:
    """An argument or file that could not become a job: shown as ``jeanscv: WHAT: reason``."""

    display: str
    reason: str


@dataclass
class Collection:
    """Everything found on the command line, in order.

    ``jobs`` is made as it is consumed, so that the first file can start while the rest
    of a big folder still gets its paths: it yields ``total`` items, a :class:`Job` for
    each input, or a :class:`Problem` where a file's outputs would clash with another's.
    ``problems`` are the arguments that gave nothing (known before the first job).
    """

    jobs: Iterator[Job | Problem]
    total: int
    problems: list[Problem]
    ignored: list[str]  # files in folders that are not images (skipped quietly)
    own_outputs: list[str]  # named files that are jeanscv outputs (``*.jeans.*``)


def is_own_output(path: Path) -> bool:
    """True for ``name.jeans.ext`` files: jeanscv's outputs are never inputs."""
    return _is_own_output_name(path.name)


def _is_own_output_name(name: str) -> bool:
    suffixes = name.split(".")
    return len(suffixes) >= 3 and suffixes[-2].lower() == "jeans"


def candidate_extensions() -> frozenset[str]:
    """Lower-case extensions taken from folders: photos, RAW, SVG and clips."""
    from jeanscv.io.clip import CLIP_EXTENSIONS
    from jeanscv.io.image import SUPPORTED_EXTENSIONS
    from jeanscv.io.svg import SVG_EXTENSIONS

    return SUPPORTED_EXTENSIONS | SVG_EXTENSIONS | CLIP_EXTENSIONS


def _walk(folder: Path, recursive: bool) -> list[tuple[str, ...]]:
    """Files in ``folder`` (and below when ``recursive``) as path parts relative to it,
    sorted, hidden names left out. Strings, not Paths: a folder of 10,000 photos is
    listed in milliseconds, and parsing that many Paths took most of a second."""
    found: list[tuple[str, ...]] = []
    if recursive:
        top = os.fspath(folder)
        for root, dirs, files in os.walk(folder):
            dirs[:] = sorted(d for d in dirs if not d.startswith("."))
            relative = os.path.relpath(root, top)
            prefix = () if relative == os.curdir else tuple(relative.split(os.sep))
            found.extend((*prefix, f) for f in files if not f.startswith("."))
    else:
        with os.scandir(folder) as entries:
            found = [(e.name,) for e in entries if not e.name.startswith(".") and e.is_file()]
    return sorted(found)


def may_name_several(arguments: list[str]) -> bool:
    """Whether ``arguments`` may name more than one input: several of them, a folder or a
    pattern (checked without listing anything)."""
    return len(arguments) > 1 or any(os.path.isdir(a) or _expand(a) is not None for a in arguments)


def _expand(argument: str) -> list[str] | None:
    """Glob matches of ``argument``, sorted; None when it is not a pattern (or exists as named)."""
    if os.path.exists(argument) or not (_GLOB_CHARS & set(argument)):
        return None
    return sorted(glob.glob(argument, recursive=True))


def collect(
    arguments: list[str],
    recursive: bool = False,
    output_dir: Path | None = None,
    fmt: str | None = None,
    extras: tuple[str, ...] = (),
) -> Collection:
    """Expand the PATH arguments into jobs with their output paths.

    Named files are always jobs (a bad one fails when it is read); folders give their
    files with a supported extension; glob patterns are expanded here (sorted) so they
    work without a shell. With ``output_dir``, outputs mirror each file's folder relative
    to the folder argument that found it; named files go to its root. ``extras`` lists
    the sidecars wanted (``json``, ``svg``, ``gif``). The same file named twice becomes
    one job. When two inputs would share outputs (``dog.png`` and ``dog.svg``), the second
    keeps its extension in their names (``dog.svg.jeans.png``).

    Folders are listed here, as strings (milliseconds for 10,000 names): that gives the
    count and the order. The jobs themselves, with their paths and output paths (most of
    a second for 10,000), are made as :attr:`Collection.jobs` is consumed.
    """
    extensions = candidate_extensions()
    cwd = os.getcwd()
    found: list[tuple[str, str, tuple[str, ...]]] = []  # (argument, display, parts below it)
    inputs: set[str] = set()  # identities of everything found: an output never replaces one
    problems: list[Problem] = []
    ignored: list[str] = []
    own: list[str] = []

    def add(argument: str, display: str, parts: tuple[str, ...] = ()) -> None:
        key = os.path.normcase(os.path.normpath(os.path.join(cwd, argument, *parts)))
        if key not in inputs:  # else the same file named twice (or by a folder and by name)
            inputs.add(key)
            found.append((argument, display, parts))

    def add_folder(folder: str) -> None:
        any_found = False
        for parts in _walk(Path(folder), recursive):
            if _is_own_output_name(parts[-1]) or parts[-1].lower().endswith(SIDECAR_SUFFIX):
                continue  # a photo's clicks file goes with its photo: no input, none skipped
            if os.path.splitext(parts[-1])[1].lower() in extensions:
                add(folder, folder, parts)
                any_found = True
            else:
                ignored.append(str(Path(folder, *parts)))
        if not any_found:
            where = "in this folder or its subfolders" if recursive else "in this folder (use -r to search subfolders)"
            problems.append(Problem(folder, f"no supported images found {where}"))

    for argument in arguments:
        matches = _expand(argument)
        names = [argument] if matches is None else matches
        if matches == []:
            problems.append(Problem(argument, "no files match this pattern"))
        for name in names:
            if os.path.isdir(name):
                add_folder(name)
            elif not os.path.lexists(name):
                problems.append(Problem(name, "file not found"))
            elif is_own_output(Path(name)):
                own.append(name)
            else:
                add(name, name)
    jobs = _jobs(found, inputs, cwd, output_dir, fmt, extras)
    return Collection(jobs, len(found), problems, ignored, own)


def _jobs(
    found: list[tuple[str, str, tuple[str, ...]]],
    inputs: set[str],
    cwd: str,
    output_dir: Path | None,
    fmt: str | None,
    extras: tuple[str, ...],
) -> Iterator[Job | Problem]:
    """The jobs of :func:`collect`, made one at a time, in order; a clash of outputs is
    decided in that order, so the first of ``dog.png`` and ``dog.svg`` keeps the plain name."""
    claimed: dict[str, str] = {}  # output path -> display name of the input that owns it
    for index, (argument, display, parts) in enumerate(found):
        path = Path(argument, *parts)
        if parts:
            display = str(Path(display, *parts))
        folder = path.parent if output_dir is None else output_dir.joinpath(*parts[:-1])
        outputs = _outputs(folder / path.stem, path, fmt, extras)
        keys = [_identity(p, cwd) for p in outputs.values()]
        if any(k in claimed for k in keys):
            # dog.png and dog.svg side by side: the second keeps its extension in the name.
            outputs = _outputs(folder / path.name, path, fmt, extras)
            keys = [_identity(p, cwd) for p in outputs.values()]
        clash = next((claimed[k] for k in keys if k in claimed), None)
        if clash is not None:
            yield Problem(display, f"its output {outputs['image'].name} would also be the output of {clash}")
        elif any(k in inputs for k in keys):
            # Only possible with odd names; an input is never replaced.
            yield Problem(display, "its output would overwrite an input file")
        else:
            claimed.update(dict.fromkeys(keys, display))
            yield Job(index, path, display, outputs)


def _outputs(base: Path, path: Path, fmt: str | None, extras: tuple[str, ...]) -> dict[str, Path]:
    """Output paths ``base.jeans.EXT`` for the picture and each sidecar in ``extras``; a
    clip (by its name) has only the ``json`` sidecar: no single fit to draw as SVG or to
    animate."""
    from jeanscv.io.clip import is_clip_path
    from jeanscv.io.write import output_extension

    stem = base.name + ".jeans"
    outputs = {"image": base.with_name(stem + output_extension(path, fmt, clips=True))}
    for extra in extras:
        if extra == "json" or not is_clip_path(path):
            outputs[extra] = base.with_name(f"{stem}.{extra}")
    return outputs


def _identity(path: Path, cwd: str | None = None) -> str:
    """A comparable key for a path (absolute, normalised, case as given); ``cwd``, the
    current folder, saves asking the OS for it for every path of a big folder."""
    return os.path.normcase(os.path.normpath(os.path.join(cwd or os.getcwd(), path)))
