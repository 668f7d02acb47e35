"""Merge encounters (merging car B, lag car A, lead car C) from any NGSIM-schema trajectory table.

Definitions (the paper's section 4.2; feet, ft/s, ft/s^2; positions are NGSIM's front bumper):

* **B** is a vehicle with a row in lane 7 (ramp / auxiliary lane) followed later by a row in
  lane 6 (the rightmost main lane). Its **merge frame** is its first lane-6 frame after its
  first lane-7 frame. Nothing in between is required: a vehicle that goes from a junction-
  internal lane straight into lane 6, or whose last lane-7 row is far back, still counts.
* At the merge frame, **A** (lag) is the lane-6 vehicle with the largest ``Local_Y`` below B's
  and **C** (lead) the lane-6 vehicle with the smallest ``Local_Y`` above B's (by position, not
  by ``Preceding`` / ``Following``). A and C keep their roles over the whole window.
* Per frame: ``d_AC = Local_Y(C) - Local_Y(A)``, ``d_AB = Local_Y(B) - Local_Y(A)`` (negative
  while B is still behind A), ``v_AC = v_Vel(A) - v_Vel(C)``, ``v_AB = v_Vel(A) - v_Vel(B)``
  (positive when A is faster, i.e. closing in), ``B_is_truck`` (B's v_Class is 3) and the
  action ``acc_A = (v_Vel(A, t+1) - v_Vel(A, t)) / 0.1 s``: the forward difference, the
  acceleration A applies in frame t (``v_Acc`` is the backward difference that led to frame t
  and is not used). The next frame may lie beyond the window: A's row at t+1 is taken from the
  table wherever it is. A frame whose t+1 row of A is not in the table has no action and no
  row. The columns, dtypes and units are :data:`irl.domains.merge.ENCOUNTER_SCHEMA`.
* **Window** (:class:`EncounterWindow`): from the first frame in which A and B are both in the
  table (both in the section), or at most ``max_frames_before`` frames before the merge, until
  ``frames_after`` frames after the merge frame (0: the merge frame is the last row). Frames in
  which A or B is missing, or A has no row at t+1, are skipped.
* **Missing neighbours**: every B gets one row in the merges summary (``merges``), with
  ``A_id = 0`` when no lane-6 vehicle is behind it at the merge frame and ``C_id = 0`` when
  none is ahead. Without A there is no per-frame row (A is the driver being modelled). Without C
  (or in frames where C is not in the table) ``d_AC`` and ``v_AC`` are NaN: the no-lead-car
  rule of :mod:`irl.domains.merge`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from irl.domains.merge import ENCOUNTER_COLUMNS, forward_acceleration
from sim.errors import TrajectoryFormatError
from sim.observe import lag_lead_positions
from sim.schema import FRAME_S, RAMP_LANE, RIGHTMOST_MAIN_LANE, V_CLASS_TRUCK

#: Columns of the per-merge summary table, in order.
MERGE_COLUMNS: dict[str, str] = {
    "encounter_id": "int64", "B_id": "int64", "A_id": "int64", "C_id": "int64",
    "merge_frame": "int64", "Global_Time": "int64", "B_is_truck": "bool",
    "first_frame": "int64", "n_frames": "int64",
}

_NEEDED = ("Vehicle_ID", "Frame_ID", "Global_Time", "Local_Y", "v_Vel", "v_Class", "Lane_ID")


@dataclass(frozen=True)
class EncounterWindow:
    """Which frames of an encounter are kept (see the module docstring).

    Attributes:
        max_frames_before: at most this many frames before the merge frame (None: no limit,
            the window starts when A and B are both in the section).
        frames_after: frames kept after the merge frame (0: stop at the merge frame).
    """

    max_frames_before: int | None = None
    frames_after: int = 0

    def __post_init__(self) -> None:
        if self.max_frames_before is not None and self.max_frames_before < 0:
            raise ValueError(f"EncounterWindow.max_frames_before must be >= 0, got {self.max_frames_before}")
        if self.frames_after < 0:
            raise ValueError(f"EncounterWindow.frames_after must be >= 0, got {self.frames_after}")


@dataclass(frozen=True)
class Encounters:
    """``frames``: one row per encounter frame (ENCOUNTER_COLUMNS); ``merges``: one row per B."""

    frames: pd.DataFrame
    merges: pd.DataFrame


def _empty(cols: dict[str, str]) -> pd.DataFrame:
    return pd.DataFrame({c: pd.Series(dtype=t) for c, t in cols.items()})


def _check(table: pd.DataFrame) -> None:
    missing = [c for c in _NEEDED if c not in table.columns]
    if missing:
        raise TrajectoryFormatError(f"trajectory table: missing columns {missing} needed for merge encounters")


def find_merges(table: pd.DataFrame) -> pd.DataFrame:
    """One row per merging vehicle B: ``B_id, merge_frame`` (int64), sorted by merge frame, B."""
    _check(table)
    vid = table["Vehicle_ID"].to_numpy(np.int64)
    frame = table["Frame_ID"].to_numpy(np.int64)
    lane = table["Lane_ID"].to_numpy(np.int64)
    on7 = lane == RAMP_LANE
    if not on7.any():
        return pd.DataFrame({"B_id": pd.Series(dtype="int64"), "merge_frame": pd.Series(dtype="int64")})
    first7 = pd.Series(frame[on7]).groupby(vid[on7]).min()
    f7 = first7.reindex(vid).to_numpy()  # NaN for vehicles never in lane 7
    cand = (lane == RIGHTMOST_MAIN_LANE) & ~np.isnan(f7) & (frame > np.nan_to_num(f7, nan=np.inf))
    merge = pd.Series(frame[cand]).groupby(vid[cand]).min()
    out = pd.DataFrame({"B_id": merge.index.to_numpy(np.int64), "merge_frame": merge.to_numpy(np.int64)})
    return out.sort_values(["merge_frame", "B_id"], kind="stable").reset_index(drop=True)


def extract(table: pd.DataFrame, *, window: EncounterWindow = EncounterWindow()) -> Encounters:
    """Every merge of ``table`` with its A and C, and the per-frame encounter variables."""
    _check(table)
    merges = find_merges(table)
    if merges.empty:
        return Encounters(_empty(ENCOUNTER_COLUMNS), _empty(MERGE_COLUMNS))
    vid = table["Vehicle_ID"].to_numpy(np.int64)
    frame = table["Frame_ID"].to_numpy(np.int64)
    lane = table["Lane_ID"].to_numpy(np.int64)
    y = table["Local_Y"].to_numpy(np.float64)
    vel = table["v_Vel"].to_numpy(np.float64)
    vclass = table["v_Class"].to_numpy(np.int64)
    gtime = table["Global_Time"].to_numpy(np.int64)
    row_of = pd.MultiIndex.from_arrays([vid, frame])
    if not row_of.is_unique:
        raise TrajectoryFormatError("trajectory table: duplicate (Vehicle_ID, Frame_ID) rows")
    first_frame = pd.Series(frame).groupby(vid).min()

    # lane-6 rows sorted by (frame, Local_Y): A/C lookups with searchsorted
    r6 = np.flatnonzero(lane == RIGHTMOST_MAIN_LANE)
    r6 = r6[np.lexsort((y[r6], frame[r6]))]
    f6 = frame[r6]

    def rows(v: int, frames: np.ndarray) -> np.ndarray:
        return row_of.get_indexer(pd.MultiIndex.from_arrays([np.full(frames.shape, v, np.int64), frames]))

    summary, chunks = [], []
    for eid, (b, mf) in enumerate(zip(merges["B_id"].to_numpy(), merges["merge_frame"].to_numpy()), start=1):
        rb = rows(b, np.array([mf]))[0]
        lo, hi = np.searchsorted(f6, mf, "left"), np.searchsorted(f6, mf, "right")
        cand = r6[lo:hi]
        cand = cand[vid[cand] != b]
        ia, ic = lag_lead_positions(y[cand].tolist(), float(y[rb]))  # the controller's rule too
        a = int(vid[cand[ia]]) if ia >= 0 else 0
        c = int(vid[cand[ic]]) if ic >= 0 else 0
        truck = bool(vclass[rb] == V_CLASS_TRUCK)
        start = mf
        if a:
            start = int(max(first_frame[a], first_frame[b]))
            if window.max_frames_before is not None:
                start = max(start, int(mf) - window.max_frames_before)
            frames = np.arange(start, mf + window.frames_after + 1, dtype=np.int64)
            ra, rbb, ra_next = rows(a, frames), rows(b, frames), rows(a, frames + 1)
            keep = (ra >= 0) & (rbb >= 0) & (ra_next >= 0)
            frames, ra, rbb, ra_next = frames[keep], ra[keep], rbb[keep], ra_next[keep]
            if c:
                rc = rows(c, frames)
                hc = rc >= 0
                yc = np.where(hc, y[np.where(hc, rc, 0)], np.nan)
                vc = np.where(hc, vel[np.where(hc, rc, 0)], np.nan)
            else:
                yc = vc = np.full(frames.shape, np.nan)
            chunks.append(pd.DataFrame({
                "encounter_id": eid, "B_id": b, "A_id": a, "C_id": c,
                "Frame_ID": frames, "Global_Time": gtime[ra], "merge_frame": mf,
                "d_AC": yc - y[ra], "d_AB": y[rbb] - y[ra],
                "v_AC": vel[ra] - vc, "v_AB": vel[ra] - vel[rbb],
                "B_is_truck": truck, "acc_A": forward_acceleration(vel[ra], vel[ra_next], FRAME_S),
            }))
            n = len(frames)
        else:
            n = 0
        summary.append((eid, b, a, c, mf, gtime[rb], truck, start, n))
    frames_df = pd.concat(chunks, ignore_index=True) if chunks else _empty(ENCOUNTER_COLUMNS)
    frames_df = frames_df.astype(ENCOUNTER_COLUMNS).loc[:, list(ENCOUNTER_COLUMNS)]
    merges_df = pd.DataFrame(summary, columns=list(MERGE_COLUMNS)).astype(MERGE_COLUMNS)
    return Encounters(frames_df, merges_df)


def extract_encounters(table: pd.DataFrame, *, window: EncounterWindow = EncounterWindow()) -> pd.DataFrame:
    """The per-frame encounter table (ENCOUNTER_COLUMNS) of every merge in ``table``."""
    return extract(table, window=window).frames
