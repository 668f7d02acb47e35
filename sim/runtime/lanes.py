"""Lanes of a run: SUMO lanes -> I-80 lane numbers (by lateral position), the lanes' centre
polylines, and where the auxiliary lane starts."""

from __future__ import annotations

import numpy as np

from merge_irl.units import FT_PER_M
from scenarios.spec.model import ScenarioSpec
from sim.runtime.hooks import RunContext
from sim.runtime.sites import I80, SiteProfile


def lane_numbers(local_x_ft: np.ndarray, n_main: int, lane_width_ft: float, site: SiteProfile = I80) -> np.ndarray:
    """Lane codes of ``site`` (int64[V]; I-80 numbers by default) of lateral positions from the
    left road edge (float64[V], ft; any unit works if ``lane_width_ft`` is in the same one).

    Lane k (0-based from the left) covers ``[k w, (k + 1) w)`` and gets the k-th of the site's
    last ``n_main`` main lanes; positions left of the road go to the leftmost of them, positions
    right of the main lanes to the site's (first) ramp lane (I-80: main lanes 7 - n .. 6, ramp
    and auxiliary lane 7).

    Raises:
        ValueError: the site has fewer than ``n_main`` main lanes.
    """
    return LaneNumbering(n_main, lane_width_ft, site)(local_x_ft)


class LaneNumbering:
    """:func:`lane_numbers` for one road, as one ``searchsorted`` and one lookup per frame."""

    def __init__(self, n_main: int, lane_width_ft: float, site: SiteProfile = I80):
        if n_main > len(site.main_lanes):
            raise ValueError(f"a road of {n_main} main lanes does not fit site {site.describe()}")
        self.edges = lane_width_ft * np.arange(1, n_main + 1, dtype=np.float64)
        self.numbers = np.array([*site.main_lanes[len(site.main_lanes) - n_main:], site.ramp_lanes[0]],
                                dtype=np.int64)

    def __call__(self, local_x_ft: np.ndarray) -> np.ndarray:
        return self.numbers[np.searchsorted(self.edges, local_x_ft, side="right")]


def lane_tables(ls, spec: ScenarioSpec, site: SiteProfile = I80) -> tuple[dict[str, int], dict[str, np.ndarray]]:
    """SUMO lane id -> the site's lane code, and lane code (str) -> centre polyline float64[P, 2] ft."""
    n, w = spec.road.main_lanes, spec.road.lane_width_m
    lane_map: dict[str, int] = {}
    pieces: dict[int, list[np.ndarray]] = {}
    for lid in ls.lane.getIDList():
        shape = np.asarray(ls.lane.getShape(lid), dtype=np.float64)
        num = int(lane_numbers(np.array([-shape[:, 1].mean()]), n, w, site)[0])  # metres here
        lane_map[lid] = num
        if not lid.startswith(":"):
            pieces.setdefault(num, []).append(shape)
    shapes = {}
    for num, parts in pieces.items():
        pts = np.concatenate(sorted(parts, key=lambda p: p[0, 0]))
        shapes[str(num)] = pts * FT_PER_M
    return lane_map, shapes


def aux_lane_start_ft(ctx: RunContext) -> float:
    """``Local_Y`` (ft) where the ramp lane (I-80: 7) first runs beside the merge lane (I-80: 6),
    the auxiliary lane's start; lanes of the run's site profile (``ctx.site``).

    Taken from the lane shapes: the first point of the ramp lane whose distance to the merge
    lane's polyline is at most 1.5 lane widths. Local_Y is measured from the first point of the
    merge lane along +x.
    """
    l6 = np.asarray(ctx.lane_shapes[str(ctx.site.merge_lane)], dtype=np.float64)
    l7 = np.asarray(ctx.lane_shapes[str(ctx.site.ramp_lanes[0])], dtype=np.float64)
    x0 = float(l6[0, 0])
    # lateral distance of each lane-7 point to lane 6 (interpolated in x; the main road runs along +x)
    y6 = np.interp(l7[:, 0], l6[:, 0], l6[:, 1], left=np.nan, right=np.nan)
    close = np.flatnonzero(np.abs(l7[:, 1] - y6) <= 1.5 * ctx.lane_width_ft)
    if close.size == 0:
        return 0.0
    return float(l7[close[0], 0] - x0)
