"""Lanes of a run: SUMO lanes -> I-80 lane numbers (by lateral position), the lanes' centre
polylines, and where the auxiliary lane starts."""

from __future__ import annotations

import numpy as np

from scenarios.spec.model import ScenarioSpec
from sim.hooks import RunContext
from sim.schema import FT_PER_M, RAMP_LANE, RIGHTMOST_MAIN_LANE


def lane_numbers(local_x_ft: np.ndarray, n_main: int, lane_width_ft: float) -> np.ndarray:
    """I-80 lane numbers (int64[V]) of lateral positions from the left road edge (float64[V], ft;
    any unit works if ``lane_width_ft`` is in the same one).

    Lane k (0-based from the left) covers ``[k w, (k + 1) w)``; positions left of the road go
    to lane 1, positions right of the main lanes to lane 7 (ramp / auxiliary lane).
    """
    return LaneNumbering(n_main, lane_width_ft)(local_x_ft)


class LaneNumbering:
    """:func:`lane_numbers` for one road, as one ``searchsorted`` and one lookup per frame."""

    def __init__(self, n_main: int, lane_width_ft: float):
        self.edges = lane_width_ft * np.arange(1, n_main + 1, dtype=np.float64)
        self.numbers = np.array([RIGHTMOST_MAIN_LANE - n_main + 1 + k for k in range(n_main)] + [RAMP_LANE],
                                dtype=np.int64)

    def __call__(self, local_x_ft: np.ndarray) -> np.ndarray:
        return self.numbers[np.searchsorted(self.edges, local_x_ft, side="right")]


def lane_tables(ls, spec: ScenarioSpec) -> tuple[dict[str, int], dict[str, np.ndarray]]:
    """SUMO lane id -> I-80 lane number, and I-80 lane (str) -> centre polyline float64[P, 2] ft."""
    n, w = spec.road.main_lanes, spec.road.lane_width_m
    lane_map: dict[str, int] = {}
    pieces: dict[int, list[np.ndarray]] = {}
    for lid in ls.lane.getIDList():
        shape = np.asarray(ls.lane.getShape(lid), dtype=np.float64)
        num = int(lane_numbers(np.array([-shape[:, 1].mean()]), n, w)[0])  # metres here
        lane_map[lid] = num
        if not lid.startswith(":"):
            pieces.setdefault(num, []).append(shape)
    shapes = {}
    for num, parts in pieces.items():
        pts = np.concatenate(sorted(parts, key=lambda p: p[0, 0]))
        shapes[str(num)] = pts * FT_PER_M
    return lane_map, shapes


def aux_lane_start_ft(ctx: RunContext) -> float:
    """``Local_Y`` (ft) where lane 7 first runs beside lane 6 (the auxiliary lane's start).

    Taken from the lane shapes: the first point of lane 7 whose distance to lane 6's polyline
    is at most 1.5 lane widths. Local_Y is measured from the first point of lane 6 along +x.
    """
    l6 = np.asarray(ctx.lane_shapes[str(RIGHTMOST_MAIN_LANE)], dtype=np.float64)
    l7 = np.asarray(ctx.lane_shapes[str(RAMP_LANE)], dtype=np.float64)
    x0 = float(l6[0, 0])
    # lateral distance of each lane-7 point to lane 6 (interpolated in x; the main road runs along +x)
    y6 = np.interp(l7[:, 0], l6[:, 0], l6[:, 1], left=np.nan, right=np.nan)
    close = np.flatnonzero(np.abs(l7[:, 1] - y6) <= 1.5 * ctx.lane_width_ft)
    if close.size == 0:
        return 0.0
    return float(l7[close[0], 0] - x0)
