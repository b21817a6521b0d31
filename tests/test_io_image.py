"""Tests for jeanscv.io.image: decoding, orientation, bit depth, and bad files."""

from __future__ import annotations

import os
import struct
import subprocess
import sys
import time
import zlib
from pathlib import Path

import cv2
import numpy as np
import pytest
from PIL import Image, ImageFile

from jeanscv.errors import JeansError
from jeanscv.io.image import (
    IMAGE_EXTENSIONS,
    RAW_EXTENSIONS,
    SUPPORTED_EXTENSIONS,
    load_image,
)

SAMPLES = Path(__file__).resolve().parents[1] / "sample_images"
RED, BLUE, GREY = (255, 0, 0), (0, 0, 255), (128, 128, 128)


def png_chunk(tag: bytes, payload: bytes) -> bytes:
    """One PNG chunk with a valid CRC."""
    return struct.pack(">I", len(payload)) + tag + payload + struct.pack(">I", zlib.crc32(tag + payload))


def corner_pattern(width: int = 48, height: int = 24) -> np.ndarray:
    """(H, W, 3) grey image, red 8x8 block at the top-left corner, blue at the top-right."""
    pixels = np.full((height, width, 3), GREY, np.uint8)
    pixels[:8, :8] = RED
    pixels[:8, -8:] = BLUE
    return pixels


def noise_image(height: int = 64, width: int = 64, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, 256, (height, width, 3), dtype=np.uint8)


# Where the stored top-left (red) and top-right (blue) blocks end up once displayed,
# read off the EXIF 2.3 orientation definitions ("0th row is the visual ...").
ORIENTATION_CORNERS = {
    1: ("top-left", "top-right"),
    2: ("top-right", "top-left"),
    3: ("bottom-right", "bottom-left"),
    4: ("bottom-left", "bottom-right"),
    5: ("top-left", "bottom-left"),
    6: ("top-right", "bottom-right"),
    7: ("bottom-right", "top-right"),
    8: ("bottom-left", "top-left"),
}


def corner_colour(pixels: np.ndarray, corner: str) -> np.ndarray:
    """Mean colour of the 4x4 patch inside the given corner."""
    vertical, horizontal = corner.split("-")
    rows = slice(0, 4) if vertical == "top" else slice(-4, None)
    cols = slice(0, 4) if horizontal == "left" else slice(-4, None)
    return pixels[rows, cols, :3].reshape(-1, 3).mean(axis=0)


@pytest.mark.parametrize("orientation", range(1, 9))
def test_exif_orientation_gives_displayed_image(tmp_path: Path, orientation: int) -> None:
    exif = Image.Exif()
    exif[0x0112] = orientation
    exif[0x010F] = "TestCam"  # Make: must survive, orientation must not
    path = tmp_path / "oriented.png"
    Image.fromarray(corner_pattern()).save(path, exif=exif.tobytes())

    loaded = load_image(path)

    expected_size = (48, 24) if orientation <= 4 else (24, 48)
    assert loaded.original_size == expected_size
    assert loaded.pixels.shape == (expected_size[1], expected_size[0], 3)
    assert loaded.exif_orientation == orientation
    red_corner, blue_corner = ORIENTATION_CORNERS[orientation]
    assert corner_colour(loaded.pixels, red_corner).tolist() == list(RED)
    assert corner_colour(loaded.pixels, blue_corner).tolist() == list(BLUE)
    kept = Image.Exif()
    kept.load(loaded.exif)
    assert kept.get(0x010F) == "TestCam"
    assert 0x0112 not in kept


def test_exif_orientation_6_jpeg_like_a_phone(tmp_path: Path) -> None:
    exif = Image.Exif()
    exif[0x0112] = 6
    path = tmp_path / "phone.jpg"
    Image.fromarray(corner_pattern()).save(path, quality=95, exif=exif.tobytes())

    loaded = load_image(path)

    assert loaded.original_size == (24, 48)
    assert loaded.source_format == "JPEG"
    assert np.abs(corner_colour(loaded.pixels, "top-right") - RED).max() < 12
    assert np.abs(corner_colour(loaded.pixels, "bottom-right") - BLUE).max() < 12
    assert loaded.exif is None  # orientation was its only tag


