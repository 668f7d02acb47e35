"""Derived columns of the trajectory table, computed vectorised over the whole table.

``Preceding`` / ``Following``: the vehicle directly ahead / behind in the same lane and frame
(by ``Local_Y``), 0 when none. ``Space_Headway`` = Local_Y(preceding) - Local_Y (ft,
front-to-front, as NGSIM), ``Time_Headway`` = Space_Headway / v_Vel (s), 9999.99 when the
vehicle stands still (NGSIM's convention); both 0 when there is no preceding vehicle.
``Total_Frames``: number of rows of the vehicle.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pandas as pd

from sim.runtime.schema import COLUMNS

#: Time_Headway of a vehicle at (almost) zero speed, as in NGSIM.
STANDSTILL_TIME_HEADWAY = 9999.99
_MIN_SPEED_FT_S = 1e-3


def _sorted_neighbours(frame: np.ndarray, lane: np.ndarray, local_y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rows ordered by (frame, lane, Local_Y), and whether each sorted row's successor shares its lane and frame.

    Returns: (order int64[N], same_next bool[N]); ``same_next[i]`` says that sorted row i + 1 is the
    vehicle directly ahead of sorted row i.
    """
    n = frame.shape[0]
    order = np.lexsort((local_y, lane, frame))
    f, la = frame[order], lane[order]
    same_next = np.zeros(n, dtype=bool)
    if n > 1:
        same_next[:-1] = (f[1:] == f[:-1]) & (la[1:] == la[:-1])
    return order, same_next


def add_derived_columns(table: pd.DataFrame) -> pd.DataFrame:
    """Fill Total_Frames, Preceding, Following, Space_Headway, Time_Headway; sort NGSIM-style.

    ``table`` needs every schema column except the derived ones. Returns a new table with all
    schema columns in schema order and dtypes, sorted by (Vehicle_ID, Frame_ID).
    """
    return table_from_columns({c: table[c].to_numpy() for c in COLUMNS if c not in DERIVED})


#: Columns computed by :func:`table_from_columns` (any given values are ignored).
DERIVED = ("Total_Frames", "Preceding", "Following", "Space_Headway", "Time_Headway")


def table_from_columns(columns: Mapping[str, np.ndarray]) -> pd.DataFrame:
    """The trajectory table from its measured columns, built in one pass.

    Args:
        columns: every schema column except :data:`DERIVED`, each an array of length N in
            any row order.
    Returns: the table (N rows, schema columns, order and dtypes), sorted by
        (Vehicle_ID, Frame_ID), with the derived columns filled.
    """
    vid = np.asarray(columns["Vehicle_ID"], dtype=np.int64)
    frame = np.asarray(columns["Frame_ID"], dtype=np.int64)
    lane = np.asarray(columns["Lane_ID"], dtype=np.int64)
    y = np.asarray(columns["Local_Y"], dtype=np.float64)
    vel = np.asarray(columns["v_Vel"], dtype=np.float64)
    n = vid.shape[0]
    order, same_next = _sorted_neighbours(frame, lane, y)
    ahead = same_next[:-1] if n else same_next
    v_s, y_s = vid[order], y[order]
    prec = np.zeros(n, dtype=np.int64)
    foll = np.zeros(n, dtype=np.int64)
    space = np.zeros(n, dtype=np.float64)
    if n > 1:
        prec[order[:-1][ahead]] = v_s[1:][ahead]
        foll[order[1:][ahead]] = v_s[:-1][ahead]
        # front-to-front spacing to the vehicle ahead: its Local_Y minus ours
        space[order[:-1][ahead]] = (y_s[1:] - y_s[:-1])[ahead]
    has = prec != 0
    th = np.zeros(n, dtype=np.float64)
    moving = has & (vel > _MIN_SPEED_FT_S)
    th[moving] = space[moving] / vel[moving]
    th[has & ~moving] = STANDSTILL_TIME_HEADWAY
    counts = np.bincount(vid, minlength=int(vid.max(initial=0)) + 1) if n else np.zeros(1, np.int64)
    derived = {"Preceding": prec, "Following": foll, "Space_Headway": space, "Time_Headway": th,
               "Total_Frames": counts[vid]}
    final = np.lexsort((frame, vid))  # stable: NGSIM's (Vehicle_ID, Frame_ID) file order
    out = {}
    for c, dtype in COLUMNS.items():
        col = derived[c] if c in derived else np.asarray(columns[c])
        out[c] = np.asarray(col[final], dtype=dtype)
    return pd.DataFrame(out, copy=False)
