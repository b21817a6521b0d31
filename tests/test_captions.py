"""Meme captions in any script: the font chosen per caption, and emoji named, never boxes."""

from __future__ import annotations

import unicodedata
from pathlib import Path

import numpy as np
import pytest

from jeanscv_cli.extras import _covers, add_captions, caption_fits, caption_text, find_font, fit_caption, wide_font


def test_latin_captions_keep_the_bold_sans_font():
    assert caption_text("how would a dog wear jeans?") == ("HOW WOULD A DOG WEAR JEANS?", find_font())


@pytest.mark.skipif(wide_font() is None, reason="cvttf-notosanscjk-bold is not installed")
@pytest.mark.parametrize("text", ["狗怎麼穿牛仔褲", "犬はジーンズ", "개는 청바지", "Как собака 狗", "Πως θα 狗"])
def test_every_script_is_drawn_by_a_font_that_has_it(text):
    drawn, font = caption_text(text)
    assert drawn == text.upper() and font == wide_font()
    assert all(_covers(font, char) for char in drawn)
    assert not all(_covers(find_font(), char) for char in drawn)  # the bold sans font alone would draw boxes


@pytest.mark.skipif(wide_font() is None, reason="cvttf-notosanscjk-bold is not installed")
def test_a_letter_the_font_lacks_is_drawn_from_its_parts():
    """Noto Sans CJK has no precomposed Greek with tonos: Ώ is drawn as Ω and its accent."""
    drawn, font = caption_text("Πώς 狗")
    assert font == wide_font() and not _covers(font, "Ώ")
    assert drawn == "ΠΏΣ 狗" and all(_covers(font, part) for part in unicodedata.normalize("NFD", drawn))


def test_an_emoji_is_named_not_drawn_as_a_box():
    drawn, font = caption_text("dog 🐶 👍🏽 jeans")
    assert drawn == "DOG [DOG FACE] [THUMBS UP SIGN] JEANS"  # the skin tone goes with its emoji
    assert all(_covers(font, char) for char in drawn)


def test_a_caption_in_another_script_is_ink_where_its_box_would_be_another():
    """The CJK caption's letters are not the font's missing-glyph boxes: the picture
    differs from the one the same font draws for characters it lacks."""
    image = np.full((200, 320, 3), 90, np.uint8)
    cjk = add_captions(image, "狗狗", None)
    boxes = add_captions(image, "\U0010ffff\U0010ffff", None)
    assert (np.abs(cjk.astype(int) - image).max(axis=-1) > 60).sum() > 200
    assert not np.array_equal(cjk, boxes)


# ------------------------------------------------------------------ long captions fitted

#: DejaVu Sans Bold, the font these exact layouts were measured with (the bold sans font
#: of most Linux systems; matplotlib ships a copy).
DEJAVU = next(
    (
        path
        for path in (
            Path("/usr/share/fonts/truetype/dejavu/DejaVuSans-Bold.ttf"),
            Path("/usr/share/fonts/TTF/DejaVuSans-Bold.ttf"),
            Path("/usr/share/fonts/dejavu/DejaVuSans-Bold.ttf"),
        )
        if path.is_file()
    ),
    None,
)
needs_dejavu = pytest.mark.skipif(DEJAVU is None, reason="DejaVu Sans Bold is not installed")

LONG = (
    "when you finally find the perfect pair of jeans but then you realise the dog has been"
    " wearing them all along and honestly they look better on him than they ever did on you"
)


def _fits_the_picture(fit, width: int, height: int) -> bool:
    """Every line within 94% of the width, and all of them within a third of the height."""
    widest = max(fit.font.getlength(line) + 2 * fit.stroke for line in fit.lines)
    return widest <= 0.94 * width and len(fit.lines) * fit.line_height <= height / 3


@needs_dejavu
def test_a_short_caption_keeps_its_one_big_line():
    fit = fit_caption("how would a dog", 800, 500, DEJAVU)
    assert (fit.size, fit.stroke, fit.lines, fit.cut) == (62, 4, ("HOW WOULD A DOG",), False)


