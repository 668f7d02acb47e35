"""Top-down frames of the merge section for ``render_mode="rgb_array"`` (numpy only, no figure).

:class:`TopDownRenderer` paints the road of a run once (every lane of the run's lane shapes,
asphalt and dashed lane edges) and then each frame's vehicles on a copy: A red, B orange,
C blue, every other car grey (trucks darker). The direction of travel is to the right, the
leftmost lane at the top and the ramp at the bottom; the lateral axis is stretched
(``lateral_scale``) so that cars stay visible on a section a kilometre long.
An environment builds its renderer only when ``render()`` is first called, so an environment
without ``render_mode`` pays nothing for it.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from sim.runtime.hooks import FrameState, RunContext

#: RGB colours of the frame (uint8).
COLOURS = {
    "grass": (34, 60, 34), "asphalt": (70, 70, 74), "marking": (225, 225, 225),
    "A": (230, 40, 40), "B": (255, 150, 20), "C": (60, 120, 255), "other": (185, 185, 185), "truck": (120, 120, 120),
}
_TRUCK_CLASS = 3


class TopDownRenderer:
    """Frames ``uint8[height, width, 3]`` of the section of run ``ctx``.

    Args:
        ctx: the run (its ``lane_shapes`` in ft, ``lane_width_ft``).
        width, height: the frame's size in pixels.
        lateral_scale: how much more a foot counts across the road than along it (>= 1).
    """

    def __init__(self, ctx: RunContext, *, width: int = 960, height: int = 160, lateral_scale: float = 6.0):
        self.width, self.height = int(width), int(height)
        shapes = [np.asarray(s, dtype=np.float64) for s in ctx.lane_shapes.values()]
        half = float(ctx.lane_width_ft) / 2.0
        xs = np.concatenate([s[:, 0] for s in shapes])
        ys = np.concatenate([s[:, 1] for s in shapes])
        self.x0 = float(xs.min())
        self.sx = (self.width - 1) / max(float(xs.max()) - self.x0, 1.0)  # px per ft along the road
        y_mid = (float(ys.max()) + float(ys.min())) / 2.0
        span = float(ys.max()) - float(ys.min()) + 4 * half
        self.sy = min(self.sx * lateral_scale, (self.height - 1) / max(span, 1.0))  # px per ft across
        self.y_top = y_mid + (self.height - 1) / (2.0 * self.sy)  # global_y at row 0
        self.background = self._road(shapes, half)

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
            r0 = np.clip(top.round().astype(int), 0, self.height - 1)
            r1 = np.clip(bot.round().astype(int), 0, self.height - 1)
            for ci, a, b in zip(c, r0, r1):
                img[a:b + 1, ci] = COLOURS["asphalt"]
            dashed = (t // 10.0) % 2 == 0  # 10 ft dashes
            img[r0[dashed], c[dashed]] = COLOURS["marking"]
            img[r1[dashed], c[dashed]] = COLOURS["marking"]
        return img

    def frame(self, frame: FrameState, roles: Mapping[int, str] | None = None) -> np.ndarray:
        """The frame's picture: a new ``uint8[height, width, 3]``; ``roles`` maps a row of ``frame``
        to ``"A"``, ``"B"`` or ``"C"`` (the controller's ``role_rows``)."""
        img = self.background.copy()
        if len(frame.sumo_ids) == 0:
            return img
        roles = roles or {}
        x1, yc = self._px(frame.global_x, frame.global_y)
        x0 = x1 - frame.length * self.sx
        hw = np.maximum(frame.width * self.sy / 2.0, 1.0)
        c0 = np.clip(np.floor(x0).astype(int), 0, self.width)
        c1 = np.clip(np.ceil(x1).astype(int), 0, self.width)
        r0 = np.clip(np.floor(yc - hw).astype(int), 0, self.height)
        r1 = np.clip(np.ceil(yc + hw).astype(int), 0, self.height)
        trucks = frame.v_class == _TRUCK_CLASS
        order = sorted(range(len(c0)), key=lambda i: i in roles)  # the roles drawn last, on top
        for i in order:
            key = roles.get(i) or ("truck" if trucks[i] else "other")
            img[r0[i]:r1[i], c0[i]:c1[i]] = COLOURS[key]
        return img
