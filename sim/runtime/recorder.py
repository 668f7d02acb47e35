"""Accumulates recorded frames as numpy blocks and builds the trajectory table once at the end."""

from __future__ import annotations

import numpy as np
import pandas as pd

from sim.runtime.schema import empty_table
from sim.runtime.table import table_from_columns


class TrajectoryRecorder:
    """Collects one block of rows per recorded frame; ``table()`` builds the NGSIM table.

    A frame's block is what the runner already holds for its hooks, kept by reference (the
    arrays are read-only and never reused), so recording copies nothing per frame.
    """

    def __init__(self) -> None:
        self._frame: list[int] = []
        self._vid: list[np.ndarray] = []
        self._kin: list[np.ndarray] = []
        self._lane: list[np.ndarray] = []
        self._static: list[np.ndarray] = []
        self.n_rows = 0

    def add(self, frame: int, vehicle_id: np.ndarray, kin: np.ndarray, lane: np.ndarray, static: np.ndarray) -> None:
        """One frame of V vehicles.

        Args:
            frame: Frame_ID.
            vehicle_id: int64[V].
            kin: float64[V, 4], columns SUMO x, SUMO y, speed, acceleration (ft, ft/s, ft/s^2).
            lane: int64[V] I-80 lane numbers.
            static: float64[V, 3], columns length (ft), width (ft), NGSIM v_Class.
        """
        self._frame.append(frame)
        self._vid.append(vehicle_id)
        self._kin.append(kin)
        self._lane.append(lane)
        self._static.append(static)
        self.n_rows += vehicle_id.shape[0]

    @property
    def n_frames(self) -> int:
        return len(self._frame)

    def table(self) -> pd.DataFrame:
        """The trajectory table (NGSIM schema, sorted by Vehicle_ID, Frame_ID)."""
        if self.n_rows == 0:
            return empty_table()
        counts = np.fromiter((v.shape[0] for v in self._vid), dtype=np.int64, count=len(self._vid))
        frame = np.repeat(np.asarray(self._frame, dtype=np.int64), counts)
        kin = np.concatenate(self._kin)
        st = np.concatenate(self._static)
        return table_from_columns({
            "Vehicle_ID": np.concatenate(self._vid),
            "Frame_ID": frame,
            "Global_Time": frame * 100,
            "Local_X": -kin[:, 1],
            "Local_Y": kin[:, 0],
            "Global_X": kin[:, 0],
            "Global_Y": kin[:, 1],
            "v_Length": st[:, 0],
            "v_Width": st[:, 1],
            "v_Class": st[:, 2],
            "v_Vel": kin[:, 2],
            "v_Acc": kin[:, 3],
            "Lane_ID": np.concatenate(self._lane),
        })
