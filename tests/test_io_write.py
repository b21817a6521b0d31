"""Tests for jeanscv.io.write: encoding and atomic writes."""

from __future__ import annotations

import io
import os
import stat
from pathlib import Path

import numpy as np
import pytest
from PIL import Image, ImageCms

from jeanscv.errors import JeansError
from jeanscv.io import write as write_module
from jeanscv.io.image import load_image
from jeanscv.io.write import (
    atomic_write_bytes,
    encode_image,
    format_for_path,
    write_image,
    write_text,
)


def gradient_rgba(height: int = 16, width: int = 24) -> np.ndarray:
    """(H, W, 4) uint8: smooth colour ramps, alpha 0 in the left column, 255 elsewhere."""
    y, x = np.mgrid[0:height, 0:width]
    rgba = np.stack([x * 10, y * 15, 255 - x * 10, np.full_like(x, 255)], axis=-1).astype(np.uint8)
    rgba[:, 0, 3] = 0
    return rgba


def decode(data: bytes) -> Image.Image:
    image = Image.open(io.BytesIO(data))
    image.load()
    return image


def test_png_keeps_alpha_exactly() -> None:
    rgba = gradient_rgba()
    image = decode(encode_image(rgba, "png"))
    assert image.format == "PNG" and image.mode == "RGBA"
    assert (np.asarray(image) == rgba).all()


def test_jpeg_drops_alpha_keeps_colours() -> None:
    rgba = gradient_rgba()
    image = decode(encode_image(rgba, "JPG"))
    assert image.format == "JPEG" and image.mode == "RGB"
    # Alpha is dropped, not composited: the transparent column keeps its colour.
    error = np.abs(np.asarray(image).astype(int) - rgba[..., :3]).mean()
    assert error < 2.0


def test_jpeg_quality_changes_size() -> None:
    noise = np.random.default_rng(0).integers(0, 256, (64, 64, 3), dtype=np.uint8)
    assert len(encode_image(noise, "jpeg", quality=50)) < len(encode_image(noise, "jpeg", quality=95))


@pytest.mark.parametrize(("fmt", "magic"), [("webp", b"RIFF"), ("tif", b"II*\x00"), ("tiff", b"II*\x00")])
def test_other_formats_keep_alpha(fmt: str, magic: bytes) -> None:
    rgba = gradient_rgba()
    data = encode_image(rgba, fmt, quality=100)
    assert data.startswith(magic)
    image = decode(data)
    assert image.mode == "RGBA"
    assert (np.asarray(image)[..., 3] == rgba[..., 3]).all()


def test_grey_array_is_encoded() -> None:
    grey = np.arange(64, dtype=np.uint8).reshape(8, 8)
    assert (np.asarray(decode(encode_image(grey, "png"))) == grey).all()


def test_exif_and_icc_profile_are_embedded(tmp_path: Path) -> None:
    exif = Image.Exif()
    exif[0x010F] = "TestCam"
    srgb = ImageCms.ImageCmsProfile(ImageCms.createProfile("sRGB")).tobytes()
    for name in ("out.jpg", "out.png"):
        write_image(tmp_path / name, gradient_rgba()[..., :3], exif=exif.tobytes(), icc_profile=srgb)
        loaded = load_image(tmp_path / name)
        assert loaded.icc_profile == srgb
        kept = Image.Exif()
        kept.load(loaded.exif)
        assert kept[0x010F] == "TestCam"


@pytest.mark.parametrize(
    "bad",
    [
        np.zeros((8, 8, 3), np.float32),
        np.zeros((8, 8, 2), np.uint8),
        np.zeros((8,), np.uint8),
    ],
)
def test_bad_arrays_are_rejected(bad: np.ndarray) -> None:
    with pytest.raises(JeansError, match="cannot encode an array"):
        encode_image(bad, "png")


def test_bad_format_and_quality() -> None:
    pixels = gradient_rgba()[..., :3]
    with pytest.raises(JeansError, match="unsupported output format 'gif'"):
        encode_image(pixels, "gif")
    with pytest.raises(JeansError, match="quality must be 1..100"):
        encode_image(pixels, "jpeg", quality=0)


def test_format_from_extension(tmp_path: Path) -> None:
    assert [format_for_path(f"a{ext}") for ext in (".PNG", ".jpg", ".jpeg", ".webp", ".tif", ".tiff")] == [
        "PNG",
        "JPEG",
        "JPEG",
        "WEBP",
        "TIFF",
        "TIFF",
    ]
    with pytest.raises(JeansError, match=r"extension '\.bmp'"):
        write_image(tmp_path / "out.bmp", gradient_rgba())
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(("name", "magic"), [("o.png", b"\x89PNG"), ("o.jpg", b"\xff\xd8\xff"), ("o.webp", b"RIFF")])
def test_write_image_picks_format_from_extension(tmp_path: Path, name: str, magic: bytes) -> None:
    write_image(tmp_path / name, gradient_rgba())
    assert (tmp_path / name).read_bytes().startswith(magic)


def test_explicit_format_overrides_extension(tmp_path: Path) -> None:
    write_image(tmp_path / "out.img", gradient_rgba(), fmt="png")
    assert (tmp_path / "out.img").read_bytes().startswith(b"\x89PNG")


