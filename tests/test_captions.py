"""Meme captions in any script: the font chosen per caption, and emoji named, never boxes."""

from __future__ import annotations

import unicodedata

import numpy as np
import pytest

from jeanscv_cli.extras import _covers, add_captions, caption_text, find_font, wide_font


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
