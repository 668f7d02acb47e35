"""Merge encounters (merging car B, lag car A, lead car C) from any NGSIM-schema trajectory table.

Definitions (the paper's section 4.2; feet, ft/s, ft/s^2; positions are NGSIM's front bumper).
Lane numbers are I-80's (ramp 7, merge lane 6); other sites pass ``site`` (:mod:`sim.runtime.sites`:
its ramp lanes for 7, its merge lane for 6; unknown lane codes are an error):

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
  and is not used), A's speed ``v_A``, and the lengths ``len_C`` and ``len_B`` (``v_Length``,
  NaN when the table has no such column or the length is not > 0). The next frame may lie beyond the window: A's row at
  t+1 is taken from the table wherever it is. A frame whose t+1 row of A is not in the table
  has no action and no row. The columns, dtypes and units are
  :data:`irl.domains.merge.encounters.ENCOUNTER_SCHEMA`.
* **Window** (:class:`EncounterWindow`): from the first frame in which A and B are both in the
  table (both in the section), or at most ``max_frames_before`` frames before the merge, until
  ``frames_after`` frames after the merge frame (0: the merge frame is the last row). Frames in
  which A or B is missing, or A has no row at t+1, are skipped.
* **Gaps** (recordings with missing frames): a merge frame is observed when B has a row in
  the frame before it. When B was last seen (on the ramp) some frames earlier, B changed lane
  at an unobserved frame in between and the merge frame is only the first frame it is *seen*
  in lane 6: ``merge_observed`` is False (in the merges summary and every frame row) and
  ``merge_gap_frames`` says how many frames are missing before it (the merge is at most that
  much earlier). ``frame_gaps`` counts the jumps in an encounter's kept frames (a frame in
  which A or B is missing); learning splits encounters there
  (:func:`irl.domains.merge.mdp.resample_encounters`), so no decision step spans them.
  A frame in which the lead car C is missing while it has rows before and after it (a gap in C's
  rows, not C yet to enter or gone) is left out the same way, not read as "no lead car":
  ``lead_gap_frames`` counts them per encounter and :func:`extract` warns
  (:class:`LeadGapWarning`).
* **Missing neighbours**: every B gets one row in the merges summary (``merges``), with
  ``A_id = 0`` when no lane-6 vehicle is behind it at the merge frame and ``C_id = 0`` when
  none is ahead. Without A there is no per-frame row (A is the driver being modelled). Without C
  (or in frames where C is not in the table) ``d_AC`` and ``v_AC`` are NaN: the no-lead-car
  rule of :mod:`irl.domains.merge.bins`.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Collection
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
import pandas as pd

from irl.domains.merge.actions import forward_acceleration
from irl.domains.merge.encounters import ENCOUNTER_COLUMNS
from merge_irl.units import FRAME_S
from sim.drivers.observe import lag_lead_positions
from sim.errors import TrajectoryFormatError
from sim.merges.take_over import TableIndex, TakeOverRule, take_overs
from sim.runtime.schema import V_CLASS_TRUCK
from sim.runtime.sites import I80, SiteProfile, check_lanes

#: Columns of the per-merge summary table, in order.
MERGE_COLUMNS: dict[str, str] = {
    "encounter_id": "int64", "B_id": "int64", "A_id": "int64", "C_id": "int64",
    "merge_frame": "int64", "Global_Time": "int64", "B_is_truck": "bool",
    "first_frame": "int64", "n_frames": "int64",
    "merge_observed": "bool", "merge_gap_frames": "int64", "frame_gaps": "int64",
    "lead_gap_frames": "int64",
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


#: A merge whose B moves this much more (ft) than its speed explains, between its last row
#: before the merge frame and the merge frame, is a jump (a SUMO teleport), not a merge. Over a
#: gap of dt seconds (missing frames) the allowance grows by what NGSIM's largest acceleration
#: (11.2 ft/s^2) can make the trapezoid rule miss, 11.2 * dt^2 / 4.
MAX_MERGE_JUMP_FT = 10.0
_MAX_ACC_FT_S2 = 11.2

#: Columns of the table of merges left out (``Encounters.excluded``).
EXCLUDED_COLUMNS: dict[str, str] = {"B_id": "int64", "merge_frame": "int64", "reason": "object"}


@dataclass(frozen=True)
class Encounters:
    """``frames``: one row per encounter frame (ENCOUNTER_COLUMNS); ``merges``: one row per B;
    ``excluded``: merges left out (EXCLUDED_COLUMNS: teleported B, position jump at the merge)."""

    frames: pd.DataFrame
    merges: pd.DataFrame
    excluded: pd.DataFrame = field(default_factory=lambda: _empty(EXCLUDED_COLUMNS))


class LeadGapWarning(UserWarning):
    """Frames in which the lead car C was missing from the table between rows of it were left out
    of their encounters (a recording's gap in C's rows, read otherwise as "no lead car")."""


def lead_gap_frames(frames: np.ndarray, c_ids: np.ndarray, rc: np.ndarray,
                    rows: Callable[[int, np.ndarray], np.ndarray], first: pd.Series, last: pd.Series) -> np.ndarray:
    """``bool[F]``: the frames in which the lead car is missing inside its own span of rows.

    Args:
        frames: ``[F]`` an encounter's frames, increasing.
        c_ids: ``[F]`` the lead car per frame (0: none found).
        rc: ``[F]`` the row of ``c_ids`` in each frame (-1: none).
        rows: ``rows(vehicle, frames) -> [F] row or -1`` of the table.
        first, last: each vehicle's first and last ``Frame_ID`` in the table.

    The reference lead is the last one seen with a row; a frame is a gap when that car has no row
    in it but has rows before and after it (the look-up then found another car further ahead, or
    none).
    """
    gap = np.zeros(frames.shape, bool)
    ref = 0
    for i, (f, c, r) in enumerate(zip(frames.tolist(), c_ids.tolist(), rc.tolist())):
        if c == ref and r >= 0:  # the same lead, seen: the usual frame
            continue
        if ref and int(first[ref]) < f < int(last[ref]) and rows(ref, np.array([f], np.int64))[0] < 0:
            gap[i] = True
            continue
        if c and r >= 0:
            ref = c
    return gap


def screen_merges(table: pd.DataFrame, merges: pd.DataFrame,
                  teleported: Collection[int] = ()) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Split ``merges`` (``B_id, merge_frame``) into real merges and non-physical ones.

    A merge is left out when B is in ``teleported`` (Vehicle_IDs SUMO reported as teleported)
    or when, between B's last row before the merge frame and the merge frame, ``Local_Y``
    moves more than :data:`MAX_MERGE_JUMP_FT` beyond what ``v_Vel`` explains (trapezoid rule,
    0.1 s frames): a vehicle put ahead without driving, as SUMO's jam teleport does.

    Returns:
        (kept merges, same columns; excluded, EXCLUDED_COLUMNS).

    Raises:
        TrajectoryFormatError: duplicate (Vehicle_ID, Frame_ID) rows.
    """
    if merges.empty:
        return merges, _empty(EXCLUDED_COLUMNS)
    vid = table["Vehicle_ID"].to_numpy(np.int64)
    frame = table["Frame_ID"].to_numpy(np.int64)
    o = np.lexsort((frame, vid))
    sv, sf = vid[o], frame[o]
    y = table["Local_Y"].to_numpy(np.float64)[o]
    v = table["v_Vel"].to_numpy(np.float64)[o]
    b = merges["B_id"].to_numpy(np.int64)
    mf = merges["merge_frame"].to_numpy(np.int64)
    idx = pd.MultiIndex.from_arrays([sv, sf])
    if not idx.is_unique:
        raise TrajectoryFormatError("trajectory table: duplicate (Vehicle_ID, Frame_ID) rows")
    pos = idx.get_indexer(pd.MultiIndex.from_arrays([b, mf]))
    prev = np.maximum(pos - 1, 0)
    has_prev = (pos > 0) & (sv[prev] == b)
    dt = (sf[pos] - sf[prev]) * FRAME_S
    jump = np.where(has_prev, np.abs(y[pos] - y[prev] - (v[pos] + v[prev]) * 0.5 * dt), 0.0)
    allowed = MAX_MERGE_JUMP_FT + _MAX_ACC_FT_S2 * dt * dt / 4.0
    tele = np.isin(b, np.fromiter(teleported, dtype=np.int64)) if len(teleported) else np.zeros(len(b), bool)
    bad = tele | (jump > allowed)
    reasons = [("teleported (SUMO's list)" if t else f"Local_Y jumps {j:.1f} ft beyond what v_Vel explains at the merge")
               for t, j in zip(tele[bad], jump[bad])]
    excluded = pd.DataFrame({"B_id": b[bad], "merge_frame": mf[bad], "reason": reasons}).astype(EXCLUDED_COLUMNS)
    return merges.loc[~bad].reset_index(drop=True), excluded