@needs_dejavu
def test_a_long_caption_is_wrapped_to_more_lines_not_cut():
    """Issue 49: 171 letters on an 800x500 picture were cut to three lines ending in
    "…"; now they take a fourth line at 1/24 of the height (20 px), nothing cut."""
    fit = fit_caption(LONG, 800, 500, DEJAVU)
    assert fit.size == 20 and not fit.cut
    assert fit.lines == (
        "WHEN YOU FINALLY FIND THE PERFECT PAIR OF JEANS BUT THEN",
        "YOU REALISE THE DOG HAS BEEN WEARING THEM ALL ALONG AND",
        "HONESTLY THEY LOOK BETTER ON HIM THAN THEY EVER DID ON",
        "YOU",
    )
    assert _fits_the_picture(fit, 800, 500)
    assert fit.summary() == {"lines": 4, "size": 20, "cut": False}


@needs_dejavu
def test_a_longer_caption_also_takes_a_smaller_size():
    """Twice as long: six lines at 18 px (the largest size at which they stay in a third
    of the height); on a 400x300 picture the first text takes 12 px, four lines."""
    fit = fit_caption(LONG + " " + LONG, 800, 500, DEJAVU)
    assert (fit.size, len(fit.lines), fit.cut) == (18, 6, False)
    assert " ".join(fit.lines) == (LONG + " " + LONG).upper() and _fits_the_picture(fit, 800, 500)
    small = fit_caption(LONG, 400, 300, DEJAVU)
    assert (small.size, small.cut) == (12, False)
    assert small.lines == (
        "WHEN YOU FINALLY FIND THE PERFECT PAIR OF JEANS",
        "BUT THEN YOU REALISE THE DOG HAS BEEN WEARING",
        "THEM ALL ALONG AND HONESTLY THEY LOOK BETTER",
        "ON HIM THAN THEY EVER DID ON YOU",
    )


@needs_dejavu
def test_a_caption_too_long_even_at_the_floor_is_cut_as_before_and_says_so():
    """On a 160x100 picture the floor is 8 px: the text does not fit a third of the
    height there, so it is cut as it always was (three lines, an ellipsis) and ``cut``."""
    fit = fit_caption(LONG, 160, 100, DEJAVU)
    assert (fit.size, fit.cut) == (8, True)
    assert fit.lines == ("WHEN YOU FINALLY", "FIND THE PERFECT", "PAIR OF JEANS BU\u2026")
    assert fit.summary() == {"lines": 3, "size": 8, "cut": True}


@pytest.mark.skipif(wide_font() is None, reason="cvttf-notosanscjk-bold is not installed")
def test_a_long_cjk_caption_is_broken_between_its_characters():
    """Chinese has no spaces to wrap at: 70 characters at 400x300 go on three lines of
    Noto Sans CJK at 12 px, broken between characters, none lost, all inside the picture
    (before: 34 a line, counted in W's, and a CJK letter is wider: they ran off its sides)."""
    drawn, font = caption_text("狗怎麼穿牛仔褲" * 10)
    fit = fit_caption(drawn, 400, 300, font)
    assert (fit.size, fit.cut, fit.font_path) == (12, False, wide_font())
    assert [len(line) for line in fit.lines] == [31, 31, 8] and "".join(fit.lines) == drawn
    assert _fits_the_picture(fit, 400, 300)


@needs_dejavu
def test_an_accent_stays_with_its_letter_when_a_word_is_broken():
    """A word wider than the picture is broken between letters, never between a letter
    and its combining accent (Noto's Greek tonos is drawn as one)."""
    word = "ΣΚΥ\u0301ΛΟΣ" * 6
    fit = fit_caption(" ".join([word] * 3), 120, 400, DEJAVU)
    assert not fit.cut and len(fit.lines) > 3
    assert not any(unicodedata.category(line[0]).startswith("M") for line in fit.lines)
    assert "".join(fit.lines).replace(" ", "") == (word * 3).upper()


@needs_dejavu
def test_add_captions_draws_the_fitted_lines(monkeypatch):
    """The picture holds the fitted lines: four bands of letters for the long caption
    (three, cut, before), along the top."""
    monkeypatch.setenv("JEANSCV_FONT", str(DEJAVU))
    image = np.full((500, 800, 3), 90, np.uint8)
    drawn = np.abs(add_captions(image, LONG, None).astype(int) - image).max(axis=-1) > 60
    rows = drawn.any(axis=1)
    bands = np.flatnonzero(rows[1:] & ~rows[:-1]).size + int(rows[0])
    assert bands == 4 and not rows[250:].any()
    assert caption_fits(800, 500, LONG, "wear jeans?")["top"] == fit_caption(LONG.upper(), 800, 500, DEJAVU)
