"""Accumulates recorded frames as numpy chunks and builds the trajectory table once at the end."""

from __future__ import annotations

import numpy as np
import pandas as pd

from sim.hooks import FrameState
from sim.schema import empty_table
from sim.table import add_derived_columns


class TrajectoryRecorder:
    """Collects one :class:`FrameState` per recorded frame; ``table()`` builds the NGSIM table."""

    _FIELDS = ("vehicle_id", "local_x", "local_y", "global_x", "global_y", "speed", "acc",
               "length", "width", "lane_id", "v_class")

    def __init__(self) -> None:
        self._chunks: dict[str, list[np.ndarray]] = {f: [] for f in self._FIELDS}
        self._frames: list[np.ndarray] = []
        self.n_rows = 0
        self.n_frames = 0

    def add(self, fs: FrameState) -> None:
        for f in self._FIELDS:
            self._chunks[f].append(getattr(fs, f))
        self._frames.append(np.full(fs.vehicle_id.shape[0], fs.frame, dtype=np.int64))
        self.n_rows += fs.vehicle_id.shape[0]
        self.n_frames += 1

    def table(self) -> pd.DataFrame:
        """The trajectory table (NGSIM schema, sorted by Vehicle_ID, Frame_ID)."""
        if self.n_rows == 0:
            return empty_table()
        cat = {f: np.concatenate(c) for f, c in self._chunks.items()}
        frame = np.concatenate(self._frames)
        raw = pd.DataFrame({
            "Vehicle_ID": cat["vehicle_id"],
            "Frame_ID": frame,
            "Total_Frames": 0,
            "Global_Time": frame * 100,
            "Local_X": cat["local_x"],
            "Local_Y": cat["local_y"],
            "Global_X": cat["global_x"],
            "Global_Y": cat["global_y"],
            "v_Length": cat["length"],
            "v_Width": cat["width"],
            "v_Class": cat["v_class"],
            "v_Vel": cat["speed"],
            "v_Acc": cat["acc"],
            "Lane_ID": cat["lane_id"],
            "Preceding": 0,
            "Following": 0,
            "Space_Headway": 0.0,
            "Time_Headway": 0.0,
        })
        return add_derived_columns(raw)
