"""Bad inputs: each gives exactly one line ``jeanscv: FILE: reason``, no traceback, no
output, exit 1; in a batch the other files are still processed."""

from __future__ import annotations

import errno
import io
import json
import os
import socket
import struct
import time
import zlib
from pathlib import Path

import numpy as np
import pytest
from conftest import ROOT, blue_pixels, write_silhouette_png
from PIL import Image

FAST = ("--iterations", "3", "--starts", "1")


def _png_chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)


def _huge_png_header() -> bytes:
    """A PNG that claims 50000x50000 pixels (header and one tiny chunk of data only)."""
    ihdr = struct.pack(">IIBBBBB", 50000, 50000, 8, 2, 0, 0, 0)
    return (
        b"\x89PNG\r\n\x1a\n"
        + _png_chunk(b"IHDR", ihdr)
        + _png_chunk(b"IDAT", zlib.compress(b"\x00" * 64))
        + _png_chunk(b"IEND", b"")
    )


def _encoded(pixels: np.ndarray, fmt: str) -> bytes:
    buffer = io.BytesIO()
    Image.fromarray(pixels).save(buffer, fmt)
    return buffer.getvalue()


def _photo() -> np.ndarray:
    rng = np.random.default_rng(1)
    return rng.integers(0, 255, size=(64, 64, 3), dtype=np.uint8)


_LAUGHS = """<?xml version="1.0"?>
<!DOCTYPE svg [
<!ENTITY lol "lol">
<!ENTITY lol2 "&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;">
<!ENTITY lol3 "&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;">
<!ENTITY lol9 "&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;">
]>
<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 256 256"><title>&lol9;</title>
<path d="M10 10 L200 10 L200 200 Z"/></svg>
"""


def _ellipse_photo(scale: float) -> tuple[np.ndarray, np.ndarray]:
    """A 96x128 photo: a noisy red ellipse (semi-axes 64*scale, 48*scale, centre (64, 48))
    on noisy green. Returns ``(pixels (96, 128, 3) uint8, object mask (96, 128) bool)``."""
    yy, xx = np.mgrid[:96, :128]
    blob = (xx - 64) ** 2 / (64 * scale) ** 2 + (yy - 48) ** 2 / (48 * scale) ** 2 < 1
    noise = np.random.default_rng(3).normal(0, 6, (96, 128, 3))
    pixels = np.where(blob[..., None], [200, 40, 40], [40, 160, 60]) + noise
    return np.clip(np.round(pixels), 0, 255).astype(np.uint8), blob


def _cubic_svg(segments: int) -> bytes:
    """A closed path of ``segments`` cubic Beziers around a circle, each with far-out
    control points, so that flattening it needs far more than MAX_SEGMENTS lines."""
    t = np.linspace(0, 2 * np.pi, segments + 1)
    x, y = 128 + 100 * np.cos(t), 128 + 100 * np.sin(t)
    d = f"M{x[0]:.2f} {y[0]:.2f}" + "".join(
        f"C{a + 300:.1f} {b - 300:.1f} {a - 300:.1f} {b + 300:.1f} {a:.2f} {b:.2f}" for a, b in zip(x[1:], y[1:])
    )
    return f'<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 256 256"><path d="{d}Z"/></svg>'.encode()


_XXE = b"""<?xml version="1.0"?>
<!DOCTYPE svg [<!ENTITY xxe SYSTEM "file:///etc/passwd">]>
<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 256 256"><title>&xxe;</title>
<path d="M10 10 L200 10 L200 200 Z"/></svg>
"""

# The sample DNG cut to 30%: LibRaw reads the header, then the raw data ends early.
_DNG = (ROOT / "sample_images" / "coffee.dng").read_bytes()

