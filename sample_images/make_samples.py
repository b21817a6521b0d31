"""Regenerate the bundled sample images from scikit-image's public-domain/CC0 data.

Run by hand from the repository root; the outputs are committed, so nothing at run
time or in the tests depends on this script::

    python sample_images/make_samples.py

Writes, next to this file:

- ``cat.jpg``, ``coffee.jpg``, ``astronaut.jpg``: photos re-encoded as JPEG (quality 92).
- ``rocket_exif6.jpg``: a portrait crop of the rocket launch, stored sideways with EXIF
  Orientation 6 (rotate 90 degrees clockwise to display), as phone cameras do.
- ``horse_cutout.png``: an RGBA cut-out (a textured horse with an anti-aliased alpha).
- ``coffee.dng``: a camera RAW (Bayer RGGB CFA, 12-bit values, camera-like channel
  gains and colour cross-talk, Orientation 6) mosaicked from the coffee photo, which LibRaw/rawpy decodes
  back to the photo.
"""

from __future__ import annotations

import io
from fractions import Fraction
from pathlib import Path

import numpy as np
import tifffile
from PIL import Image
from skimage import data as skdata

OUT_DIR = Path(__file__).resolve().parent
JPEG_QUALITY = 92
JPEG_MAX_BYTES = 150_000

# The synthetic camera: each photosite's filter leaks some light of the other
# primaries (rows of CROSSTALK sum to 1), and red and blue photosites collect less
# light than green (CAMERA_GAINS), as in real sensors. So a neutral grey is not
# neutral in the raw data, and both the camera white balance (AsShotNeutral) and the
# colour matrix (ColorMatrix1) must be applied for the colours to come out right.
CROSSTALK = np.array([[0.80, 0.15, 0.05], [0.10, 0.80, 0.10], [0.05, 0.20, 0.75]])
CAMERA_GAINS = np.array([0.55, 1.0, 0.72])
CAMERA_FROM_SRGB = np.diag(CAMERA_GAINS) @ CROSSTALK  # linear sRGB -> raw camera RGB
RAW_BLACK = 256
RAW_WHITE = 4095

# XYZ (D65) -> linear sRGB, IEC 61966-2-1.
XYZ_TO_SRGB = np.array(
    [
        [3.2404542, -1.5371385, -0.4985314],
        [-0.9692660, 1.8760108, 0.0415560],
        [0.0556434, -0.2040259, 1.0572252],
    ]
)


def save_jpeg(name: str, rgb: np.ndarray, exif: Image.Exif | None = None) -> Path:
    """Write an (H, W, 3) uint8 array as a JPEG, lowering quality until it fits the size cap."""
    img = Image.fromarray(rgb, "RGB")
    for quality in range(JPEG_QUALITY, 60, -4):
        buf = io.BytesIO()
        img.save(buf, "JPEG", quality=quality, optimize=True, exif=exif.tobytes() if exif is not None else b"")
        if buf.tell() <= JPEG_MAX_BYTES:
            break
    path = OUT_DIR / name
    path.write_bytes(buf.getvalue())
    return path


def make_rocket_exif6() -> Path:
    """Portrait crop around the rocket, stored rotated so EXIF orientation 6 shows it upright."""
    rocket = skdata.rocket()  # (427, 640, 3)
    upright = rocket[:, 182:462]  # (427, 280, 3): the rocket, centred
    # Orientation 6 means "rotate the stored image 90 degrees clockwise to display",
    # so store it rotated 90 degrees counter-clockwise.
    stored = np.ascontiguousarray(np.rot90(upright, k=1))
    exif = Image.Exif()
    exif[0x0112] = 6
    return save_jpeg("rocket_exif6.jpg", stored, exif)


def make_horse_cutout() -> Path:
    """RGBA horse: the CC0 silhouette's anti-aliased edge as alpha, a chestnut coat from the gravel texture."""
    grey = np.asarray(Image.open(Path(skdata.__file__).parent / "horse.png").convert("L"))
    alpha = 255 - grey  # (328, 400) uint8; the silhouette is black on white
    h, w = alpha.shape
    texture = skdata.gravel()[:h, :w].astype(np.float64) / 255.0  # (512, 512) uint8
    shade = 0.75 + 0.5 * (texture - texture.mean())
    coat = np.array([139.0, 84.0, 45.0])  # chestnut
    rgb = np.clip(shade[..., None] * coat, 0, 255).astype(np.uint8)
    rgba = np.dstack([rgb, alpha])
    path = OUT_DIR / "horse_cutout.png"
    Image.fromarray(rgba, "RGBA").save(path, optimize=True)
    return path