def _empty(cols: dict[str, str]) -> pd.DataFrame:
    return pd.DataFrame({c: pd.Series(dtype=t) for c, t in cols.items()})


def _check(table: pd.DataFrame) -> None:
    missing = [c for c in _NEEDED if c not in table.columns]
    if missing:
        raise TrajectoryFormatError(f"trajectory table: missing columns {missing} needed for merge encounters")


def find_merges(table: pd.DataFrame, *, site: SiteProfile = I80) -> pd.DataFrame:
    """One row per merging vehicle B: ``B_id, merge_frame`` (int64), sorted by merge frame, B.

    ``site`` gives the lane coding (:mod:`sim.runtime.sites`): B has a row in one of its ramp lanes
    and later one in its merge lane.

    Raises:
        TrajectoryFormatError: a needed column is missing, or ``Lane_ID`` holds codes the
            site does not list.
    """
    _check(table)
    vid = table["Vehicle_ID"].to_numpy(np.int64)
    frame = table["Frame_ID"].to_numpy(np.int64)
    lane = table["Lane_ID"].to_numpy(np.int64)
    check_lanes(lane, site)
    on7 = np.isin(lane, np.asarray(site.ramp_lanes, dtype=np.int64))
    if not on7.any():
        return pd.DataFrame({"B_id": pd.Series(dtype="int64"), "merge_frame": pd.Series(dtype="int64")})
    first7 = pd.Series(frame[on7]).groupby(vid[on7]).min()
    f7 = first7.reindex(vid).to_numpy()  # NaN for vehicles never in lane 7
    cand = (lane == site.merge_lane) & ~np.isnan(f7) & (frame > np.nan_to_num(f7, nan=np.inf))
    merge = pd.Series(frame[cand]).groupby(vid[cand]).min()
    out = pd.DataFrame({"B_id": merge.index.to_numpy(np.int64), "merge_frame": merge.to_numpy(np.int64)})
    return out.sort_values(["merge_frame", "B_id"], kind="stable").reset_index(drop=True)


