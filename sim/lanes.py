"""Lanes of a run: where the auxiliary lane starts, from the run's lane shapes."""

from __future__ import annotations

import numpy as np

from sim.hooks import RunContext
from sim.schema import RAMP_LANE, RIGHTMOST_MAIN_LANE


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
