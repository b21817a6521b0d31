"""The cut inside a detector's box (``jeanscv.subject.boxed.segment_box(...,
drop_support=True)``): the box engine's cut without what the animal stands or lies on
at the bottom of its box
(:func:`~jeanscv.subject.boxed.without_support`), on synthetic photos with exact answers."""

from __future__ import annotations

import cv2
import numpy as np

from jeanscv.detect import Detection
from jeanscv.subject import detected
from jeanscv.subject.boxed import segment_box, without_support
from jeanscv.subject.interactive import ClickSession

BOX = (95, 65, 225, 200)
#: The first row of BOX's bottom band (a third of its height).
BAND_TOP = round(200 - 0.33 * (200 - 65))


def _animal(shape: tuple[int, int]) -> np.ndarray:
    animal = np.zeros(shape, np.uint8)
    cv2.ellipse(animal, (160, 110), (60, 40), 0, 0, 360, 1, -1)
    return animal.astype(bool)


def _cat_on_a_post(seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A dark animal on a wooden post that runs to the photo's bottom edge (where the
    box ends: no margin below it), a second leg of the post beside the box, a pale
    wall, noise: (photo, animal, post)."""
    shape = (200, 320)
    image = np.full((*shape, 3), (200, 205, 210), np.uint8)
    post = np.zeros(shape, bool)
    post[150:, 140:180] = True
    post[120:, 232:250] = True
    image[post] = (150, 110, 70)
    animal = _animal(shape)
    image[animal] = (70, 70, 75)
    noise = np.random.default_rng(seed).normal(0, 8, image.shape)
    return np.clip(image + noise, 0, 255).astype(np.uint8), animal, post & ~animal


def _flat_scene() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Flat colours: (photo, animal, post, the cut that took the post inside BOX)."""
    shape = (240, 320)
    image = np.full((*shape, 3), (200, 205, 210), np.uint8)
    post = np.zeros(shape, bool)
    post[150:, 140:180] = True
    image[post] = (140, 100, 60)
    animal = _animal(shape)
    image[animal] = (60, 60, 60)
    post &= ~animal
    cut = np.zeros(shape, bool)
    x0, y0, x1, y1 = BOX
    cut[y0:y1, x0:x1] = (animal | post)[y0:y1, x0:x1]
    return image, animal, post, cut


def test_the_post_under_the_animal_is_dropped_exactly_in_the_bottom_band():
    image, animal, post, cut = _flat_scene()
    expected = cut.copy()
    expected[BAND_TOP:] &= ~post[BAND_TOP:]  # above the band the post is left to the cut
    assert np.array_equal(without_support(image, cut, BOX), expected)


def test_a_piece_left_wholly_inside_the_band_goes_too():
    image, animal, post, cut = _flat_scene()
    paw = np.zeros_like(cut)
    paw[185:195, 110:125] = True  # the animal's colour, apart from it, low in the box
    image[paw] = (60, 60, 60)
    expected = cut.copy()
    expected[BAND_TOP:] &= ~post[BAND_TOP:]
    assert np.array_equal(without_support(image, cut | paw, BOX), expected)


def test_the_cut_stays_where_too_much_of_it_would_go():
    """A support as large as a white cat's chest on a white toilet: more than 30% of the
    cut would go, so nothing does."""
    image, animal, post, cut = _flat_scene()
    x0, y0, x1, y1 = BOX
    image[BAND_TOP:y1, x0:x1] = (140, 100, 60)  # the post widened to the whole band
    big = cut.copy()
    big[BAND_TOP:y1, x0:x1] = True
    assert np.count_nonzero(big[BAND_TOP:] & ~animal[BAND_TOP:]) > 0.3 * np.count_nonzero(big)
    assert np.array_equal(without_support(image, big, BOX), big)


def test_a_detail_too_small_to_be_a_support_stays():
    """A sliver of the support's colour, under 4% of the cut (a horse's white socks), is
    a detail of the animal, not what it stands on: nothing goes."""
    image, animal, post, cut = _flat_scene()
    leg = np.zeros_like(cut)
    leg[140:196, 112:120] = True  # a leg down into the bottom band, left of the post
    sock = np.zeros_like(cut)
    sock[190:196, 112:120] = True  # its end, the post's colour
    image[leg] = (60, 60, 60)
    image[sock] = (140, 100, 60)
    whole = animal | leg
    assert 0 < np.count_nonzero(sock) < 0.04 * np.count_nonzero(whole)
    assert np.array_equal(without_support(image, whole, BOX), whole)


def test_nothing_to_learn_from_leaves_the_cut_as_it_is():
    image, animal, post, cut = _flat_scene()
    empty = np.zeros_like(cut)
    assert np.array_equal(without_support(image, empty, BOX), empty)
    flat = (95, 100, 225, 102)  # a box two rows high
    assert np.array_equal(without_support(image, cut, flat), cut)


def test_a_detectors_box_leaves_out_the_post_a_persons_box_takes():
    for seed in range(3):
        image, animal, post = _cat_on_a_post(seed)
        # A person's box: GrabCut takes the post inside the box (no margin below it).
        persons = segment_box(image, BOX, 480).mask
        x0, y0, x1, y1 = BOX
        assert np.count_nonzero(persons & post) == np.count_nonzero(post[y0:y1, x0:x1])
        # The detector's: the whole animal, none of the post in the bottom band, nothing else.
        mask = segment_box(image, BOX, 480, drop_support=True).mask
        assert np.array_equal(mask & animal, animal)
        assert not (mask & ~animal & ~post).any()
        assert not (mask & post)[BAND_TOP:].any()
        assert np.count_nonzero(mask & post) < 0.06 * np.count_nonzero(post[y0:y1, x0:x1])


def test_the_click_engine_keeps_the_box_cut_and_the_detector_path_uses_the_new_one():
    image, animal, post = _cat_on_a_post()
    box = tuple(float(v) for v in BOX)
    clicked = ClickSession(image).segment([], [], box).mask
    assert np.array_equal(clicked, segment_box(image, box, 480).mask)
    found = detected.detected_segmentations(image, [Detection("cat", 0, 0.9, box)], 480)[0]
    assert found.method == "detector"
    assert np.array_equal(found.mask, segment_box(image, box, 480, drop_support=True).mask)
    assert not np.array_equal(found.mask, clicked)