def test_write_text_utf8(tmp_path: Path) -> None:
    write_text(tmp_path / "fit.json", '{"garment": "jeans", "note": "café ✓"}\n')
    assert (tmp_path / "fit.json").read_bytes() == '{"garment": "jeans", "note": "café ✓"}\n'.encode()


def test_atomic_write_replaces_and_keeps_mode(tmp_path: Path) -> None:
    target = tmp_path / "out.bin"
    target.write_bytes(b"old")
    os.chmod(target, 0o640)

    atomic_write_bytes(target, b"new contents")

    assert target.read_bytes() == b"new contents"
    assert stat.S_IMODE(target.stat().st_mode) == 0o640
    assert [p.name for p in tmp_path.iterdir()] == ["out.bin"]


def test_new_file_mode_follows_umask(tmp_path: Path) -> None:
    old_umask = os.umask(0o022)
    try:
        atomic_write_bytes(tmp_path / "new.bin", b"x")
    finally:
        os.umask(old_umask)
    assert stat.S_IMODE((tmp_path / "new.bin").stat().st_mode) == 0o644


def test_failed_rename_leaves_old_target_and_no_temp(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    target = tmp_path / "out.png"
    target.write_bytes(b"previous output")

    def failing_replace(src: object, dst: object) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(write_module.os, "replace", failing_replace)
    with pytest.raises(JeansError, match="^cannot write output: no space left on device$"):
        write_image(target, gradient_rgba())

    assert target.read_bytes() == b"previous output"
    assert [p.name for p in tmp_path.iterdir()] == ["out.png"]


def test_ctrl_c_mid_write_leaves_no_temp(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    target = tmp_path / "out.txt"
    target.write_text("previous")

    def interrupted_fsync(fd: int) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(write_module.os, "fsync", interrupted_fsync)
    with pytest.raises(KeyboardInterrupt):
        write_text(target, "half of something")

    assert target.read_text() == "previous"
    assert [p.name for p in tmp_path.iterdir()] == ["out.txt"]


def test_missing_folder(tmp_path: Path) -> None:
    with pytest.raises(JeansError, match="^cannot write output: no such file or directory$"):
        write_text(tmp_path / "no" / "such" / "dir" / "out.txt", "x")


def test_parent_is_a_file(tmp_path: Path) -> None:
    (tmp_path / "file").write_text("x")
    with pytest.raises(JeansError, match="^cannot write output: not a directory$"):
        write_text(tmp_path / "file" / "out.txt", "x")


def test_target_is_a_folder(tmp_path: Path) -> None:
    (tmp_path / "out.png").mkdir()
    with pytest.raises(JeansError, match="^cannot write output: is a directory$"):
        write_image(tmp_path / "out.png", gradient_rgba())
    assert [p.name for p in tmp_path.iterdir()] == ["out.png"]


def test_read_only_folder(tmp_path: Path) -> None:
    folder = tmp_path / "locked"
    folder.mkdir()
    folder.chmod(0o555)
    try:
        if os.access(folder, os.W_OK):
            pytest.skip("running with privileges that ignore folder permissions (root)")
        with pytest.raises(JeansError, match="^cannot write output: permission denied$"):
            write_image(folder / "out.png", gradient_rgba())
        assert list(folder.iterdir()) == []
    finally:
        folder.chmod(0o755)


def test_permission_denied_is_translated(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # The same failure as test_read_only_folder, reproducible when tests run as root.
    def denied(*args: object, **kwargs: object) -> int:
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(write_module.os, "open", denied)
    with pytest.raises(JeansError, match="^cannot write output: permission denied$"):
        write_image(tmp_path / "out.png", gradient_rgba())
    assert list(tmp_path.iterdir()) == []


def test_an_interrupt_just_after_the_temporary_file_is_made_leaves_none(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A signal can land between the temporary file's creation and the block that removes
    it on failure (a ``-j 2`` run's SIGTERM once left ``.s01.jeans.png.*.tmp``): the
    file is removed all the same."""
    target = tmp_path / "out.txt"
    target.write_text("previous")

    def interrupted_lock(fd: int, wait: bool) -> bool:
        raise KeyboardInterrupt

    monkeypatch.setattr(write_module, "_lock", interrupted_lock)
    with pytest.raises(KeyboardInterrupt):
        write_text(target, "half of something")

    assert target.read_text() == "previous"
    assert [p.name for p in tmp_path.iterdir()] == ["out.txt"]


def test_abandon_writes_removes_what_is_being_written(tmp_path, monkeypatch):
    """A process that exits without waiting for its writer threads (``jeanscv serve``)
    leaves no temporary file, and no write starts or finishes after it."""
    monkeypatch.setattr(write_module, "_abandoned", False)
    monkeypatch.setattr(write_module, "_writing", set())
    tmp, fd = write_module._create_temporary(tmp_path / "a.png")  # a write under way in another thread
    assert tmp.exists()
    assert write_module.abandon_writes() == [tmp] and not tmp.exists()
    os.close(fd)
    with pytest.raises(JeansError, match="stopping"):
        write_module.atomic_write_bytes(tmp_path / "b.png", b"data")
    assert list(tmp_path.iterdir()) == []