def srgb_to_linear(v: np.ndarray) -> np.ndarray:
    """Inverse sRGB transfer function on values in [0, 1]."""
    return np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4)


def rationals(values: np.ndarray, denominator: int = 10000) -> tuple[int, ...]:
    """Flatten values into (numerator, denominator) pairs for a TIFF (S)RATIONAL tag."""
    out: list[int] = []
    for v in np.asarray(values, dtype=np.float64).ravel():
        f = Fraction(float(v)).limit_denominator(denominator)
        out += [f.numerator, f.denominator]
    return tuple(out)


def make_dng() -> Path:
    """Mosaic the coffee photo into a 12-bit RGGB Bayer DNG with orientation 6."""
    return write_dng(skdata.coffee(), OUT_DIR / "coffee.dng")  # (400, 600, 3) uint8, sRGB


def write_dng(displayed: np.ndarray, path: Path) -> Path:
    """Mosaic an (H, W, 3) uint8 sRGB photo (even H and W) into a 12-bit RGGB Bayer DNG
    at ``path``, stored sideways with orientation 6, so it displays as ``displayed``."""
    linear = srgb_to_linear(displayed.astype(np.float64) / 255.0)
    camera = linear @ CAMERA_FROM_SRGB.T
    stored = np.rot90(camera, k=1)  # (W, H, 3): orientation 6 rotates it back
    h, w, _ = stored.shape
    channel = np.empty((h, w), dtype=np.intp)  # RGGB: which colour each photosite sees
    channel[0::2, 0::2] = 0
    channel[0::2, 1::2] = 1
    channel[1::2, 0::2] = 1
    channel[1::2, 1::2] = 2
    cfa = np.take_along_axis(stored, channel[..., None], axis=2)[..., 0]
    rng = np.random.default_rng(20230401)
    # A little photon/read noise, so the file behaves like a sensor and not a lookup table.
    noisy = cfa * (RAW_WHITE - RAW_BLACK) + rng.normal(0.0, 2.0, cfa.shape)
    raw = np.clip(np.round(RAW_BLACK + noisy), 0, RAW_WHITE).astype(np.uint16)

    color_matrix = CAMERA_FROM_SRGB @ XYZ_TO_SRGB  # XYZ -> camera space
    white = CAMERA_FROM_SRGB @ np.ones(3)  # what a white patch looks like to the camera
    as_shot_neutral = white / white.max()
    extratags = [
        (50706, "B", 4, (1, 4, 0, 0), True),  # DNGVersion
        (50707, "B", 4, (1, 1, 0, 0), True),  # DNGBackwardVersion
        (50708, "s", 0, "jeanscv synthetic RGGB", True),  # UniqueCameraModel
        (271, "s", 0, "jeanscv", True),  # Make
        (272, "s", 0, "synthetic RGGB", True),  # Model
        (274, "H", 1, 6, True),  # Orientation: rotate 90 degrees clockwise to display
        (33421, "H", 2, (2, 2), True),  # CFARepeatPatternDim
        (33422, "B", 4, (0, 1, 1, 2), True),  # CFAPattern: R G / G B
        (50710, "B", 3, (0, 1, 2), True),  # CFAPlaneColor
        (50711, "H", 1, 1, True),  # CFALayout: rectangular
        (50713, "H", 2, (1, 1), True),  # BlackLevelRepeatDim
        (50714, "H", 1, RAW_BLACK, True),  # BlackLevel
        (50717, "H", 1, RAW_WHITE, True),  # WhiteLevel
        (50721, "2i", 9, rationals(color_matrix), True),  # ColorMatrix1 (SRATIONAL)
        (50778, "H", 1, 21, True),  # CalibrationIlluminant1: D65
        (50728, "2I", 3, rationals(as_shot_neutral), True),  # AsShotNeutral
    ]
    tifffile.imwrite(
        path,
        raw,
        photometric=tifffile.PHOTOMETRIC.CFA,
        subfiletype=0,
        extratags=extratags,
        metadata=None,
        software=False,
    )
    return path


def main() -> None:
    """Write every sample and print its size."""
    paths = [
        save_jpeg("cat.jpg", skdata.chelsea()),
        save_jpeg("coffee.jpg", skdata.coffee()),
        save_jpeg("astronaut.jpg", skdata.astronaut()),
        make_rocket_exif6(),
        make_horse_cutout(),
        make_dng(),
    ]
    for p in paths:
        print(f"{p.name:20s} {p.stat().st_size:8d} bytes")


if __name__ == "__main__":
    main()
