"""Helpers for the NGSIM tests: a synthetic trajectory table in the schema (not a test module)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from sim.runtime.schema import COLUMNS


def synthetic_table(n_vehicles: int = 20, n_frames: int = 60, seed: int = 0) -> pd.DataFrame:
    """A plausible trajectory table: cars ~15 ft long, moving along Local_Y, lanes 1..7."""
    rng = np.random.default_rng(seed)
    parts = []
    for vid in range(1, n_vehicles + 1):
        f0 = int(rng.integers(1, 200))
        fr = np.arange(f0, f0 + n_frames)
        vel = np.clip(30 + np.cumsum(rng.normal(0, 1, n_frames)) * 0.1, 0, None)
        y = np.cumsum(vel) * 0.1 + rng.uniform(0, 500)
        parts.append(pd.DataFrame({
            "Vehicle_ID": vid, "Frame_ID": fr, "Total_Frames": n_frames,
            "Global_Time": 1113433136100 + fr * 100,
            "Local_X": rng.normal(30, 3, n_frames), "Local_Y": y,
            "Global_X": 6042842.1 + rng.normal(0, 1, n_frames), "Global_Y": 2133117.6 + y,
            "v_Length": rng.uniform(13, 40), "v_Width": rng.uniform(5.5, 8.5),
            "v_Class": int(rng.choice([2, 2, 2, 3])), "v_Vel": vel, "v_Acc": rng.normal(0, 3, n_frames),
            "Lane_ID": int(rng.integers(1, 8)), "Preceding": 0, "Following": 0,
            "Space_Headway": rng.uniform(0, 200, n_frames), "Time_Headway": rng.uniform(0, 5, n_frames),
        }))
    return pd.concat(parts).astype(COLUMNS).reset_index(drop=True)


def write_large_ngsim(path, size_mb: float, seed: int = 0) -> int:
    """Write an NGSIM-format CSV of about ``size_mb`` MB with the project's streaming writer
    (vehicles of 1000 frames along Local_Y in lanes 1..7, ~106 bytes a row); returns its rows."""
    from sim.ngsim.write import write_ngsim_csv_blocks

    n_frames, per_block = 1000, 50
    n_vehicles = max(1, int(size_mb * 1e6 / 106 / n_frames))
    rng = np.random.default_rng(seed)

    def blocks():
        for v0 in range(0, n_vehicles, per_block):
            nv = min(per_block, n_vehicles - v0)
            n = nv * n_frames
            step = np.tile(np.arange(n_frames), nv)
            fr = np.repeat(rng.integers(1, 9000, nv), n_frames) + step
            y = np.repeat(rng.uniform(0, 200, nv), n_frames) + step * 3.0
            lane = np.repeat(rng.integers(1, 8, nv), n_frames)
            yield pd.DataFrame({
                "Vehicle_ID": np.repeat(np.arange(v0 + 1, v0 + nv + 1), n_frames), "Frame_ID": fr,
                "Total_Frames": n_frames, "Global_Time": 1113433136100 + fr * 100,
                "Local_X": lane * 12.0 - 6 + rng.normal(0, 1, n), "Local_Y": y,
                "Global_X": 6042842.0 + rng.normal(0, 5, n), "Global_Y": 2133117.0 + y,
                "v_Length": np.repeat(rng.uniform(13, 40, nv), n_frames),
                "v_Width": np.repeat(rng.uniform(5.5, 8.5, nv), n_frames), "v_Class": 2,
                "v_Vel": np.clip(30 + rng.normal(0, 3, n), 0, None), "v_Acc": rng.normal(0, 3, n),
                "Lane_ID": lane, "Preceding": 0, "Following": 0,
                "Space_Headway": rng.uniform(0, 200, n), "Time_Headway": rng.uniform(0, 5, n),
            }).astype(COLUMNS)

    write_ngsim_csv_blocks(blocks(), path)
    return n_vehicles * n_frames