def test_16bit_grey_png_is_scaled_not_clipped(tmp_path: Path) -> None:
    grey = np.zeros((8, 16), np.uint16)
    grey[0, :4] = [65535, 32768, 257 * 100, 300]
    path = tmp_path / "grey16.png"
    Image.fromarray(grey).save(path)
    assert path.read_bytes()[24] == 16  # IHDR bit depth: really a 16-bit file

    loaded = load_image(path)

    assert loaded.pixels.shape == (8, 16, 3)
    assert loaded.pixels[0, :4, 0].tolist() == [255, 128, 100, 1]
    assert (loaded.pixels[..., 0] == loaded.pixels[..., 2]).all()


def test_16bit_rgb_and_rgba_png_are_rounded(tmp_path: Path) -> None:
    rgba = np.zeros((8, 8, 4), np.uint16)
    rgba[..., 3] = 65535
    rgba[0, 0] = [65535, 32768, 65280, 40000]  # 65280 / 257 = 254.0; Pillow alone gives 255
    rgba[0, 1, :3] = [257 * 77, 128, 0]
    cv2.imwrite(str(tmp_path / "rgb16.png"), np.ascontiguousarray(rgba[..., 2::-1]))
    cv2.imwrite(str(tmp_path / "rgba16.png"), rgba[..., [2, 1, 0, 3]])

    rgb = load_image(tmp_path / "rgb16.png").pixels
    with_alpha = load_image(tmp_path / "rgba16.png")

    assert rgb[0, 0].tolist() == [255, 128, 254]
    assert rgb[0, 1].tolist() == [77, 0, 0]
    assert with_alpha.pixels[0, 0].tolist() == [255, 128, 254, 156]
    assert with_alpha.alpha_meaningful


def test_grey_and_grey_alpha_png(tmp_path: Path) -> None:
    grey = np.arange(64, dtype=np.uint8).reshape(8, 8) * 4
    Image.fromarray(grey, "L").save(tmp_path / "grey.png")
    alpha = np.full((8, 8), 255, np.uint8)
    alpha[0, 0] = 0
    Image.fromarray(np.dstack([grey, alpha]), "LA").save(tmp_path / "grey_alpha.png")

    plain = load_image(tmp_path / "grey.png")
    with_alpha = load_image(tmp_path / "grey_alpha.png")

    assert plain.pixels.shape == (8, 8, 3)
    assert (plain.pixels == grey[..., None]).all()
    assert not plain.alpha_meaningful
    assert with_alpha.pixels.shape == (8, 8, 4)
    assert (with_alpha.pixels[..., 0] == grey).all()
    assert with_alpha.pixels[0, 0, 3] == 0 and with_alpha.pixels[0, 1, 3] == 255
    assert with_alpha.alpha_meaningful


def test_palette_png_with_transparent_index(tmp_path: Path) -> None:
    indices = np.zeros((8, 8), np.uint8)
    indices[2:6, 2:6] = 1
    palette_image = Image.fromarray(indices, "P")
    palette_image.putpalette([0, 0, 0, 200, 30, 10] + [0] * 762)
    palette_image.save(tmp_path / "palette.png", transparency=0)

    loaded = load_image(tmp_path / "palette.png")

    assert loaded.pixels.shape == (8, 8, 4)
    assert loaded.alpha_meaningful
    assert loaded.pixels[3, 3].tolist() == [200, 30, 10, 255]
    assert loaded.pixels[0, 0, 3] == 0
    assert int((loaded.pixels[..., 3] == 255).sum()) == 16


def test_opaque_rgba_keeps_alpha_but_is_not_meaningful(tmp_path: Path) -> None:
    rgba = np.dstack([noise_image(8, 8), np.full((8, 8), 255, np.uint8)])
    Image.fromarray(rgba, "RGBA").save(tmp_path / "opaque.png")

    loaded = load_image(tmp_path / "opaque.png")

    assert loaded.pixels.shape == (8, 8, 4)
    assert not loaded.alpha_meaningful
    assert (loaded.pixels == rgba).all()


