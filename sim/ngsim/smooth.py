"""Optional smoothing of NGSIM's noisy kinematics: position -> speed -> acceleration.

NGSIM's ``v_Vel`` / ``v_Acc`` come from differentiating video-tracked positions and are noisy
(accelerations jump between +-11.2 ft/s^2 from frame to frame; see Thiemann, Treiber and
Kesting 2008, "Estimating acceleration and lane-changing dynamics from NGSIM trajectory
data"). The filter here is a Savitzky-Golay filter (least-squares local polynomial of order
``polyorder`` over ``window_frames`` frames, ``scipy.signal.savgol_filter``) applied to each
vehicle's ``Local_Y`` over every run of consecutive frames: the smoothed position, and its first
and second derivatives as ``v_Vel`` (ft/s, clipped at 0) and ``v_Acc`` (ft/s^2). Runs shorter
than the window use the longest odd window that fits (and are left as read when that is not
longer than ``polyorder``). ``Local_X``, global coordinates and headways are unchanged.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from merge_irl.units import FRAME_S


@dataclass(frozen=True)
class SmoothingConfig:
    """Savitzky-Golay filter settings (defaults: 2.1 s window, cubic)."""

    window_frames: int = 21
    polyorder: int = 3

    def __post_init__(self) -> None:
        if self.window_frames < 3 or self.window_frames % 2 == 0:
            raise ValueError(f"window_frames must be odd and >= 3, got {self.window_frames}")
        if not 1 <= self.polyorder < self.window_frames:
            raise ValueError(f"polyorder must be in [1, window_frames), got {self.polyorder}")

    def describe(self) -> str:
        return (f"Savitzky-Golay on Local_Y, window {self.window_frames} frames "
                f"({self.window_frames * FRAME_S:.1f} s), order {self.polyorder}")


def _runs(vehicle: np.ndarray, frame: np.ndarray) -> np.ndarray:
    """int64[R+1] boundaries of runs of consecutive frames of one vehicle (table sorted)."""
    brk = np.flatnonzero((vehicle[1:] != vehicle[:-1]) | (frame[1:] != frame[:-1] + 1)) + 1
    return np.concatenate([[0], brk, [len(vehicle)]])


def smooth_table(table: pd.DataFrame, cfg: SmoothingConfig = SmoothingConfig()) -> pd.DataFrame:
    """Return a copy with ``Local_Y``, ``v_Vel``, ``v_Acc`` recomputed (table sorted by vehicle, frame)."""
    from scipy.signal import savgol_filter  # lazy: scipy.signal costs ~60 MB to import

    out = table.copy()
    y = out["Local_Y"].to_numpy(dtype=np.float64).copy()
    v = out["v_Vel"].to_numpy(dtype=np.float64).copy()
    a = out["v_Acc"].to_numpy(dtype=np.float64).copy()
    b = _runs(out["Vehicle_ID"].to_numpy(), out["Frame_ID"].to_numpy())
    for s, e in zip(b[:-1], b[1:]):
        n = e - s
        w = min(cfg.window_frames, n if n % 2 else n - 1)
        if w <= cfg.polyorder:
            continue
        seg = y[s:e].copy()
        y[s:e] = savgol_filter(seg, w, cfg.polyorder, mode="interp")
        v[s:e] = np.maximum(savgol_filter(seg, w, cfg.polyorder, deriv=1, delta=FRAME_S, mode="interp"), 0.0)
        a[s:e] = savgol_filter(seg, w, cfg.polyorder, deriv=2, delta=FRAME_S, mode="interp")
    out["Local_Y"], out["v_Vel"], out["v_Acc"] = y, v, a
    return out


def jerk_rms(table: pd.DataFrame) -> float:
    """RMS of (a[t+1] - a[t]) / 0.1 s over consecutive frames of the same vehicle (ft/s^3)."""
    if len(table) < 2:
        return 0.0
    veh = table["Vehicle_ID"].to_numpy()
    fr = table["Frame_ID"].to_numpy()
    acc = table["v_Acc"].to_numpy(dtype=np.float64)
    ok = (veh[1:] == veh[:-1]) & (fr[1:] == fr[:-1] + 1)
    if not ok.any():
        return 0.0
    j = np.diff(acc)[ok] / FRAME_S
    return float(np.sqrt(np.mean(j * j)))
