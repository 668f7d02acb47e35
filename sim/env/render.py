"""Top-down frames of the merge section for ``render_mode="rgb_array"`` (numpy only, no figure).

:class:`TopDownRenderer` paints the road of a run once (every lane of the run's lane shapes,
asphalt and dashed lane edges) under a header strip (:data:`HEADER_H` rows) holding the legend
(a swatch and a name per colour: "A lag car (agent)" red, "B merging" orange, "C lead" blue,
"other" grey, "truck" darker) and a distance scale bar along the road (the largest of
:data:`SCALE_BAR_M` that fits in :data:`SCALE_BAR_MAX_PX`, labelled in metres); then, on a copy
per frame, the vehicles, a letter A, B or C above each car of a role, and the simulation clock
("T 123.4 S", the frame's ``time_s``) at the header's left. The direction of travel is to the
right, the leftmost lane at the top and the ramp at the bottom; the lateral axis is stretched
(``lateral_scale``) so that cars stay visible on a section a kilometre long (the scale bar
measures along the road only). Text is a 5x7 bitmap font (:mod:`sim.env.glyphs`).
An environment builds its renderer only when ``render()`` is first called, so an environment
without ``render_mode`` pays nothing for it.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from merge_irl.units import FT_PER_M
from sim.env.glyphs import GLYPH_H, draw_text, text_mask
from sim.runtime.hooks import FrameState, RunContext

#: RGB colours of the frame (uint8).
COLOURS = {
    "grass": (34, 60, 34), "asphalt": (70, 70, 74), "marking": (225, 225, 225),
    "A": (230, 40, 40), "B": (255, 150, 20), "C": (60, 120, 255), "other": (185, 185, 185), "truck": (120, 120, 120),
    "header": (16, 16, 20), "text": (255, 255, 255),
}
#: Rows of the header strip (legend, clock, scale bar) above the road.
HEADER_H = GLYPH_H + 4
#: The legend's entries in order: (colour key, name).
LEGEND = (("A", "A lag car (agent)"), ("B", "B merging"), ("C", "C lead"), ("other", "other"), ("truck", "truck"))
#: Scale bar lengths to choose from (m) and the longest bar drawn (px).
SCALE_BAR_M = (10, 20, 50, 100, 200, 500, 1000)
SCALE_BAR_MAX_PX = 140
#: Columns of the header left to the clock.
CLOCK_W = 70
_TRUCK_CLASS = 3


class TopDownRenderer:
    """Frames ``uint8[height, width, 3]`` of the section of run ``ctx``.

    Args:
        ctx: the run (its ``lane_shapes`` in ft, ``lane_width_ft``).
        width, height: the frame's size in pixels (the header strip included; height > 2 * HEADER_H).
        lateral_scale: how much more a foot counts across the road than along it (>= 1).

    Attributes:
        legend_box, clock_box, scale_box: ``(row0, row1, col0, col1)`` of the legend, the clock and
            the scale bar in the header (pixels, ends excluded).
        scale_m: the scale bar's length (m).
        label_boxes: role -> ``(row0, row1, col0, col1)`` of its letter in the last frame drawn.
    """

    def __init__(self, ctx: RunContext, *, width: int = 960, height: int = 160, lateral_scale: float = 6.0):
        self.width, self.height = int(width), int(height)
        road_h = self.height - HEADER_H
        shapes = [np.asarray(s, dtype=np.float64) for s in ctx.lane_shapes.values()]
        half = float(ctx.lane_width_ft) / 2.0
        xs = np.concatenate([s[:, 0] for s in shapes])
        ys = np.concatenate([s[:, 1] for s in shapes])
        self.x0 = float(xs.min())
        self.sx = (self.width - 1) / max(float(xs.max()) - self.x0, 1.0)  # px per ft along the road
        y_mid = (float(ys.max()) + float(ys.min())) / 2.0
        span = float(ys.max()) - float(ys.min()) + 4 * half
        self.sy = min(self.sx * lateral_scale, (road_h - 1) / max(span, 1.0))  # px per ft across
        self.y_top = y_mid + (road_h - 1) / (2.0 * self.sy) + HEADER_H / self.sy  # global_y at row 0
        self.background = self._road(shapes, half)
        self.background[:HEADER_H] = COLOURS["header"]
        self.clock_box = (0, HEADER_H, 0, CLOCK_W)
        self.legend_box = self._legend(self.background, CLOCK_W)
        self.scale_m, self.scale_box = self._scale_bar(self.background)
        self.label_boxes: dict[str, tuple[int, int, int, int]] = {}

    def _px(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return (x - self.x0) * self.sx, (self.y_top - y) * self.sy

    def _road(self, shapes: list[np.ndarray], half: float) -> np.ndarray:
        img = np.empty((self.height, self.width, 3), dtype=np.uint8)
        img[:] = COLOURS["grass"]
        for s in shapes:
            seg = np.hypot(*np.diff(s, axis=0).T)
            along = np.concatenate([[0.0], np.cumsum(seg)])
            t = np.linspace(0.0, along[-1], max(2, int(along[-1] * self.sx * 2)))
            x, y = np.interp(t, along, s[:, 0]), np.interp(t, along, s[:, 1])
            col, top = self._px(x, y + half)
            _, bot = self._px(x, y - half)
            c = np.clip(col.round().astype(int), 0, self.width - 1)
            r0 = np.clip(top.round().astype(int), HEADER_H, self.height - 1)
            r1 = np.clip(bot.round().astype(int), HEADER_H, self.height - 1)
            for ci, a, b in zip(c, r0, r1):
                img[a:b + 1, ci] = COLOURS["asphalt"]
            dashed = (t // 10.0) % 2 == 0  # 10 ft dashes
            img[r0[dashed], c[dashed]] = COLOURS["marking"]
            img[r1[dashed], c[dashed]] = COLOURS["marking"]
        return img

    def _legend(self, img: np.ndarray, col: int) -> tuple[int, int, int, int]:
        """Paints the legend into the header from column ``col``; returns its box."""
        row, start = (HEADER_H - GLYPH_H) // 2, col
        for key, name in LEGEND:
            img[row:row + GLYPH_H, col:col + GLYPH_H] = COLOURS[key]
            col = draw_text(img, name, row, col + GLYPH_H + 3, COLOURS["text"]) + 12
        return 0, HEADER_H, start, col - 12

    def _scale_bar(self, img: np.ndarray) -> tuple[int, tuple[int, int, int, int]]:
        """Paints the scale bar at the header's right; returns its length (m) and box."""
        px_per_m = self.sx * FT_PER_M
        fits = [m for m in SCALE_BAR_M if m * px_per_m <= SCALE_BAR_MAX_PX]
        metres = fits[-1] if fits else SCALE_BAR_M[0]
        bar = max(int(round(metres * px_per_m)), 2)
        c1 = self.width - 4
        c0 = c1 - bar
        mid = HEADER_H // 2
        img[mid, c0:c1] = COLOURS["text"]
        img[mid - 2:mid + 3, c0] = COLOURS["text"]
        img[mid - 2:mid + 3, c1 - 1] = COLOURS["text"]
        label = f"{metres} m"
        lc = c0 - 4 - text_mask(label).shape[1]
        draw_text(img, label, (HEADER_H - GLYPH_H) // 2, lc, COLOURS["text"])
        return metres, (0, HEADER_H, lc, c1)

    def _label(self, img: np.ndarray, role: str, r0: int, r1: int, c0: int, c1: int) -> tuple[int, int, int, int]:
        """The letter ``role`` on a dark box just above the car at rows r0..r1, columns c0..c1
        (below it when there is no room above); returns the box."""
        h, w = GLYPH_H + 2, 7
        top = r0 - h - 1 if r0 - h - 1 >= HEADER_H else r1 + 1
        left = min(max((c0 + c1) // 2 - w // 2, 0), self.width - w)
        img[top:top + h, left:left + w] = COLOURS["header"]
        draw_text(img, role, top + 1, left + 1, COLOURS["text"])
        return top, min(top + h, self.height), left, left + w

    def frame(self, frame: FrameState, roles: Mapping[int, str] | None = None) -> np.ndarray:
        """The frame's picture: a new ``uint8[height, width, 3]``, with the clock of ``frame.time_s``
        and a letter above each car of a role; ``roles`` maps a row of ``frame`` to ``"A"``, ``"B"``
        or ``"C"`` (the controller's ``role_rows``)."""
        img = self.background.copy()
        self.label_boxes = {}
        draw_text(img, f"t {float(frame.time_s):.1f} s", (HEADER_H - GLYPH_H) // 2, 4, COLOURS["text"])
        if len(frame.sumo_ids) == 0:
            return img
        roles = roles or {}
        x1, yc = self._px(frame.global_x, frame.global_y)
        x0 = x1 - frame.length * self.sx
        hw = np.maximum(frame.width * self.sy / 2.0, 1.0)
        c0 = np.clip(np.floor(x0).astype(int), 0, self.width)
        c1 = np.clip(np.ceil(x1).astype(int), 0, self.width)
        r0 = np.clip(np.floor(yc - hw).astype(int), HEADER_H, self.height)
        r1 = np.clip(np.ceil(yc + hw).astype(int), HEADER_H, self.height)
        trucks = frame.v_class == _TRUCK_CLASS
        order = sorted(range(len(c0)), key=lambda i: i in roles)  # the roles drawn last, on top
        for i in order:
            key = roles.get(i) or ("truck" if trucks[i] else "other")
            img[r0[i]:r1[i], c0[i]:c1[i]] = COLOURS[key]
        self.label_boxes = {}
        for i, role in roles.items():
            if c1[i] > c0[i] and r1[i] > r0[i]:  # in the picture
                self.label_boxes[role] = self._label(img, role, int(r0[i]), int(r1[i]), int(c0[i]), int(c1[i]))
        return img