def extract(table: pd.DataFrame, *, window: EncounterWindow = EncounterWindow(),
            site: SiteProfile = I80, teleported: Collection[int] = (),
            take_over: TakeOverRule | None = None) -> Encounters:
    """Every merge of ``table`` with its A and C, and the per-frame encounter variables.

    ``site``: the lane coding (:mod:`sim.runtime.sites`; I-80's by default, as in simulated runs).
    ``teleported``: Vehicle_IDs SUMO teleported; their merges, and merges with a position jump,
    are left out (listed in ``excluded``, see :func:`screen_merges`).
    ``take_over``: A, C and the window by the closed-loop controller's rule instead of the
    merge frame's (:mod:`sim.merges.take_over`: A is handed to B in the take-over zone, C is A's lead
    car other than B in every frame, the window runs from the take-over until the controller
    would release A); ``window`` must then be left at its default. Simulated demonstrations use
    it (:func:`sim.merges.demonstrators.encounters_of_run`), so that they are what the controller observes.

    Warns:
        LeadGapWarning: frames with C missing between rows of it were left out.

    Raises:
        TrajectoryFormatError: see :func:`find_merges`; duplicate (Vehicle_ID, Frame_ID) rows.
        ValueError: ``take_over`` given with a window other than the default.
    """
    _check(table)
    if take_over is not None and window != EncounterWindow():
        raise ValueError("extract: the take-over rule sets the window itself; leave `window` at its default")
    merges, excluded = screen_merges(table, find_merges(table, site=site), teleported)
    if merges.empty:
        return Encounters(_empty(ENCOUNTER_COLUMNS), _empty(MERGE_COLUMNS), excluded)
    index = TableIndex(table, site.merge_lane)  # merge-lane vehicles per frame by Local_Y: A/C look-ups
    if not index.unique:
        raise TrajectoryFormatError("trajectory table: duplicate (Vehicle_ID, Frame_ID) rows")
    vid, frame, rows = index.vid, index.frame, index.rows
    cols = _row_columns(table, index)

    controlled = (take_overs(index, merges, take_over, ramp_lanes=tuple(site.ramp_lanes))
                  if take_over is not None else None)
    summary, chunks = [], []
    for eid, (b, mf) in enumerate(zip(merges["B_id"].to_numpy(), merges["merge_frame"].to_numpy()), start=1):
        rb = rows(b, np.array([mf]))[0]
        truck = bool(cols.vclass[rb] == V_CLASS_TRUCK)
        observed = bool(rows(b, np.array([mf - 1]))[0] >= 0)  # B seen in the frame before its merge frame
        gap_before = 0 if observed else int(mf - 1 - frame[(vid == b) & (frame < mf)].max())
        if controlled is not None:
            to = controlled[eid - 1]
            a, c, start = to.a_id, 0, to.start
            frames = np.arange(to.start, to.end, dtype=np.int64)
        else:
            a, c, start, frames = _merge_frame_window(index, cols, window, b, mf, rb)
        n = n_lead_gaps = 0
        if a:
            chunk, c, frames, n_lead_gaps = _encounter_frames(
                index, cols, _Encounter(eid, b, a, c, mf, truck, observed), frames,
                controlled=controlled is not None)
            chunks.append(chunk)
            n = len(frames)
        summary.append((eid, b, a, c, mf, cols.gtime[rb], truck, start, n, observed, gap_before,
                        int(np.count_nonzero(np.diff(frames) > 1)) if n else 0, n_lead_gaps))
    frames_df = pd.concat(chunks, ignore_index=True) if chunks else _empty(ENCOUNTER_COLUMNS)
    frames_df = frames_df.astype(ENCOUNTER_COLUMNS).loc[:, list(ENCOUNTER_COLUMNS)]
    merges_df = pd.DataFrame(summary, columns=list(MERGE_COLUMNS)).astype(MERGE_COLUMNS)
    gapped = merges_df[merges_df["lead_gap_frames"] > 0]
    if len(gapped):
        warnings.warn(f"{int(gapped['lead_gap_frames'].sum())} frame(s) of {len(gapped)} encounter(s) had the lead car C "
                      "missing between rows of it (a gap in the recording) and were left out, as gaps in A and B "
                      "are (not read as 'no lead car'); learning splits the encounters there (merges summary: "
                      "lead_gap_frames)", LeadGapWarning, stacklevel=2)
    return Encounters(frames_df, merges_df, excluded)


