"""A 5x7 bitmap font of the few characters the rendered frames write (numpy only, no font file).

:func:`text_mask` turns a string into a boolean mask ``bool[7, 6 * len(text) - 1]`` (one blank
column between characters); :func:`draw_text` paints it into a frame. The characters: the digits,
the capitals of the frame's words (:data:`GLYPHS`), space, ``.``, ``:``, ``-``, ``(``, ``)``, ``=``;
lower case is drawn as upper case. Any other character raises ``KeyError``.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

#: Glyph height and width in pixels; one blank column separates two glyphs.
GLYPH_H, GLYPH_W = 7, 5

_ROWS: dict[str, tuple[str, ...]] = {
    '0': ('.###.', '#...#', '#..##', '#.#.#', '##..#', '#...#', '.###.'),
    '1': ('..#..', '.##..', '..#..', '..#..', '..#..', '..#..', '.###.'),
    '2': ('.###.', '#...#', '....#', '...#.', '..#..', '.#...', '#####'),
    '3': ('####.', '....#', '....#', '.###.', '....#', '....#', '####.'),
    '4': ('...#.', '..##.', '.#.#.', '#..#.', '#####', '...#.', '...#.'),
    '5': ('#####', '#....', '####.', '....#', '....#', '#...#', '.###.'),
    '6': ('..##.', '.#...', '#....', '####.', '#...#', '#...#', '.###.'),
    '7': ('#####', '....#', '...#.', '..#..', '.#...', '.#...', '.#...'),
    '8': ('.###.', '#...#', '#...#', '.###.', '#...#', '#...#', '.###.'),
    '9': ('.###.', '#...#', '#...#', '.####', '....#', '...#.', '.##..'),
    'A': ('.###.', '#...#', '#...#', '#####', '#...#', '#...#', '#...#'),
    'B': ('####.', '#...#', '#...#', '####.', '#...#', '#...#', '####.'),
    'C': ('.###.', '#...#', '#....', '#....', '#....', '#...#', '.###.'),
    'D': ('####.', '#...#', '#...#', '#...#', '#...#', '#...#', '####.'),
    'E': ('#####', '#....', '#....', '####.', '#....', '#....', '#####'),
    'G': ('.###.', '#...#', '#....', '#.###', '#...#', '#...#', '.####'),
    'H': ('#...#', '#...#', '#...#', '#####', '#...#', '#...#', '#...#'),
    'I': ('.###.', '..#..', '..#..', '..#..', '..#..', '..#..', '.###.'),
    'K': ('#...#', '#..#.', '#.#..', '##...', '#.#..', '#..#.', '#...#'),
    'L': ('#....', '#....', '#....', '#....', '#....', '#....', '#####'),
    'M': ('#...#', '##.##', '#.#.#', '#.#.#', '#...#', '#...#', '#...#'),
    'N': ('#...#', '##..#', '#.#.#', '#..##', '#...#', '#...#', '#...#'),
    'O': ('.###.', '#...#', '#...#', '#...#', '#...#', '#...#', '.###.'),
    'R': ('####.', '#...#', '#...#', '####.', '#.#..', '#..#.', '#...#'),
    'S': ('.####', '#....', '#....', '.###.', '....#', '....#', '####.'),
    'T': ('#####', '..#..', '..#..', '..#..', '..#..', '..#..', '..#..'),
    'U': ('#...#', '#...#', '#...#', '#...#', '#...#', '#...#', '.###.'),
    'V': ('#...#', '#...#', '#...#', '#...#', '#...#', '.#.#.', '..#..'),
    ' ': ('.....', '.....', '.....', '.....', '.....', '.....', '.....'),
    '.': ('.....', '.....', '.....', '.....', '.....', '..##.', '..##.'),
    ':': ('.....', '..##.', '..##.', '.....', '..##.', '..##.', '.....'),
    '-': ('.....', '.....', '.....', '#####', '.....', '.....', '.....'),
    '=': ('.....', '.....', '#####', '.....', '#####', '.....', '.....'),
    '(': ('...#.', '..#..', '.#...', '.#...', '.#...', '..#..', '...#.'),
    ')': ('.#...', '..#..', '...#.', '...#.', '...#.', '..#..', '.#...'),
}

#: Character -> ``bool[7, 5]``.
GLYPHS: dict[str, np.ndarray] = {
    k: np.array([[c == "#" for c in row] for row in rows], dtype=bool) for k, rows in _ROWS.items()}


@lru_cache(maxsize=512)
def text_mask(text: str) -> np.ndarray:
    """``bool[7, 6 * len(text) - 1]``: the pixels of ``text`` (read-only, cached).

    Raises:
        KeyError: a character with no glyph (the message names it).
    """
    if not text:
        return np.zeros((GLYPH_H, 0), dtype=bool)
    out = np.zeros((GLYPH_H, (GLYPH_W + 1) * len(text) - 1), dtype=bool)
    for i, ch in enumerate(text.upper()):
        if ch not in GLYPHS:
            raise KeyError(f"no glyph for {ch!r} in {text!r}; the font has {''.join(sorted(GLYPHS))!r}")
        out[:, i * (GLYPH_W + 1):i * (GLYPH_W + 1) + GLYPH_W] = GLYPHS[ch]
    out.flags.writeable = False
    return out


def draw_text(img: np.ndarray, text: str, row: int, col: int, colour: tuple[int, int, int]) -> int:
    """Paint ``text`` into ``img`` (``uint8[H, W, 3]``, in place) with its top-left corner at
    ``(row, col)``, clipped at the frame's edges; returns the column after the text (px)."""
    mask = text_mask(text)
    h, w = mask.shape
    r0, c0 = max(row, 0), max(col, 0)
    r1, c1 = min(row + h, img.shape[0]), min(col + w, img.shape[1])
    if r1 > r0 and c1 > c0:
        sub = mask[r0 - row:r1 - row, c0 - col:c1 - col]
        img[r0:r1, c0:c1][sub] = colour
    return col + w
