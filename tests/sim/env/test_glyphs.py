"""The frames' bitmap font: a string's mask is its glyphs side by side, text is clipped at the
frame's edges, and a character without a glyph is named in the error."""

import numpy as np
import pytest

from sim.env.glyphs import GLYPH_H, GLYPH_W, GLYPHS, draw_text, text_mask


def test_a_string_is_its_glyphs_one_column_apart_and_lower_case_is_upper_case():
    m = text_mask("a1")
    assert m.shape == (GLYPH_H, 2 * GLYPH_W + 1)
    np.testing.assert_array_equal(m[:, :GLYPH_W], GLYPHS["A"])
    np.testing.assert_array_equal(m[:, GLYPH_W + 1:], GLYPHS["1"])
    assert not m[:, GLYPH_W].any()
    assert len({g.tobytes() for g in GLYPHS.values()}) == len(GLYPHS)  # no two glyphs alike


def test_text_is_painted_in_place_and_clipped_at_the_edges():
    img = np.zeros((10, 8, 3), dtype=np.uint8)
    end = draw_text(img, "T 1", 5, 3, (255, 0, 0))
    assert end == 3 + text_mask("T 1").shape[1]
    painted = img[..., 0] == 255
    np.testing.assert_array_equal(painted[5:10, 3:8], GLYPHS["T"][:5])  # cut at the bottom and the right
    assert not painted[:5].any() and not painted[:, :3].any()
    draw_text(img, "8", -20, -20, (0, 255, 0))  # wholly outside: nothing
    assert not img[..., 1].any()


def test_a_character_without_a_glyph_is_named():
    with pytest.raises(KeyError, match=r"no glyph for '\?' in 'T\?'"):
        text_mask("T?")
