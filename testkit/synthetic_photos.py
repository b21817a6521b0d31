"""Synthetic "photos" with known object masks, for testing segmentation.

A silhouette (procedural animal, blob, ``skimage.data.horse()`` or a paper silhouette
from ``/work/shared/silhouettes``) is filled with one real photographic texture from
``skimage.data`` and placed on another, with anti-aliased edges, Gaussian noise and a
JPEG round trip (quality 75). Everything is seeded, so the set is deterministic.

Arrays: images are ``(H, W, 3) uint8`` RGB, masks ``(H, W) bool`` (True = object).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache
from pathlib import Path

import cv2
import numpy as np
import skimage.data

SHARED_SILHOUETTES = Path(__file__).resolve().parents[2] / "shared" / "silhouettes"

# skimage.data images bundled with the wheel (no pooch download needed).
_TEXTURE_NAMES = (
    "chelsea",
    "astronaut",
    "coffee",
    "grass",
    "gravel",
    "brick",
    "rocket",
    "camera",
    "text",
    "moon",
    "page",
    "clock",
)


@dataclass(frozen=True)
class SyntheticPhoto:
    """One test photo: ``image`` (H, W, 3) uint8 RGB and its true ``mask`` (H, W) bool."""

    name: str
    image: np.ndarray
    mask: np.ndarray
    description: str

    @property
    def size(self) -> str:
        """``"WxH"`` of the image."""
        return f"{self.image.shape[1]}x{self.image.shape[0]}"


@cache
def _load_texture(name: str) -> np.ndarray | None:
    """The skimage.data image ``name`` as (h, w, 3) uint8, or None if it cannot load offline."""
    try:
        image = np.asarray(getattr(skimage.data, name)())
    except Exception:  # pooch cache missing, no network: this texture is unavailable
        return None
    if image.dtype != np.uint8:
        return None
    if image.ndim == 2:
        image = np.repeat(image[:, :, None], 3, axis=2)
    return np.ascontiguousarray(image[:, :, :3])


def available_textures() -> list[str]:
    """Names of the skimage.data textures that load here without a download."""
    return [name for name in _TEXTURE_NAMES if _load_texture(name) is not None]


def texture(
    name: str,
    height: int,
    width: int,
    rng: np.random.Generator,
    *,
    tint: tuple[float, float, float] = (1.0, 1.0, 1.0),
    gain: float = 1.0,
    offset: float = 0.0,
) -> np.ndarray:
    """A random crop of skimage texture ``name`` covering (height, width), colour-adjusted.

    The source is scaled so that its short side covers the output with some slack, a
    random window is cut, then ``pixel * gain * tint + offset`` is applied per channel.
    Returns (height, width, 3) uint8.
    """
    source = _load_texture(name)
    if source is None:
        raise RuntimeError(f"texture {name!r} is not available offline")
    h, w = source.shape[:2]
    scale = max(height / h, width / w) * rng.uniform(1.05, 1.4)
    big = cv2.resize(
        source,
        (int(np.ceil(w * scale)), int(np.ceil(h * scale))),
        interpolation=cv2.INTER_LINEAR if scale > 1 else cv2.INTER_AREA,
    )
    y0 = int(rng.integers(0, big.shape[0] - height + 1))
    x0 = int(rng.integers(0, big.shape[1] - width + 1))
    crop = big[y0 : y0 + height, x0 : x0 + width].astype(np.float32)
    crop = crop * gain * np.asarray(tint, dtype=np.float32) + offset
    return np.clip(crop, 0, 255).astype(np.uint8)


def animal_mask(
    height: int,
    width: int,
    rng: np.random.Generator,
    *,
    center: tuple[float, float] = (0.5, 0.5),
    size: float = 0.6,
    flip: bool = False,
) -> np.ndarray:
    """A four-legged animal drawn with cv2: ellipse body, neck, head, ears, legs, tail.

    ``center`` is (x, y) as fractions of (width, height); ``size`` is the body length
    (tail tip to nose) as a fraction of ``min(height, width)``. Returns (height, width) bool.
    """
    unit = size * min(height, width) / 1.3  # the drawing below spans ~1.3 body units
    cx, cy = center[0] * width, center[1] * height
    sign = -1.0 if flip else 1.0
    jitter = lambda s: 1.0 + rng.uniform(-s, s)  # noqa: E731 - tiny local helper

    def pt(x: float, y: float) -> tuple[int, int]:
        # 4 fractional bits: cv2 draws with sub-pixel precision via `shift`.
        return (int(round((cx + sign * x * unit) * 16)), int(round((cy + y * unit) * 16)))

    def thick(t: float) -> int:
        return max(1, int(round(t * unit)))

    canvas = np.zeros((height, width), np.uint8)
    body_w, body_h = 0.45 * jitter(0.1), 0.2 * jitter(0.15)
    cv2.ellipse(
        canvas,
        pt(0, 0),
        (int(body_w * unit * 16), int(body_h * unit * 16)),
        sign * rng.uniform(-8, 8),
        0,
        360,
        255,
        -1,
        cv2.LINE_8,
        4,
    )
    head = (0.52 * jitter(0.05), -0.3 * jitter(0.15))
    cv2.line(canvas, pt(0.3, -0.05), pt(*head), 255, thick(0.16 * jitter(0.2)), cv2.LINE_8, 4)
    cv2.circle(canvas, pt(*head), int(0.14 * jitter(0.15) * unit * 16), 255, -1, cv2.LINE_8, 4)
    snout_end = (head[0] + 0.2, head[1] + 0.05)
    cv2.line(canvas, pt(*head), pt(*snout_end), 255, thick(0.12), cv2.LINE_8, 4)
    for dx in (-0.05, 0.06):  # ears
        ear = np.array(
            [
                pt(head[0] + dx - 0.05, head[1] - 0.08),
                pt(head[0] + dx + 0.05, head[1] - 0.08),
                pt(head[0] + dx, head[1] - 0.24),
            ],
            np.int32,
        )
        cv2.fillPoly(canvas, [ear], 255, cv2.LINE_8, 4)
    leg_len = 0.45 * jitter(0.15)
    leg_t = 0.085 * jitter(0.15)
    for x in (-0.32, -0.2, 0.2, 0.32):
        foot = (x + rng.uniform(-0.08, 0.08), 0.12 + leg_len)
        cv2.line(canvas, pt(x, 0.08), pt(*foot), 255, thick(leg_t), cv2.LINE_8, 4)
    tail = np.array(
        [pt(-0.42, -0.05), pt(-0.58, -0.15 - rng.uniform(0, 0.1)), pt(-0.72, -0.3 - rng.uniform(0, 0.1))], np.int32
    )
    cv2.polylines(canvas, [tail], False, 255, thick(0.06), cv2.LINE_8, 4)
    return canvas > 0


def blob_mask(
    height: int,
    width: int,
    rng: np.random.Generator,
    *,
    center: tuple[float, float] = (0.5, 0.5),
    size: float = 0.5,
    lobes: int = 5,
) -> np.ndarray:
    """A smooth star-shaped blob: radius r(t) = r0 (1 + sum of a few random harmonics).

    ``size`` is the mean diameter as a fraction of ``min(height, width)``. Returns bool.
    """
    t = np.linspace(0, 2 * np.pi, 720, endpoint=False)
    radius = np.ones_like(t)
    for k in range(2, 2 + lobes):
        radius += rng.uniform(0.03, 0.25) / np.sqrt(k - 1) * np.cos(k * t + rng.uniform(0, 2 * np.pi))
    r0 = 0.5 * size * min(height, width)
    xs = center[0] * width + r0 * radius * np.cos(t)
    ys = center[1] * height + r0 * radius * np.sin(t)
    canvas = np.zeros((height, width), np.uint8)
    polygon = np.round(np.stack([xs, ys], axis=1) * 16).astype(np.int32)
    cv2.fillPoly(canvas, [polygon], 255, cv2.LINE_8, 4)
    return canvas > 0


def _place(
    silhouette: np.ndarray,
    height: int,
    width: int,
    center: tuple[float, float],
    size: float,
    flip: bool,
) -> np.ndarray:
    """Scale a bool silhouette so its bounding-box height is ``size * height`` and paste it
    centred at ``center`` (fractions), clipping at the frame. Returns (height, width) bool."""
    rows, cols = np.nonzero(silhouette)
    crop = silhouette[rows.min() : rows.max() + 1, cols.min() : cols.max() + 1].astype(np.float32)
    if flip:
        crop = crop[:, ::-1]
    out_h = max(2, int(round(size * height)))
    out_w = max(2, int(round(crop.shape[1] * out_h / crop.shape[0])))
    scaled = cv2.resize(crop, (out_w, out_h), interpolation=cv2.INTER_LINEAR) >= 0.5
    canvas = np.zeros((height, width), bool)
    top = int(round(center[1] * height - out_h / 2))
    left = int(round(center[0] * width - out_w / 2))
    y0, y1 = max(top, 0), min(top + out_h, height)
    x0, x1 = max(left, 0), min(left + out_w, width)
    canvas[y0:y1, x0:x1] = scaled[y0 - top : y1 - top, x0 - left : x1 - left]
    return canvas


def horse_mask(height: int, width: int, *, center=(0.5, 0.5), size=0.6, flip=False) -> np.ndarray:
    """``skimage.data.horse()`` (dark horse on white, so inverted) placed in the frame."""
    return _place(~np.asarray(skimage.data.horse(), bool), height, width, center, size, flip)


def shared_silhouette_mask(
    name: str,
    height: int,
    width: int,
    *,
    center=(0.5, 0.5),
    size=0.6,
    flip=False,
) -> np.ndarray | None:
    """Paper silhouette ``NAME.png`` (grey, 255 inside) placed in the frame, or None if absent."""
    path = SHARED_SILHOUETTES / f"{name}.png"
    if not path.is_file():
        return None
    grey = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    if grey is None:
        return None
    return _place(grey >= 128, height, width, center, size, flip)


def compose(
    mask: np.ndarray,
    foreground: np.ndarray,
    background: np.ndarray,
    rng: np.random.Generator,
    *,
    noise_sigma: float = 4.0,
    jpeg_quality: int = 75,
    edge_blur: float = 0.8,
) -> np.ndarray:
    """Blend ``foreground`` over ``background`` through a slightly blurred ``mask`` (camera
    optics), add Gaussian noise and round-trip through JPEG. Returns (H, W, 3) uint8 RGB."""
    alpha = cv2.GaussianBlur(mask.astype(np.float32), (0, 0), edge_blur)[:, :, None]
    image = alpha * foreground.astype(np.float32) + (1 - alpha) * background.astype(np.float32)
    image += rng.normal(0.0, noise_sigma, image.shape).astype(np.float32)
    image = np.clip(np.round(image), 0, 255).astype(np.uint8)
    ok, encoded = cv2.imencode(".jpg", cv2.cvtColor(image, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, jpeg_quality])
    assert ok
    return cv2.cvtColor(cv2.imdecode(encoded, cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)


# One case: (name, description, (width, height), silhouette spec, foreground texture
# spec, background texture spec, noise sigma). Texture spec: (name, tint, gain, offset).
_GREEN, _TERRACOTTA, _BLUE, _SAND = (0.55, 1.0, 0.45), (1.15, 0.62, 0.45), (0.5, 0.7, 1.2), (1.1, 0.95, 0.7)
_CASES = [
    (
        "animal_on_grass",
        "procedural animal, cat fur on grass",
        (640, 480),
        ("animal", dict(center=(0.5, 0.52), size=0.75)),
        ("chelsea", (1, 1, 1), 1.0, 0),
        ("grass", _GREEN, 0.9, 0),
        4,
    ),
    (
        "horse_on_brick",
        "skimage horse filled with coffee on brick wall",
        (800, 600),
        ("horse", dict(center=(0.45, 0.5), size=0.7)),
        ("coffee", (1, 1, 1), 1.0, 0),
        ("brick", _TERRACOTTA, 1.1, 10),
        5,
    ),
    (
        "blob_on_gravel",
        "astronaut-textured blob on gravel, small image",
        (400, 300),
        ("blob", dict(center=(0.55, 0.45), size=0.55)),
        ("astronaut", (1, 1, 1), 1.0, 0),
        ("gravel", (1, 1, 1), 1.0, 0),
        4,
    ),
    (
        "dog_on_moon",
        "paper dog, rocket texture on lunar surface",
        (1024, 768),
        ("shared:dog", dict(center=(0.5, 0.5), size=0.55)),
        ("rocket", _TERRACOTTA, 1.3, 20),
        ("moon", (1, 1, 1), 1.0, 40),
        5,
    ),
    (
        "balldragon_portrait",
        "paper balldragon, cat fur on a blue-grey brick wall, portrait",
        (600, 800),
        ("shared:balldragon", dict(center=(0.5, 0.45), size=0.5)),
        ("chelsea", (1, 1, 1), 1.0, 30),
        ("brick", _BLUE, 0.9, 0),
        4,
    ),
    (
        "small_horse_on_grass",
        "small horse (about 3% of the frame) on grass",
        (1200, 900),
        ("horse", dict(center=(0.3, 0.65), size=0.25, flip=True)),
        ("brick", _BLUE, 1.3, 0),
        ("grass", _GREEN, 0.9, 0),
        6,
    ),
    (
        "low_contrast_gravel",
        "low contrast: darker gravel blob on gravel",
        (800, 600),
        ("blob", dict(center=(0.45, 0.55), size=0.6)),
        ("gravel", (1, 1, 1), 0.7, 0),
        ("gravel", (1, 1, 1), 1.0, 15),
        6,
    ),
    (
        "low_contrast_moon",
        "low contrast: moon-textured blob on slightly darker moon",
        (640, 480),
        ("blob", dict(center=(0.5, 0.5), size=0.6)),
        ("moon", (1, 1, 1), 1.0, 28),
        ("moon", (1, 1, 1), 1.0, 0),
        5,
    ),
    (
        "light_on_dark",
        "paper-white animal on a dark rock background",
        (900, 675),
        ("animal", dict(center=(0.55, 0.5), size=0.6)),
        ("page", (1, 1, 1), 1.0, 40),
        ("gravel", (1, 1, 1), 0.45, 0),
        4,
    ),
    (
        "isoluminant_colour",
        "red brick blob on green grass of the same brightness",
        (640, 480),
        ("blob", dict(center=(0.4, 0.5), size=0.5, lobes=3)),
        ("brick", (1.3, 0.75, 0.6), 1.0, 0),
        ("grass", (0.8, 1.15, 0.7), 0.95, 0),
        4,
    ),
    (
        "cut_by_border",
        "large animal whose legs leave the bottom of the frame",
        (1000, 750),
        ("animal", dict(center=(0.5, 0.62), size=0.9)),
        ("coffee", (1.1, 1.0, 0.8), 1.2, 20),
        ("grass", _GREEN, 0.8, 0),
        5,
    ),
    (
        "big_horse_on_text",
        "large horse (blue-tinted cameraman photo) on printed text",
        (1200, 900),
        ("horse", dict(center=(0.5, 0.5), size=0.8)),
        ("camera", _BLUE, 0.9, 0),
        ("text", (1, 1, 1), 1.0, 40),
        5,
    ),
    (
        "person_on_page",
        "paper person, rocket texture, on a printed page",
        (700, 700),
        ("shared:person", dict(center=(0.5, 0.5), size=0.75)),
        ("rocket", _TERRACOTTA, 1.4, 10),
        ("page", (1, 1, 1), 1.0, 0),
        4,
    ),
    (
        "vitruvian_on_grass",
        "paper vitruvian man, sand-tinted brick on grass",
        (800, 800),
        ("shared:vitruvian", dict(center=(0.5, 0.5), size=0.8)),
        ("brick", _SAND, 1.3, 20),
        ("grass", _GREEN, 0.8, 0),
        4,
    ),
    (
        "grass_blob_on_brick",
        "grass-textured blob on a grey brick wall, square",
        (500, 500),
        ("blob", dict(center=(0.5, 0.5), size=0.55, lobes=4)),
        ("grass", _GREEN, 1.0, 0),
        ("brick", (1, 1, 1), 1.0, 0),
        4,
    ),
    (
        "fur_animal_on_text",
        "terracotta-fur animal on printed text",
        (960, 720),
        ("animal", dict(center=(0.45, 0.55), size=0.7)),
        ("chelsea", _TERRACOTTA, 1.2, 0),
        ("text", (1, 1, 1), 1.0, 40),
        5,
    ),
]


def _silhouette(spec, height: int, width: int, rng: np.random.Generator) -> np.ndarray | None:
    kind, params = spec
    if kind == "animal":
        return animal_mask(height, width, rng, **params)
    if kind == "blob":
        return blob_mask(height, width, rng, **params)
    if kind == "horse":
        return horse_mask(height, width, **params)
    return shared_silhouette_mask(kind.split(":", 1)[1], height, width, **params)


def case_names() -> list[str]:
    """Names of all cases, available here or not (for test parametrisation)."""
    return [case[0] for case in _CASES]


@cache
def photo(name: str, seed: int = 2023) -> SyntheticPhoto | None:
    """The case ``name`` rendered with ``seed``, or None if its silhouette or a texture
    is unavailable here (the paper silhouettes live outside the project)."""
    index = case_names().index(name)
    _, description, (width, height), shape, fg, bg, noise = _CASES[index]
    available = set(available_textures())
    if fg[0] not in available or bg[0] not in available:
        return None
    rng = np.random.default_rng([seed, index])
    mask = _silhouette(shape, height, width, rng)
    if mask is None:
        return None
    foreground = texture(fg[0], height, width, rng, tint=fg[1], gain=fg[2], offset=fg[3])
    background = texture(bg[0], height, width, rng, tint=bg[1], gain=bg[2], offset=bg[3])
    image = compose(mask, foreground, background, rng, noise_sigma=noise)
    return SyntheticPhoto(name, image, mask, description)


def photo_set(seed: int = 2023) -> list[SyntheticPhoto]:
    """The test photos: 16 cases, minus any whose silhouette or texture is unavailable."""
    photos = (photo(name, seed) for name in case_names())
    return [case for case in photos if case is not None]


def iou(predicted: np.ndarray, truth: np.ndarray) -> float:
    """Intersection over union of two same-shape bool masks."""
    union = np.logical_or(predicted, truth).sum()
    return float(np.logical_and(predicted, truth).sum() / union) if union else 1.0


@dataclass(frozen=True)
class MultiPhoto:
    """A test photo with several objects: ``image`` (H, W, 3) uint8 and one (H, W) bool
    mask per object in ``masks``, left to right."""

    name: str
    image: np.ndarray
    masks: tuple[np.ndarray, ...]


def two_objects(seed: int = 2023, width: int = 800, height: int = 500) -> MultiPhoto:
    """A dog and its owner: two separate objects side by side on grass, a person
    (the zoo's ``person``, coffee-textured) on the left and a dog (its
    ``dog``, cat fur) on the right. Needs the coffee, chelsea and grass textures
    (bundled with scikit-image)."""
    from testkit.synthetic import ZOO

    rng = np.random.default_rng([seed, 11])
    owner = _place(ZOO["person"]() >= 0.5, height, width, (0.3, 0.5), 0.85, False)
    dog = _place(ZOO["dog"]() >= 0.5, height, width, (0.7, 0.6), 0.45, True)
    coat = texture("coffee", height, width, rng, tint=(1.1, 1.0, 0.8), gain=1.2, offset=20)
    fur = texture("chelsea", height, width, rng)
    ground = texture("grass", height, width, rng, tint=_GREEN, gain=0.9)
    foreground = np.where(owner[..., None], coat, fur)
    image = compose(owner | dog, foreground, ground, rng)
    return MultiPhoto("two_objects", image, (owner, dog))


def _sofa(height: int, width: int, rng: np.random.Generator) -> np.ndarray:
    """A plain wall over a plain red-brown sofa seat filling the lower half, with a
    little upholstery grain: (height, width, 3) uint8."""
    room = np.empty((height, width, 3), np.float32)
    room[:] = (214, 206, 190)
    room[np.arange(height) >= 0.5 * height] = (150, 72, 60)
    room += rng.normal(0.0, 3.0, room.shape).astype(np.float32)
    return np.clip(room, 0, 255).astype(np.uint8)


def _fur(mask: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Cat fur over ``mask``'s box at the photo's own scale (not blown up to the frame:
    fine fur), zero elsewhere: (H, W, 3) uint8."""
    rows, cols = np.nonzero(mask)
    y0, y1, x0, x1 = rows.min(), rows.max() + 1, cols.min(), cols.max() + 1
    coat = np.zeros((*mask.shape, 3), np.uint8)
    coat[y0:y1, x0:x1] = texture("chelsea", y1 - y0, x1 - x0, rng)
    return coat