def test_cmyk_jpeg_becomes_rgb(tmp_path: Path) -> None:
    cmyk = np.zeros((16, 32, 4), np.uint8)
    cmyk[:, :16] = [0, 255, 255, 0]  # magenta + yellow = red
    cmyk[:, 16:] = [255, 255, 0, 0]  # cyan + magenta = blue
    Image.frombytes("CMYK", (32, 16), cmyk.tobytes()).save(tmp_path / "cmyk.jpg", quality=95)

    loaded = load_image(tmp_path / "cmyk.jpg")

    assert loaded.pixels.shape == (16, 32, 3)
    assert np.abs(loaded.pixels[8, 4].astype(int) - RED).max() <= 8
    assert np.abs(loaded.pixels[8, 28].astype(int) - BLUE).max() <= 8


def test_animated_gif_gives_first_frame(tmp_path: Path) -> None:
    frames = [Image.new("RGB", (10, 10), colour) for colour in (RED, (0, 255, 0), BLUE)]
    frames[0].save(tmp_path / "anim.gif", save_all=True, append_images=frames[1:], duration=100, loop=0)

    loaded = load_image(tmp_path / "anim.gif")

    assert loaded.source_format == "GIF"
    assert loaded.pixels.shape == (10, 10, 3)
    assert (loaded.pixels == RED).all()


@pytest.mark.parametrize(
    ("name", "save_kw", "fmt"),
    [
        ("a.webp", {"lossless": True}, "WEBP"),
        ("a.tif", {"compression": "tiff_lzw"}, "TIFF"),
        ("a.bmp", {}, "BMP"),
        ("a.png", {}, "PNG"),
    ],
)
def test_lossless_formats_round_trip_exactly(tmp_path: Path, name: str, save_kw: dict, fmt: str) -> None:
    pixels = noise_image(12, 20, seed=3)
    Image.fromarray(pixels).save(tmp_path / name, **save_kw)

    loaded = load_image(tmp_path / name)

    assert loaded.source_format == fmt
    assert not loaded.is_raw
    assert loaded.original_size == (20, 12)
    assert (loaded.pixels == pixels).all()


def test_webp_with_alpha(tmp_path: Path) -> None:
    rgba = np.dstack([noise_image(12, 12, seed=4), np.tile(np.arange(12, dtype=np.uint8) * 20, (12, 1))])
    Image.fromarray(rgba, "RGBA").save(tmp_path / "alpha.webp", lossless=True, exact=True)

    loaded = load_image(tmp_path / "alpha.webp")

    assert loaded.alpha_meaningful
    assert (loaded.pixels == rgba).all()


def test_rgb_icc_profile_is_kept_grey_one_dropped(tmp_path: Path) -> None:
    from PIL import ImageCms

    srgb = ImageCms.ImageCmsProfile(ImageCms.createProfile("sRGB")).tobytes()
    Image.fromarray(noise_image(8, 8)).save(tmp_path / "tagged.png", icc_profile=srgb)
    fake_grey = srgb[:16] + b"GRAY" + srgb[20:]
    Image.fromarray(noise_image(8, 8)[..., 0], "L").save(tmp_path / "grey.png", icc_profile=fake_grey)

    assert load_image(tmp_path / "tagged.png").icc_profile == srgb
    assert load_image(tmp_path / "grey.png").icc_profile is None


# --- bad files -------------------------------------------------------------------


def assert_rejected(path: Path, fragment: str, **kw: object) -> str:
    with pytest.raises(JeansError) as info:
        load_image(path, **kw)
    message = str(info.value)
    assert fragment in message
    assert "\n" not in message and str(path) not in message
    return message


def test_empty_file(tmp_path: Path) -> None:
    (tmp_path / "empty.jpg").write_bytes(b"")
    (tmp_path / "empty.nef").write_bytes(b"")
    assert_rejected(tmp_path / "empty.jpg", "empty file")
    assert_rejected(tmp_path / "empty.nef", "empty file")


