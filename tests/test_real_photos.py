"""Subject finding on real photographs against reference masks (``../shared/real_photos``,
U-2-Net's published predictions; skipped when the folder is absent).

The floors sit about 0.05 under what ``segment(image, "auto")`` reaches today (``python
bench/real_photos.py`` prints the table): they catch regressions, they are not targets.
The issue's target, mean IoU >= 0.80, is not reached; see the README's real-photo table.
"""

from __future__ import annotations

import numpy as np
import pytest

from jeanscv.io.image import load_image
from jeanscv.subject.photo import segment
from testkit.real_photo_set import photo_paths, reference_mask
from testkit.synthetic_photos import iou

# IoU reached on 2026-11-23 (horizon bands left out, one-side contact): 0002-01 0.89,
# 0003 0.90, bike 0.48, boat 0.80, girl 0.60, hockey 0.13, horse 0.92, im_01 0.74, im_14
# 0.47, im_21 0.90, im_27 0.31, lamp2_meitu_1 0.91, long 0.71, rifle1 0.65, rifle2 0.73,
# sailboat3 0.94, vangogh 0.74, whisk 0.85.
FLOORS = {
    "0002-01": 0.80,
    "0003": 0.85,
    "bike": 0.42,
    "boat": 0.72,
    "girl": 0.55,
    "hockey": 0.05,
    "horse": 0.85,
    "im_01": 0.68,
    "im_14": 0.40,
    "im_21": 0.85,
    "im_27": 0.20,
    "lamp2_meitu_1": 0.85,
    "long": 0.65,
    "rifle1": 0.58,
    "rifle2": 0.65,
    "sailboat3": 0.85,
    "vangogh": 0.68,
    "whisk": 0.80,
}
MEAN_FLOOR = 0.65

PHOTOS = photo_paths()
pytestmark = pytest.mark.skipif(not PHOTOS, reason="../shared/real_photos is absent")


@pytest.fixture(scope="module")
def segmented(real_photo_hypotheses) -> dict[str, tuple[float, dict]]:
    """Per photo: the IoU with the reference mask, and auto's details."""
    results = {}
    for path in PHOTOS:
        found = segment(load_image(path).pixels[..., :3], shared=real_photo_hypotheses.take(path.stem))
        results[path.stem] = iou(found.mask, reference_mask(path)), found.details
    return results


@pytest.fixture(scope="module")
def scores(segmented) -> dict[str, float]:
    return {stem: score for stem, (score, _) in segmented.items()}


@pytest.mark.parametrize("stem", sorted(FLOORS))
def test_real_photo_iou_floor(stem, scores):
    if stem not in scores:
        pytest.skip(f"{stem} is not in ../shared/real_photos")
    assert scores[stem] >= FLOORS[stem], f"{stem}: IoU {scores[stem]:.3f} < {FLOORS[stem]}"


def test_real_photo_mean_iou(scores):
    assert np.mean(list(scores.values())) >= MEAN_FLOOR


def test_auto_says_why_the_winner_won(segmented):
    _, details = segmented[PHOTOS[0].stem]  # segment(PHOTOS[0]'s pixels)'s details
    chosen = details["chosen"]
    assert chosen in details["candidates"] and chosen in details["reason"]
    best = max(details["candidates"].values(), key=lambda c: c["score"])
    assert best is details["candidates"][chosen]


def test_the_worst_photos_are_called_uncertain(segmented):
    """The subject is called uncertain (it may be the wrong thing: the hypotheses
    disagree, its colours are the border's, or it runs along a side) on the three
    photos under IoU 0.5 whose masks also hold other things (hockey 0.13, im_27 0.31,
    im_14 0.47; bike's 0.48 is its spokes, not another thing), and on at most two of the
    eight it gets at 0.75 or better (on 2026-11-27: lamp2_meitu_1, whose jeans hang over
    the background, and sailboat3)."""
    uncertain = {stem for stem, (_, details) in segmented.items() if details["uncertain"]}
    assert {"hockey", "im_27", "im_14"} & set(segmented) <= uncertain
    good = {stem for stem, (score, _) in segmented.items() if score >= 0.75}
    assert len(uncertain & good) <= 2, sorted(uncertain & good)
