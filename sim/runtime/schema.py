"""The trajectory table: NGSIM's vehicle-trajectory schema, shared by simulated and real data.

One row per vehicle per frame. Units are NGSIM's: feet, ft/s, ft/s^2, frames of 0.1 s,
``Global_Time`` in milliseconds. Lanes are numbered as on I-80: 1 is the leftmost (HOV) lane,
6 the rightmost main lane, 7 the on-ramp / auxiliary lane. ``Local_Y`` runs along the road,
``Local_X`` across it. ``Preceding`` / ``Following`` are vehicle ids in the same lane, 0 when
there is none; ``Space_Headway`` (ft, front-to-front) and ``Time_Headway`` (s) are 0 when there
is no preceding vehicle, as in NGSIM.
"""

from __future__ import annotations

import pandas as pd

#: Column order and numpy dtype of every column of the trajectory table.
COLUMNS: dict[str, str] = {
    "Vehicle_ID": "int64",
    "Frame_ID": "int64",
    "Total_Frames": "int64",
    "Global_Time": "int64",
    "Local_X": "float64",
    "Local_Y": "float64",
    "Global_X": "float64",
    "Global_Y": "float64",
    "v_Length": "float64",
    "v_Width": "float64",
    "v_Class": "int64",
    "v_Vel": "float64",
    "v_Acc": "float64",
    "Lane_ID": "int64",
    "Preceding": "int64",
    "Following": "int64",
    "Space_Headway": "float64",
    "Time_Headway": "float64",
}

#: NGSIM vehicle classes.
V_CLASS_MOTORCYCLE = 1
V_CLASS_AUTO = 2
V_CLASS_TRUCK = 3

#: I-80 lane numbering.
RIGHTMOST_MAIN_LANE = 6
RAMP_LANE = 7



def empty_table() -> pd.DataFrame:
    """An empty trajectory table with the right columns and dtypes."""
    return pd.DataFrame({c: pd.Series(dtype=t) for c, t in COLUMNS.items()})


def conform(table: pd.DataFrame) -> pd.DataFrame:
    """Return ``table`` with exactly the schema's columns, in order, cast to the schema dtypes.

    Raises ``KeyError`` naming the missing columns.

    Raises:
        KeyError: the table lacks some of :data:`COLUMNS` (listed in the message).
    """
    missing = [c for c in COLUMNS if c not in table.columns]
    if missing:
        raise KeyError(f"trajectory table is missing columns {missing}")
    return table.loc[:, list(COLUMNS)].astype(COLUMNS).reset_index(drop=True)


def sort_table(table: pd.DataFrame) -> pd.DataFrame:
    """Sort by (Vehicle_ID, Frame_ID), NGSIM's file order."""
    return table.sort_values(["Vehicle_ID", "Frame_ID"], kind="stable").reset_index(drop=True)