class _RowColumns(NamedTuple):
    """The table's per-row columns that :func:`extract` reads (each of length n_rows, in table order).

    ``vel``: v_Vel (ft/s, float64); ``length``: v_Length (ft, float64; NaN where the table has no
    such column or the length is not > 0); ``vclass``: v_Class (int64); ``gtime``: Global_Time
    (ms, int64); ``first_frame`` / ``last_frame``: each Vehicle_ID's first and last Frame_ID.
    """

    vel: np.ndarray
    length: np.ndarray
    vclass: np.ndarray
    gtime: np.ndarray
    first_frame: pd.Series
    last_frame: pd.Series


def _row_columns(table: pd.DataFrame, index: TableIndex) -> _RowColumns:
    """The per-row columns of ``table`` that :func:`extract` reads (see :class:`_RowColumns`)."""
    vel = table["v_Vel"].to_numpy(np.float64)
    length = (table["v_Length"].to_numpy(np.float64) if "v_Length" in table.columns
              else np.full(len(table), np.nan))
    length = np.where(length > 0, length, np.nan)  # a length of 0 (NGSIM's readers accept it) is unknown
    vclass = table["v_Class"].to_numpy(np.int64)
    gtime = table["Global_Time"].to_numpy(np.int64)
    first_frame = pd.Series(index.frame).groupby(index.vid).min()
    last_frame = pd.Series(index.frame).groupby(index.vid).max()
    return _RowColumns(vel, length, vclass, gtime, first_frame, last_frame)


class _Encounter(NamedTuple):
    """One merge as :func:`_encounter_frames` writes it: ids (Vehicle_ID; ``c`` 0 for none) and merge frame."""

    eid: int
    b: int
    a: int
    c: int
    mf: int
    truck: bool
    observed: bool


def _merge_frame_window(index: TableIndex, cols: _RowColumns, window: EncounterWindow,
                        b: int, mf: int, rb: int) -> tuple[int, int, int, np.ndarray]:
    """A and C of B at its merge frame ``mf`` (B's row ``rb``), and the window's frames.

    Returns ``(a, c, start, frames)``: A's and C's Vehicle_IDs (0 for none), the window's first
    frame (``mf`` without A) and its frames (int64 Frame_IDs, ``start`` .. ``mf + frames_after``).
    """
    ys_m, vids_m = index.merge_lane_at(int(mf))
    ys_m, vids_m = [yy for yy, v in zip(ys_m, vids_m) if v != b], vids_m[vids_m != b]
    ia, ic = lag_lead_positions(ys_m, float(index.y[rb]))  # the controller's rule too
    a = int(vids_m[ia]) if ia >= 0 else 0
    c = int(vids_m[ic]) if ic >= 0 else 0
    start = mf
    if a:
        start = int(max(cols.first_frame[a], cols.first_frame[b]))
        if window.max_frames_before is not None:
            start = max(start, int(mf) - window.max_frames_before)
    frames = np.arange(start, mf + window.frames_after + 1, dtype=np.int64)
    return a, c, start, frames