def pet_beside_owner(seed: int = 2023, width: int = 800, height: int = 500) -> MultiPhoto:
    """A pet on a sofa beside its owner: an animal-textured blob (cat fur) lying on a
    plain sofa-coloured seat that fills the lower half of the frame, and a standing
    person-shaped figure (the zoo's ``person``, plainly dressed) beside it, before a
    plain wall. ``masks``: (person, animal). Needs the chelsea texture (bundled with
    scikit-image)."""
    from testkit.synthetic import ZOO

    rng = np.random.default_rng([seed, 30])
    owner = _place(ZOO["person"]() >= 0.5, height, width, (0.27, 0.52), 0.8, False)
    pet = blob_mask(height, width, rng, center=(0.66, 0.62), size=0.36, lobes=4)
    room = _sofa(height, width, rng)
    clothes = np.empty_like(room)
    clothes[:] = (52, 64, 110)  # plain blue
    foreground = np.where(pet[..., None], _fur(pet, rng), clothes)
    image = compose(owner | pet, foreground, room, rng)
    return MultiPhoto("pet_beside_owner", image, (owner, pet))


def two_pets_on_sofa(seed: int = 2023, width: int = 800, height: int = 500) -> MultiPhoto:
    """Two animal-textured blobs (cat fur) lying apart on a plain sofa, the left one the
    larger; ``masks``: (left, right)."""
    rng = np.random.default_rng([seed, 31])
    left = blob_mask(height, width, rng, center=(0.3, 0.64), size=0.42, lobes=4)
    right = blob_mask(height, width, rng, center=(0.74, 0.66), size=0.3, lobes=4)
    fur = np.maximum(_fur(left, rng), _fur(right, rng))
    image = compose(left | right, fur, _sofa(height, width, rng), rng)
    return MultiPhoto("two_pets_on_sofa", image, (left, right))
