"""Derived columns of the trajectory table, computed vectorised over the whole table.

``Preceding`` / ``Following``: the vehicle directly ahead / behind in the same lane and frame
(by ``Local_Y``), 0 when none. ``Space_Headway`` = Local_Y(preceding) - Local_Y (ft,
front-to-front, as NGSIM), ``Time_Headway`` = Space_Headway / v_Vel (s), 9999.99 when the
vehicle stands still (NGSIM's convention); both 0 when there is no preceding vehicle.
``Total_Frames``: number of rows of the vehicle.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from sim.schema import COLUMNS, sort_table

#: Time_Headway of a vehicle at (almost) zero speed, as in NGSIM.
STANDSTILL_TIME_HEADWAY = 9999.99
_MIN_SPEED_FT_S = 1e-3


def neighbours(frame: np.ndarray, lane: np.ndarray, local_y: np.ndarray, vehicle: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Preceding and following Vehicle_ID of every row (0 when none).

    Args: frame, lane, vehicle: int64[N]; local_y: float64[N].
    Returns: (preceding, following), int64[N] each, aligned with the inputs.
    """
    n = frame.shape[0]
    order = np.lexsort((local_y, lane, frame))  # by frame, then lane, then Local_Y ascending
    f, la, v = frame[order], lane[order], vehicle[order]
    same_next = np.zeros(n, dtype=bool)
    if n > 1:
        same_next[:-1] = (f[1:] == f[:-1]) & (la[1:] == la[:-1])
    prec_sorted = np.zeros(n, dtype=np.int64)
    prec_sorted[:-1][same_next[:-1]] = v[1:][same_next[:-1]]
    foll_sorted = np.zeros(n, dtype=np.int64)
    foll_sorted[1:][same_next[:-1]] = v[:-1][same_next[:-1]]
    preceding = np.empty(n, dtype=np.int64)
    following = np.empty(n, dtype=np.int64)
    preceding[order] = prec_sorted
    following[order] = foll_sorted
    return preceding, following


def add_derived_columns(table: pd.DataFrame) -> pd.DataFrame:
    """Fill Total_Frames, Preceding, Following, Space_Headway, Time_Headway; sort NGSIM-style.

    ``table`` needs Vehicle_ID, Frame_ID, Lane_ID, Local_Y, v_Vel. Returns a new table with
    all schema columns in schema order, sorted by (Vehicle_ID, Frame_ID).
    """
    vid = table["Vehicle_ID"].to_numpy(np.int64)
    frame = table["Frame_ID"].to_numpy(np.int64)
    lane = table["Lane_ID"].to_numpy(np.int64)
    y = table["Local_Y"].to_numpy(np.float64)
    vel = table["v_Vel"].to_numpy(np.float64)
    prec, foll = neighbours(frame, lane, y, vid)
    out = table.copy()
    out["Preceding"] = prec
    out["Following"] = foll
    # Local_Y of the preceding vehicle in the same frame: look it up by (vehicle, frame) key.
    space = np.zeros(len(vid))
    has = prec != 0
    if has.any():
        key_all = pd.MultiIndex.from_arrays([vid, frame])
        pos = key_all.get_indexer(pd.MultiIndex.from_arrays([prec[has], frame[has]]))
        space[has] = y[pos] - y[has]
    out["Space_Headway"] = space
    th = np.zeros(len(vid))
    moving = has & (vel > _MIN_SPEED_FT_S)
    th[moving] = space[moving] / vel[moving]
    th[has & ~moving] = STANDSTILL_TIME_HEADWAY
    out["Time_Headway"] = th
    counts = np.bincount(vid, minlength=int(vid.max(initial=0)) + 1) if len(vid) else np.zeros(1, np.int64)
    out["Total_Frames"] = counts[vid].astype(np.int64)
    out = out.loc[:, list(COLUMNS)].astype(COLUMNS)
    return sort_table(out)