def _lead_cars(index: TableIndex, enc: _Encounter, frames: np.ndarray, ra: np.ndarray,
               *, controlled: bool) -> tuple[np.ndarray, np.ndarray, int]:
    """C frame by frame over ``frames`` (A's rows ``ra``, both of length n_frames).

    Returns ``(c_ids, rc, c)``: C's Vehicle_ID per frame (int64, 0 for none), C's table row per
    frame (-1 where C has none) and the C of the merges summary. Under the take-over rule C is
    A's lead car other than B in every frame (the summary's C: the one at the merge frame, else
    the last); otherwise the merge frame's ``enc.c`` throughout.
    """
    if controlled:  # C: A's lead car other than B, frame by frame
        c_ids = np.array([index.lead(int(f), float(ya), (enc.a, int(enc.b))) for f, ya in zip(frames, index.y[ra])],
                         dtype=np.int64)
        rc = np.where(c_ids > 0, index.row_of.get_indexer(pd.MultiIndex.from_arrays([c_ids, frames])), -1)
        at_merge = np.flatnonzero(frames == enc.mf)
        c = int(c_ids[at_merge[0]]) if len(at_merge) else int(c_ids[-1]) if len(c_ids) else 0
        return c_ids, rc, c
    c_ids = np.full(frames.shape, enc.c, np.int64)
    rc = index.rows(enc.c, frames) if enc.c else np.full(frames.shape, -1)
    return c_ids, rc, enc.c


def _encounter_frames(index: TableIndex, cols: _RowColumns, enc: _Encounter, frames: np.ndarray,
                      *, controlled: bool) -> tuple[pd.DataFrame, int, np.ndarray, int]:
    """The per-frame rows (ENCOUNTER_COLUMNS' names) of one encounter with an A over the window ``frames``.

    Frames without A, B or A's next row, and frames in a gap of C's rows, are left out.
    Returns ``(chunk, c, kept_frames, n_lead_gaps)``: the rows, the summary's C (Vehicle_ID, 0
    for none), the kept Frame_IDs (int64) and how many frames a gap in C's rows left out.
    """
    rows, y, vel, length = index.rows, index.y, cols.vel, cols.length
    a, b, mf = enc.a, enc.b, enc.mf
    ra, rbb, ra_next = rows(a, frames), rows(b, frames), rows(a, frames + 1)
    keep = (ra >= 0) & (rbb >= 0) & (ra_next >= 0)
    frames, ra, rbb, ra_next = frames[keep], ra[keep], rbb[keep], ra_next[keep]
    c_ids, rc, c = _lead_cars(index, enc, frames, ra, controlled=controlled)
    c_gap = lead_gap_frames(frames, c_ids, rc, rows, cols.first_frame, cols.last_frame)
    if c_gap.any():  # left out as A's and B's gaps are: counted, and learning splits there
        frames, ra, rbb, ra_next = frames[~c_gap], ra[~c_gap], rbb[~c_gap], ra_next[~c_gap]
        c_ids, rc = c_ids[~c_gap], rc[~c_gap]
    hc = rc >= 0
    yc = np.where(hc, y[np.where(hc, rc, 0)], np.nan)
    vc = np.where(hc, vel[np.where(hc, rc, 0)], np.nan)
    lc = np.where(hc, length[np.where(hc, rc, 0)], np.nan)
    chunk = pd.DataFrame({
        "encounter_id": enc.eid, "B_id": b, "A_id": a, "C_id": c_ids,
        "Frame_ID": frames, "Global_Time": cols.gtime[ra], "merge_frame": mf,
        "d_AC": yc - y[ra], "d_AB": y[rbb] - y[ra],
        "v_AC": vel[ra] - vc, "v_AB": vel[ra] - vel[rbb],
        "B_is_truck": enc.truck, "acc_A": forward_acceleration(vel[ra], vel[ra_next], FRAME_S),
        "v_A": vel[ra], "len_C": lc, "len_B": length[rbb], "merge_observed": enc.observed,
    })
    return chunk, c, frames, int(c_gap.sum())


def extract_encounters(table: pd.DataFrame, *, window: EncounterWindow = EncounterWindow(),
                       site: SiteProfile = I80) -> pd.DataFrame:
    """The per-frame encounter table (ENCOUNTER_COLUMNS) of every merge in ``table``.

    Raises:
        TrajectoryFormatError: see :func:`extract`.
    """
    return extract(table, window=window, site=site).frames