def test_missing_file_and_folder(tmp_path: Path) -> None:
    assert_rejected(tmp_path / "nope.jpg", "file not found")
    assert_rejected(tmp_path, "is a folder")


def test_text_renamed_jpg(tmp_path: Path) -> None:
    (tmp_path / "notes.jpg").write_text("these are not the pixels you are looking for\n")
    assert_rejected(tmp_path / "notes.jpg", "not an image file")


def test_truncated_jpeg(tmp_path: Path) -> None:
    Image.fromarray(noise_image()).save(tmp_path / "full.jpg", quality=90)
    data = (tmp_path / "full.jpg").read_bytes()
    (tmp_path / "cut.jpg").write_bytes(data[: len(data) // 2])
    assert_rejected(tmp_path / "cut.jpg", "truncated or corrupt image")


def test_truncated_png(tmp_path: Path) -> None:
    Image.fromarray(noise_image()).save(tmp_path / "full.png")
    data = (tmp_path / "full.png").read_bytes()
    (tmp_path / "cut.png").write_bytes(data[: len(data) // 2])
    assert_rejected(tmp_path / "cut.png", "truncated or corrupt image")


def test_truncated_stays_an_error_even_if_pillow_is_told_to_tolerate_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    Image.fromarray(noise_image()).save(tmp_path / "full.jpg", quality=90)
    data = (tmp_path / "full.jpg").read_bytes()
    (tmp_path / "cut.jpg").write_bytes(data[: len(data) // 2])
    monkeypatch.setattr(ImageFile, "LOAD_TRUNCATED_IMAGES", True)

    assert_rejected(tmp_path / "cut.jpg", "truncated or corrupt image")
    assert ImageFile.LOAD_TRUNCATED_IMAGES is True  # the caller's setting is restored


def test_decompression_bomb_header_rejected_before_decoding(tmp_path: Path) -> None:
    header = struct.pack(">IIBBBBB", 50000, 50000, 8, 2, 0, 0, 0)  # 8-bit RGB
    bomb = (
        b"\x89PNG\r\n\x1a\n"
        + png_chunk(b"IHDR", header)
        + png_chunk(b"IDAT", zlib.compress(b"\x00" * 4096))
        + png_chunk(b"IEND", b"")
    )
    (tmp_path / "bomb.png").write_bytes(bomb)

    start = time.perf_counter()
    message = assert_rejected(tmp_path / "bomb.png", "50000x50000 = 2500 MP")
    elapsed = time.perf_counter() - start

    assert "limit of 100 MP" in message
    assert elapsed < 0.5  # decoding 7.5 GB of pixels would take far longer (or die)


def test_max_pixels_is_configurable(tmp_path: Path) -> None:
    Image.fromarray(noise_image(40, 50)).save(tmp_path / "small.png")
    assert_rejected(tmp_path / "small.png", "40 = 0.002 MP, over the --max-pixels limit of 0.001 MP", max_pixels=1000)
    assert load_image(tmp_path / "small.png", max_pixels=2000).original_size == (50, 40)


@pytest.mark.parametrize(("width", "height"), [(1, 1), (7, 100), (100, 7)])
def test_too_small(tmp_path: Path, width: int, height: int) -> None:
    Image.new("RGB", (width, height), RED).save(tmp_path / "tiny.png")
    assert_rejected(tmp_path / "tiny.png", f"image too small: {width}x{height}")


def test_smallest_accepted_size(tmp_path: Path) -> None:
    Image.new("RGB", (8, 8), RED).save(tmp_path / "eight.png")
    assert load_image(tmp_path / "eight.png").pixels.shape == (8, 8, 3)


def test_text_renamed_nef(tmp_path: Path) -> None:
    (tmp_path / "fake.nef").write_text("definitely not a Nikon\n" * 20)
    assert_rejected(tmp_path / "fake.nef", "not a readable RAW file")


def test_jpeg_renamed_cr2(tmp_path: Path) -> None:
    (tmp_path / "photo.cr2").write_bytes((SAMPLES / "cat.jpg").read_bytes())
    assert_rejected(tmp_path / "photo.cr2", "not a readable RAW file")


def test_truncated_dng(tmp_path: Path) -> None:
    data = (SAMPLES / "coffee.dng").read_bytes()
    (tmp_path / "cut.dng").write_bytes(data[: len(data) // 2])
    assert_rejected(tmp_path / "cut.dng", "not a readable RAW file")


def test_raw_max_pixels(tmp_path: Path) -> None:
    assert_rejected(SAMPLES / "coffee.dng", "image is 600x400 = 0.24 MP", max_pixels=100_000)


# --- RAW and the bundled samples ----------------------------------------------------


def block_means(pixels: np.ndarray, rows: int, cols: int) -> np.ndarray:
    """(rows, cols, 3) mean colours of a grid of equal blocks."""
    h, w = pixels.shape[:2]
    return pixels[..., :3].astype(np.float64).reshape(rows, h // rows, cols, w // cols, 3).mean(axis=(1, 3))


def test_sample_dng_decodes_upright_with_the_photo_colours() -> None:
    photo = np.asarray(Image.open(SAMPLES / "coffee.jpg").convert("RGB"))

    loaded = load_image(SAMPLES / "coffee.dng")

    assert loaded.is_raw and loaded.source_format == "DNG"
    assert loaded.exif_orientation == 6
    assert loaded.original_size == (600, 400)  # stored 400x600 portrait, shown landscape
    assert loaded.pixels.shape == (400, 600, 3)  # the camera's full size by default
    assert not loaded.alpha_meaningful
    # The DNG was mosaicked from this photo through camera gains and colour cross-talk;
    # white balance, colour matrix and orientation must all undo that.
    assert np.abs(loaded.pixels.reshape(-1, 3).mean(axis=0) - photo.reshape(-1, 3).mean(axis=0)).max() < 6
    assert np.abs(block_means(loaded.pixels, 10, 15) - block_means(photo, 10, 15)).max() < 12


def test_sample_dng_half_size() -> None:
    loaded = load_image(SAMPLES / "coffee.dng", raw_half_size=True)
    assert loaded.pixels.shape == (200, 300, 3)  # each 2x2 Bayer block is one pixel
    assert loaded.original_size == (600, 400)
    full = load_image(SAMPLES / "coffee.dng").pixels
    halved = full.astype(np.float64).reshape(200, 2, 300, 2, 3).mean(axis=(1, 3))
    assert np.abs(block_means(loaded.pixels, 10, 15) - block_means(halved, 10, 15)).max() < 12


@pytest.mark.parametrize(
    ("name", "size", "channels", "orientation", "alpha"),
    [
        ("cat.jpg", (451, 300), 3, 1, False),
        ("coffee.jpg", (600, 400), 3, 1, False),
        ("astronaut.jpg", (512, 512), 3, 1, False),
        ("rocket_exif6.jpg", (280, 427), 3, 6, False),
        ("horse_cutout.png", (400, 328), 4, 1, True),
    ],
)
def test_bundled_samples(name: str, size: tuple[int, int], channels: int, orientation: int, alpha: bool) -> None:
    loaded = load_image(SAMPLES / name)
    assert loaded.original_size == size
    assert loaded.pixels.shape == (size[1], size[0], channels)
    assert loaded.exif_orientation == orientation
    assert loaded.alpha_meaningful is alpha
    assert (SAMPLES / name).stat().st_size < 200_000


def test_sample_horse_alpha_covers_the_horse() -> None:
    alpha = load_image(SAMPLES / "horse_cutout.png").pixels[..., 3]
    assert alpha[0, 0] == 0  # corner: background
    assert alpha[164, 200] == 255  # the horse's body
    assert 0.25 < (alpha > 127).mean() < 0.45


def test_extension_sets() -> None:
    assert {".jpg", ".png", ".webp", ".tif", ".bmp", ".gif"} <= IMAGE_EXTENSIONS
    assert {".dng", ".nef", ".cr2", ".cr3", ".arw", ".raf"} <= RAW_EXTENSIONS
    assert not IMAGE_EXTENSIONS & RAW_EXTENSIONS
    assert SUPPORTED_EXTENSIONS == IMAGE_EXTENSIONS | RAW_EXTENSIONS
    assert all(ext == ext.lower() and ext.startswith(".") for ext in SUPPORTED_EXTENSIONS)


def test_rawpy_is_not_imported_with_the_module() -> None:
    code = "import sys, jeanscv.io.image; print('rawpy' in sys.modules, 'cv2' in sys.modules)"
    root = str(Path(__file__).resolve().parents[1])
    result = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        check=True,
        cwd=root,
        env={**os.environ, "PYTHONPATH": root},
    )
    assert result.stdout.split() == ["False", "False"]


def test_tiff_orientation_tag_is_applied(tmp_path: Path) -> None:
    Image.fromarray(corner_pattern()).save(tmp_path / "oriented.tif", tiffinfo={0x0112: 8})

    loaded = load_image(tmp_path / "oriented.tif")

    assert loaded.exif_orientation == 8
    assert loaded.original_size == (24, 48)
    assert corner_colour(loaded.pixels, "bottom-left").tolist() == list(RED)
    assert corner_colour(loaded.pixels, "top-left").tolist() == list(BLUE)


@pytest.mark.parametrize("orientation", [3, 6])
def test_16bit_colour_tiff_and_png_with_orientation(tmp_path: Path, orientation: int) -> None:
    import tifffile

    stored = corner_pattern().astype(np.uint16) * 257
    stored[:8, :8] = [65280, 0, 0]  # red that rounds to 254 (Pillow's high byte says 255)
    tifffile.imwrite(tmp_path / "deep.tif", stored, photometric="rgb", extratags=[(274, "H", 1, orientation, True)])
    cv2.imwrite(str(tmp_path / "plain.png"), np.ascontiguousarray(stored[..., ::-1]))
    png = (tmp_path / "plain.png").read_bytes()
    exif = Image.Exif()
    exif[0x0112] = orientation
    iend = png.rindex(b"IEND") - 4  # insert eXIf before IEND, as some writers do
    (tmp_path / "deep.png").write_bytes(png[:iend] + png_chunk(b"eXIf", exif.tobytes()[6:]) + png[iend:])

    for name in ("deep.tif", "deep.png"):
        loaded = load_image(tmp_path / name)
        red_corner, blue_corner = ORIENTATION_CORNERS[orientation]
        assert loaded.exif_orientation == orientation, name
        assert corner_colour(loaded.pixels, red_corner).tolist() == [254, 0, 0], name
        assert corner_colour(loaded.pixels, blue_corner).tolist() == list(BLUE), name


def _jpeg_with_metadata(segments: int) -> bytes:
    """A small JPEG with ``segments`` full 64 KB EXIF (APP1) segments after its SOI."""
    import io

    buffer = io.BytesIO()
    Image.fromarray(np.full((16, 16, 3), 90, np.uint8)).save(buffer, "JPEG")
    jpeg = buffer.getvalue()
    segment = b"\xff\xe1" + struct.pack(">H", 65535) + b"Exif\x00\x00" + b"\x00" * (65535 - 8)
    return jpeg[:2] + segment * segments + jpeg[2:]


def test_jpeg_metadata_over_the_cap_is_refused_before_pillow_reads_it(tmp_path: Path) -> None:
    """Pillow joins EXIF segments quadratically (1,500 of them took 43 s): over 16 MB of
    metadata the file is refused from its segment headers alone."""
    from jeanscv.io.image import MAX_JPEG_METADATA

    small = tmp_path / "some.jpg"
    small.write_bytes(_jpeg_with_metadata(20))  # 1.3 MB: read as usual
    assert load_image(small).pixels.shape == (16, 16, 3)
    bomb = tmp_path / "bomb.jpg"
    bomb.write_bytes(_jpeg_with_metadata(MAX_JPEG_METADATA // 65535 + 1))
    with pytest.raises(JeansError, match="JPEG metadata is over 16 MB"):
        load_image(bomb)