# name -> (file bytes, expected words of the reason)
BAD_FILES = {
    "empty.png": (b"", "empty file"),
    "truncated.jpg": (_encoded(_photo(), "JPEG")[:300], "truncated or corrupt"),
    "truncated.png": (_encoded(_photo(), "PNG")[:200], "truncated or corrupt"),
    "text.jpg": (b"this is not a picture\n" * 20, "not an image file"),
    "huge.png": (_huge_png_header(), "over the --max-pixels limit"),
    "tiny.png": (_encoded(np.zeros((1, 1, 3), np.uint8), "PNG"), "too small"),
    "flat.png": (_encoded(np.full((64, 64, 3), 128, np.uint8), "PNG"), "no object found to segment"),
    "nopath.svg": (b'<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 256 256"><g/></svg>', "no filled path"),
    "zeroarea.svg": (
        b'<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 256 256"><path d="M10 10 L100 100 L200 200 Z"/></svg>',
        "silhouette is empty",
    ),
    "laughs.svg": (_LAUGHS.encode(), "entities"),
    "fake.nef": (b"II*\x00" + b"\x00" * 400, "not a readable RAW file"),
    # A red object covering 95% of the frame: only the corners are background.
    "fullframe.png": (_encoded(_ellipse_photo(1.2)[0], "PNG"), "no object found to segment"),
    "xxe.svg": (_XXE, "SVG declares XML entities, which are refused for safety"),
    "cubics.svg": (_cubic_svg(100_000), "path is too complex: over 2000000 segments after flattening"),
    "truncated.dng": (_DNG[: len(_DNG) * 3 // 10], "not a readable RAW file: raw data truncated or corrupt"),
}


def _error_lines(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines() if line.startswith("jeanscv: ")]


@pytest.mark.parametrize("name", sorted(BAD_FILES))
def test_bad_file_alone(tmp_path, run_cli, capfd, name):
    data, words = BAD_FILES[name]
    bad = tmp_path / name
    bad.write_bytes(data)
    result = run_cli(bad, *FAST, "-q", "--json")
    assert result.exit_code == 1
    assert "Traceback" not in result.stderr
    # C libraries write to file descriptor 2 directly, past click (LibRaw would print
    # "FILE: Unexpected end of file" for the truncated DNG): nothing may get through.
    assert capfd.readouterr().err == ""
    lines = result.stderr.splitlines()
    assert len(lines) == 1, result.stderr
    prefix = f"jeanscv: {bad}: "
    assert lines[0].startswith(prefix) and len(lines[0]) > len(prefix)
    assert words in lines[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == [name]


@pytest.mark.parametrize("point", ["128,10", "-1,10", "10,96", "1e9,5"])
def test_click_outside_the_image_fails_that_input(tmp_path, run_cli, point):
    photo = tmp_path / "photo.png"
    photo.write_bytes(_encoded(_ellipse_photo(0.6)[0], "PNG"))  # 128x96
    result = run_cli(photo, *FAST, "--json", "-q", f"--point={point}")
    assert result.exit_code == 1
    x, y = (float(v) for v in point.split(","))
    assert result.stderr.splitlines() == [f"jeanscv: {photo}: click ({x:g}, {y:g}) is outside the 128x96 image"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["photo.png"]


def test_missing_file_and_empty_folder(tmp_path, run_cli):
    (tmp_path / "docs").mkdir()
    (tmp_path / "docs" / "notes.txt").write_text("hello")
    missing = tmp_path / "missing.png"
    result = run_cli(missing, tmp_path / "docs", tmp_path / "nothing*.png", *FAST, "-q")
    assert result.exit_code == 1
    assert result.stderr.splitlines() == [
        f"jeanscv: {missing}: file not found",
        f"jeanscv: {tmp_path / 'docs'}: no supported images found in this folder (use -r to search subfolders)",
        f"jeanscv: {tmp_path / 'nothing*.png'}: no files match this pattern",
    ]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["docs"]


@pytest.mark.parametrize("jobs", ["1", "2"])
def test_batch_goes_on_past_bad_files(tmp_path, run_cli, jobs):
    """Every bad file gets exactly one line; the two good ones are done, serially and in workers."""
    folder = tmp_path / "in"
    folder.mkdir()
    for name, (data, _) in BAD_FILES.items():
        (folder / name).write_bytes(data)
    write_silhouette_png(folder / "good.png")
    write_silhouette_png(folder / "mön chat ü.png", "dog")
    (folder / "readme.txt").write_text("not an image")
    result = run_cli(folder, *FAST, "-o", tmp_path / "out", "-j", jobs)
    assert result.exit_code == 1
    assert "Traceback" not in result.stderr
    errors = _error_lines(result.stderr)
    assert len(errors) == len(BAD_FILES)
    for name, (_, words) in BAD_FILES.items():
        mine = [line for line in errors if line.startswith(f"jeanscv: {folder / name}: ")]
        assert len(mine) == 1 and words in mine[0], (name, errors)
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["good.jeans.png", "mön chat ü.jeans.png"]
    # 15 failed, the good ones done, readme.txt skipped quietly.
    assert result.stderr.splitlines()[-1].startswith(f"2 ok, {len(BAD_FILES)} failed, 1 skipped in ")


def test_unwritable_output_folder(tmp_path, run_cli, monkeypatch):
    src = write_silhouette_png(tmp_path / "a.png")
    locked = tmp_path / "locked"
    locked.mkdir()
    if getattr(os, "geteuid", lambda: -1)() == 0:
        # root ignores permission bits: refuse file creation in that folder instead.
        real_open = os.open

        def guarded_open(path, flags, *args, **kwargs):
            if Path(path).parent == locked and flags & os.O_CREAT:
                raise PermissionError(errno.EACCES, "Permission denied", str(path))
            return real_open(path, flags, *args, **kwargs)

        monkeypatch.setattr(os, "open", guarded_open)
    else:
        locked.chmod(0o555)
    try:
        result = run_cli(src, *FAST, "-q", "-o", locked)
    finally:
        locked.chmod(0o755)
    assert result.exit_code == 1
    assert result.stderr.splitlines() == [f"jeanscv: {src}: cannot write output: permission denied"]
    assert list(locked.iterdir()) == []


def test_unexpected_exception_is_one_line(tmp_path, run_cli, monkeypatch):
    from jeanscv import pipeline

    def boom(*args, **kwargs):
        raise RuntimeError("something\nbroke")

    monkeypatch.setattr(pipeline, "apply_jeans", boom)
    src = write_silhouette_png(tmp_path / "a.png")
    result = run_cli(src, *FAST, "-q")
    assert result.exit_code == 1
    assert result.stderr.splitlines() == [f"jeanscv: {src}: unexpected error (RuntimeError: something broke)"]


def test_existing_output_skipped_then_overwritten(tmp_path, run_cli):
    src = write_silhouette_png(tmp_path / "a.png")
    out = tmp_path / "a.jeans.png"
    out.write_bytes(b"placeholder")
    result = run_cli(src, *FAST)
    assert result.exit_code == 0
    assert out.read_bytes() == b"placeholder"
    assert f"{src}: skipped (output exists; --overwrite redoes it)" in result.stderr
    assert result.stderr.splitlines()[-1].startswith("0 ok, 0 failed, 1 skipped in ")
    result = run_cli(src, *FAST, "--overwrite", "-q")
    assert result.exit_code == 0 and result.stderr == ""
    with Image.open(out) as im:
        assert im.size == (256, 256)


def test_overwrite_that_fails_keeps_the_old_output(tmp_path, run_cli, monkeypatch):
    """Disk full while replacing an output: the old file is untouched and no temporary is left."""
    src = write_silhouette_png(tmp_path / "a.png")
    (tmp_path / "a.jeans.png").write_bytes(b"previous result")

    def full_disk(fd):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(os, "fsync", full_disk)
    result = run_cli(src, *FAST, "-q", "--overwrite")
    assert result.exit_code == 1
    assert result.stderr.splitlines() == [f"jeanscv: {src}: cannot write output: no space left on device"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.jeans.png", "a.png"]
    assert (tmp_path / "a.jeans.png").read_bytes() == b"previous result"


def test_max_pixels_option(tmp_path, run_cli):
    src = tmp_path / "photo.png"
    src.write_bytes(_encoded(_photo(), "PNG"))
    result = run_cli(src, *FAST, "-q", "--max-pixels", "4000")
    assert result.exit_code == 1
    assert result.stderr.splitlines() == [
        f"jeanscv: {src}: image is 64x64 = 0.004096 MP, over the --max-pixels limit of 0.004 MP"
    ]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["photo.png"]


@pytest.mark.parametrize("iterations", ["3", "0"])
def test_diverged_fit_is_one_line(tmp_path, run_cli, monkeypatch, iterations):
    """A non-finite loss for every start fails the file: during the steps (3 iterations)
    or at the final scoring (0 iterations)."""
    import functools

    from jeanscv.fitting import fitter, objectives

    real_objective = fitter.make_objective

    def nan_objective(*args, **kwargs):
        evaluate = real_objective(*args, **kwargs)

        def diverged(*call, **options):
            totals, grad, terms = evaluate(*call, **options)
            return totals * float("nan"), grad, {name: value * float("nan") for name, value in terms.items()}

        return diverged

    def nan_descent(*args, **kwargs):
        # the steps taken one by one, so that the objective above is the one they take
        return functools.partial(objectives.descend_by_steps, nan_objective(*args, **kwargs))

    monkeypatch.setattr(fitter, "make_objective", nan_objective)
    monkeypatch.setattr(fitter, "make_descent", nan_descent)
    src = write_silhouette_png(tmp_path / "a.png")
    result = run_cli(src, "--iterations", iterations, "--starts", "2", "-q")
    assert result.exit_code == 1
    what = "non-finite loss" if iterations == "3" else "non-finite vertices"
    assert result.stderr.splitlines() == [f"jeanscv: {src}: the fit diverged ({what})"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.png"]


def test_object_filling_the_frame_with_grabcut(tmp_path, run_cli):
    """A smooth surface filling the frame: GrabCut's mask covers it all and is refused."""
    yy, xx = np.mgrid[:96, :128]
    src = tmp_path / "wall.png"
    src.write_bytes(_encoded(np.stack([xx * 2, yy * 2, np.full_like(xx, 100)], -1).astype(np.uint8), "PNG"))
    result = run_cli(src, *FAST, "-q", "--silhouette", "grabcut")
    assert result.exit_code == 1
    assert result.stderr.splitlines() == [
        f"jeanscv: {src}: the object fills the whole frame: no background to separate it from"
    ]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["wall.png"]


# --- valid but unusual inputs: they must simply work --------------------------------


def _figure_matches(output: Path, shape: np.ndarray) -> None:
    """The paper-style figure in ``output`` shows ``shape`` (H, W) bool: no white on the
    object, no black off it (jeans may be blue anywhere)."""
    with Image.open(output) as im:
        rgb = np.asarray(im.convert("RGB")).astype(int)
    assert rgb.shape[:2] == shape.shape
    black, white = rgb.max(-1) < 60, rgb.min(-1) > 200
    assert black.sum() > 0.3 * shape.sum()
    assert int((white & shape).sum()) == 0
    assert int((black & ~shape).sum()) == 0


def _person(height: int = 72, width: int = 48) -> np.ndarray:
    """(height, width) bool: a body with one arm out to the right, so any flip or turn shows."""
    yy, xx = np.mgrid[:height, :width]
    body = (np.abs(xx - 20) < 9) & (yy > 8) & (yy < height - 8)
    arm = (xx >= 20) & (xx < 42) & (yy > 14) & (yy < 22)
    return body | arm


def test_16bit_grey_silhouette(tmp_path, run_cli):
    shape = _person()
    src = tmp_path / "deep.png"
    Image.fromarray(np.where(shape, 0, 65535).astype(np.uint16)).save(src)
    with Image.open(src) as im:
        assert im.mode == "I;16"
    result = run_cli(src, *FAST, "-q")
    assert result.exit_code == 0 and result.stderr == ""
    _figure_matches(tmp_path / "deep.jeans.png", shape)


def test_animated_gif_becomes_a_clip_of_figures(tmp_path, run_cli):
    """An animated GIF is a clip (tests/test_clips.py): a silhouette drawing's frames each
    become the paper's figure of that frame's shape."""
    shape = _person()
    frames = [
        Image.fromarray(np.where(np.roll(shape, 4 * k, axis=1), 0, 255).astype(np.uint8)).convert("P") for k in range(3)
    ]
    src = tmp_path / "walk.gif"
    frames[0].save(src, save_all=True, append_images=frames[1:], duration=100, loop=0)
    with Image.open(src) as im:
        assert im.n_frames == 3
    result = run_cli(src, *FAST, "-q")
    assert result.exit_code == 0 and result.stderr == ""
    _figure_matches(tmp_path / "walk.jeans.gif", shape)  # Pillow opens a GIF on its first frame
    with Image.open(tmp_path / "walk.jeans.gif") as im:
        assert im.n_frames == 3
        im.seek(2)
        rgb = np.asarray(im.convert("RGB")).astype(int)
    assert int(((rgb.max(-1) < 60) & ~np.roll(shape, 8, axis=1)).sum()) == 0


@pytest.mark.parametrize("kind", ["16-bit RGB PNG", "CMYK JPEG"])
def test_16bit_and_cmyk_photos(tmp_path, run_cli, kind):
    """The photo decodes to the right colours: the background comes out as it went in
    (exactly from 16 bits, within JPEG error from CMYK) and denim lands on the object only."""
    import cv2

    pixels, blob = _ellipse_photo(0.6)
    if kind == "CMYK JPEG":
        src, tolerance = tmp_path / "photo.jpg", 10
        Image.fromarray(pixels).convert("CMYK").save(src, quality=95)
    else:
        src, tolerance = tmp_path / "photo.png", 0
        cv2.imwrite(str(src), pixels[..., ::-1].astype(np.uint16) * 257)  # BGR, 0..65535
    with Image.open(src) as im:
        assert im.mode == ("CMYK" if kind == "CMYK JPEG" else "RGB")
    result = run_cli(src, *FAST, "-q", "--format", "png")
    assert result.exit_code == 0 and result.stderr == ""
    with Image.open(tmp_path / "photo.jeans.png") as im:
        out = np.asarray(im.convert("RGB")).astype(int)
    yy, xx = np.mgrid[:96, :128]
    near = (xx - 64) ** 2 / 40.4**2 + (yy - 48) ** 2 / 30.8**2 < 1  # the ellipse grown by 2 px
    diff = np.abs(out - pixels).max(-1)
    assert int(diff[~near].max()) <= tolerance
    painted = diff > 24
    assert int((painted & ~near).sum()) == 0
    assert painted.sum() > 0.2 * blob.sum()


# Pillow's Image.transpose that undoes each EXIF orientation (its exif_transpose table).
_UNDO = {
    2: Image.Transpose.FLIP_LEFT_RIGHT,
    3: Image.Transpose.ROTATE_180,
    4: Image.Transpose.FLIP_TOP_BOTTOM,
    5: Image.Transpose.TRANSPOSE,
    6: Image.Transpose.ROTATE_270,
    7: Image.Transpose.TRANSVERSE,
    8: Image.Transpose.ROTATE_90,
}
_INVERSE = {2: 2, 3: 3, 4: 4, 5: 5, 6: 8, 7: 7, 8: 6}


@pytest.mark.parametrize("orientation", range(2, 9))
def test_exif_orientation(tmp_path, run_cli, orientation):
    """A JPEG stored turned or mirrored, with the EXIF tag saying how to show it: the
    output has the displayed size and shows the figure the right way round."""
    from PIL import ImageOps

    shape = _person()  # as displayed: 48 wide, 72 tall
    shown = Image.fromarray(np.where(shape, 0, 255).astype(np.uint8)).convert("RGB")
    stored = shown.transpose(_UNDO[_INVERSE[orientation]])
    exif = Image.Exif()
    exif[0x0112] = orientation
    src = tmp_path / f"o{orientation}.jpg"
    stored.save(src, quality=95, exif=exif)
    with Image.open(src) as im:  # Pillow agrees on what is displayed
        assert np.abs(np.asarray(ImageOps.exif_transpose(im)).astype(int) - np.asarray(shown)).max() < 16
    result = run_cli(src, *FAST, "-q", "--format", "png")
    assert result.exit_code == 0 and result.stderr == ""
    _figure_matches(tmp_path / f"o{orientation}.jeans.png", shape)


def test_name_with_spaces_and_non_ascii(tmp_path, run_cli):
    folder = tmp_path / "my photos"
    folder.mkdir()
    src = write_silhouette_png(folder / "mön chat ü.png")
    out = tmp_path / "out dir"
    result = run_cli(src, *FAST, "--json", "-o", out)
    assert result.exit_code == 0
    assert f"{src} -> {out / 'mön chat ü.jeans.png'} (" in result.stderr
    assert sorted(p.name for p in out.iterdir()) == ["mön chat ü.jeans.json", "mön chat ü.jeans.png"]
    report = json.loads((out / "mön chat ü.jeans.json").read_text(encoding="utf-8"))
    assert (report["input"], report["output"]) == (str(src), str(out / "mön chat ü.jeans.png"))


def test_svg_with_a_100000_segment_path(tmp_path, run_cli):
    """100,000 straight segments around a flower shape: decoded and fitted in bounded time."""
    t = np.linspace(0, 2 * np.pi, 100_000, endpoint=False)
    radius = 90 + 20 * np.sin(7 * t)
    x, y = 128 + radius * np.cos(t), 128 + radius * np.sin(t)
    d = "M" + " L".join(f"{a:.3f} {b:.3f}" for a, b in zip(x, y)) + " Z"
    src = tmp_path / "flower.svg"
    src.write_text(f'<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 256 256"><path d="{d}"/></svg>')
    began = time.perf_counter()
    result = run_cli(src, *FAST, "-q")
    assert time.perf_counter() - began < 60
    assert result.exit_code == 0 and result.stderr == ""
    with Image.open(tmp_path / "flower.jeans.png") as im:
        assert im.size == (256, 256)
        assert blue_pixels(im) > 1000


@pytest.fixture
def no_network(monkeypatch):
    """Any attempt to open a network socket fails the test (a Unix-domain one, which the
    workers' fork server listens on, is no network)."""
    local = socket.socket

    def refuse(*args, **kwargs):
        raise AssertionError("jeanscv tried to open a network connection")

    def unix_only(family=socket.AF_INET, *args, **kwargs):
        if family != socket.AF_UNIX:
            refuse()
        return local(family, *args, **kwargs)

    monkeypatch.setattr(socket, "socket", unix_only)
    monkeypatch.setattr(socket, "create_connection", refuse)


def test_svg_doctype_with_external_dtd_is_not_fetched(tmp_path, run_cli, no_network):
    """An external DTD is never read: the standard SVG 1.1 DOCTYPE works offline, and an
    entity that only a local DTD defines stays unexpanded (so the path stays empty)."""
    standard = tmp_path / "standard.svg"
    standard.write_text(
        '<?xml version="1.0"?>\n<!DOCTYPE svg PUBLIC "-//W3C//DTD SVG 1.1//EN" '
        '"http://www.w3.org/Graphics/SVG/1.1/DTD/svg11.dtd">\n'
        '<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 256 256"><path d="M10 10 L200 10 L200 200 Z"/></svg>'
    )
    (tmp_path / "local.dtd").write_text('<!ENTITY shape "M10 10 L200 10 L200 200 Z">')
    local = tmp_path / "local.svg"
    local.write_text(
        '<?xml version="1.0"?>\n<!DOCTYPE svg SYSTEM "local.dtd">\n'
        '<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 256 256"><path d="&shape;"/></svg>'
    )
    result = run_cli(standard, local, *FAST, "-q", "-j", "1")  # here, where no_network holds (not in workers)
    assert result.exit_code == 1
    assert result.stderr.splitlines() == [f"jeanscv: {local}: SVG has no filled path"]
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "local.dtd",
        "local.svg",
        "standard.jeans.png",
        "standard.svg",
    ]


def test_svg_external_entity_is_refused(tmp_path, run_cli, no_network):
    """An entity pointing at a local file or a URL: refused before parsing, nothing read."""
    (tmp_path / "secret.txt").write_text("M10 10 L200 10 L200 200 Z")
    for name, target in (("file.svg", (tmp_path / "secret.txt").as_uri()), ("url.svg", "http://example.com/x")):
        (tmp_path / name).write_text(
            f'<?xml version="1.0"?>\n<!DOCTYPE svg [<!ENTITY xxe SYSTEM "{target}">]>\n'
            '<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 256 256"><path d="&xxe;"/></svg>'
        )
    # One worker: with one per core (the default) the two lines may come in either order.
    result = run_cli(tmp_path / "file.svg", tmp_path / "url.svg", *FAST, "-q", "-j", "1")
    assert result.exit_code == 1
    assert result.stderr.splitlines() == [
        f"jeanscv: {tmp_path / name}: SVG declares XML entities, which are refused for safety"
        for name in ("file.svg", "url.svg")
    ]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file.svg", "secret.txt", "url.svg"]
