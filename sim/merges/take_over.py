"""The closed-loop controller's choice of the lag car A, applied to a recorded trajectory table.

Demonstrations and closed-loop control must see the same encounters (so that a driver learns
and acts on the same terms). The controller (:mod:`sim.closed_loop.controller`) cannot know which car will
end up behind B when B merges; it hands B a lag car A when B reaches the take-over zone and
keeps it. :class:`TakeOverRule` states that rule and :func:`take_overs` applies it to a whole
table (through its :class:`TableIndex`), so that :func:`sim.merges.encounters.extract` can cut the demonstrations exactly where the
controller would have observed SUMO's driver:

* **Take-over** (the controller's ``take_over``): at the first frame in which B is on a
  ramp lane with ``Local_Y >= zone_start_ft``, before its merge frame, and a lane-6 vehicle is
  strictly behind B within ``max_lag_ft`` that is not already A (or B) of another encounter
  being observed then, that vehicle is A. Otherwise the next frame is tried.
* **End**: the last frame before ``hold_frames`` frames after B's merge frame, before
  ``max_frames`` frames after the take-over, and before the first frame in which A is not in
  lane 6, A or B has no row, or A has no row at t+1 (no action). The controller releases A in the
  same frames (``merge_done``, ``timeout``, ``left_lane``, ``b_lost``, ``removed``).
* **C** in every frame (the controller's ``lead_of(..., exclude=(A, B))``): the nearest lane-6
  vehicle strictly ahead of A other than B.

Two controller events cannot be seen in a table and are not reproduced: a B that never merges
(it holds its A in the controller; here it has no encounter) and collisions.
"""

from __future__ import annotations

import heapq
import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from merge_irl.units import FRAME_S
from sim.closed_loop.config import ControllerConfig
from sim.drivers.observe import lag_lead_positions


@dataclass(frozen=True)
class TakeOverRule:
    """Where and for how long the controller observes an encounter (see the module docstring).

    Attributes:
        zone_start_ft: B is handed an A once its ``Local_Y`` is at least this (ft).
        max_lag_ft: A is at most this far behind B (ft).
        hold_frames: frames A stays observed after B's merge frame (0.1 s frames).
        max_frames: frames after the take-over at which A is released in any case.
    """

    zone_start_ft: float
    max_lag_ft: float = 250.0
    hold_frames: int = 30
    max_frames: int = 600

    def __post_init__(self) -> None:
        if not math.isfinite(self.zone_start_ft):
            raise ValueError(f"TakeOverRule.zone_start_ft must be finite, got {self.zone_start_ft}")
        if not (self.max_lag_ft > 0 and math.isfinite(self.max_lag_ft)):
            raise ValueError(f"TakeOverRule.max_lag_ft must be a positive number, got {self.max_lag_ft}")
        if self.hold_frames < 0 or self.max_frames < 1:
            raise ValueError(f"TakeOverRule: hold_frames >= 0 and max_frames >= 1, got {self.hold_frames}, "
                             f"{self.max_frames}")

    @classmethod
    def of_controller(cls, config: ControllerConfig, aux_lane_start_ft: float) -> TakeOverRule:
        """The rule of a controller with ``config`` on a road whose auxiliary lane starts at
        ``aux_lane_start_ft`` (:attr:`sim.runtime.run_result.SimulationResult.aux_lane_start_ft`).

        Raises:
            ValueError: the zone start is not finite (no auxiliary lane known and no
                ``zone_start_ft`` in ``config``).
        """
        zone = config.zone_start(aux_lane_start_ft)
        if not math.isfinite(zone):
            raise ValueError(f"the take-over zone needs where the auxiliary lane starts (got {aux_lane_start_ft}) "
                             "or ControllerConfig.zone_start_ft; the merge-frame rule needs neither")
        return cls(zone, float(config.max_lag_ft), config.hold_frames(FRAME_S), config.max_frames(FRAME_S))


@dataclass(frozen=True)
class TakeOver:
    """One encounter as the controller would observe it: B, its merge frame, A (0: none) and the
    frames ``[start, end)`` (0.1 s frame numbers) in which A is observed."""

    b_id: int
    merge_frame: int
    a_id: int
    start: int
    end: int


class TableIndex:
    """Look-ups into a trajectory table for cutting encounters (built once per table): its
    columns, the row of each (Vehicle_ID, Frame_ID), and the merge-lane vehicles of each frame
    sorted by ``Local_Y`` for lag and lead look-ups.

    Args:
        table: trajectory table with ``Vehicle_ID, Frame_ID, Local_Y, Lane_ID``.
        merge_lane: the site's merge lane code (lane 6 on I-80).

    Attributes:
        vid, frame, lane: ``[N]`` int64 columns; y: ``[N]`` float64 ``Local_Y`` (ft).
        row_of: MultiIndex (Vehicle_ID, Frame_ID) -> row (:attr:`unique` False: duplicate rows).
    """

    def __init__(self, table: pd.DataFrame, merge_lane: int):
        self.vid = table["Vehicle_ID"].to_numpy(np.int64)
        self.frame = table["Frame_ID"].to_numpy(np.int64)
        self.lane = table["Lane_ID"].to_numpy(np.int64)
        self.y = table["Local_Y"].to_numpy(np.float64)
        self.merge_lane = int(merge_lane)
        self.row_of = pd.MultiIndex.from_arrays([self.vid, self.frame])
        m = np.flatnonzero(self.lane == merge_lane)
        m = m[np.lexsort((self.y[m], self.frame[m]))]
        self._merge_frames, self._merge_ys, self._merge_vids = self.frame[m], self.y[m], self.vid[m]

    @property
    def unique(self) -> bool:
        """No (Vehicle_ID, Frame_ID) pair has two rows."""
        return bool(self.row_of.is_unique)

    def rows(self, v: int, frames: np.ndarray) -> np.ndarray:
        """``[len(frames)]`` rows of vehicle ``v`` at ``frames`` (-1 where it has none)."""
        return self.row_of.get_indexer(pd.MultiIndex.from_arrays([np.full(frames.shape, v, np.int64), frames]))

    def merge_lane_at(self, f: int) -> tuple[list[float], np.ndarray]:
        """``(Local_Y ascending, Vehicle_IDs)`` of the merge-lane vehicles at frame ``f``."""
        lo, hi = np.searchsorted(self._merge_frames, f, "left"), np.searchsorted(self._merge_frames, f, "right")
        return self._merge_ys[lo:hi].tolist(), self._merge_vids[lo:hi]

    def lag(self, f: int, y_ref: float, max_gap_ft: float) -> int:
        """Vehicle_ID of the nearest merge-lane vehicle strictly behind ``y_ref`` within
        ``max_gap_ft`` at frame ``f`` (:func:`sim.drivers.observe.lag_lead_positions`); 0 if none."""
        ys, vids = self.merge_lane_at(f)
        k, _ = lag_lead_positions(ys, y_ref)
        if k < 0 or ys[k] < y_ref - max_gap_ft:
            return 0
        return int(vids[k])

    def lead(self, f: int, y_ref: float, exclude: tuple[int, ...]) -> int:
        """Vehicle_ID of the nearest merge-lane vehicle strictly ahead of ``y_ref`` at frame
        ``f`` that is not in ``exclude`` (:func:`sim.drivers.observe.lag_lead_positions`); 0 if none."""
        ys, vids = self.merge_lane_at(f)
        _, k = lag_lead_positions(ys, y_ref)
        for j in range(k, len(ys)) if k >= 0 else ():
            if int(vids[j]) not in exclude:
                return int(vids[j])
        return 0


def take_overs(index: TableIndex, merges: pd.DataFrame, rule: TakeOverRule, *,
               ramp_lanes: tuple[int, ...]) -> list[TakeOver]:
    """The controller's encounter of every merge in ``merges`` (``B_id, merge_frame``), in the
    order of ``merges``.

    The controller is replayed frame by frame: a B without A asks for its lag car in every frame
    it spends in the zone; a car that is A or B of an encounter being observed cannot be A of
    another (the controller's ``_active`` check), and within a frame Bs ask in Vehicle_ID order.

    Args:
        index: :class:`TableIndex` of the trajectory table (unique (Vehicle_ID, Frame_ID)).
        merges: one row per B (:func:`sim.merges.encounters.find_merges`).
        rule: :class:`TakeOverRule`.
        ramp_lanes: the site's ramp lane codes (:mod:`sim.runtime.sites`).
    """
    vid, frame, y = index.vid, index.frame, index.y
    on_ramp = np.isin(index.lane, np.asarray(ramp_lanes, dtype=np.int64)) & (y >= rule.zone_start_ft)
    ramp_rows = np.flatnonzero(on_ramp)
    ramp_rows = ramp_rows[np.lexsort((frame[ramp_rows], vid[ramp_rows]))]

    # each B's rows in the zone before its merge, in frame order
    zone: dict[tuple[int, int], np.ndarray] = {}
    for b, mf in zip(merges["B_id"].to_numpy(np.int64).tolist(), merges["merge_frame"].to_numpy(np.int64).tolist()):
        lo, hi = np.searchsorted(vid[ramp_rows], b, "left"), np.searchsorted(vid[ramp_rows], b, "right")
        r = ramp_rows[lo:hi]
        zone[(b, mf)] = r[frame[r] < mf]
    busy: dict[int, list[tuple[int, int]]] = {}  # Vehicle_ID -> observed [start, end) as A or B

    def free(v: int, f: int) -> bool:
        return not any(s <= f < e for s, e in busy.get(v, ()))

    # replay the controller in time order: every frame, each waiting B (by Vehicle_ID) asks for
    # its lag car; the take-overs of earlier frames decide who is busy
    found = {key: TakeOver(key[0], key[1], 0, key[1], key[1]) for key in zone}
    waiting = [(int(frame[r[0]]), key[0], key[1], 0) for key, r in zone.items() if len(r)]
    heapq.heapify(waiting)
    while waiting:
        f, b, mf, k = heapq.heappop(waiting)
        i = zone[(b, mf)][k]
        a = index.lag(f, float(y[i]), rule.max_lag_ft)
        if a and free(a, f):
            end = _end(index, a, b, f, mf, rule)
            found[(b, mf)] = TakeOver(b, mf, a, f, end)
            busy.setdefault(a, []).append((f, end))
            busy.setdefault(b, []).append((f, end))
        elif k + 1 < len(zone[(b, mf)]):
            heapq.heappush(waiting, (int(frame[zone[(b, mf)][k + 1]]), b, mf, k + 1))
    return [found[(int(b), int(mf))] for b, mf in zip(merges["B_id"], merges["merge_frame"])]


def _end(index: TableIndex, a: int, b: int, start: int, mf: int, rule: TakeOverRule) -> int:
    """First frame after the take-over at ``start`` in which A is no longer observed."""
    stop = min(mf + rule.hold_frames, start + rule.max_frames)
    frames = np.arange(start, max(stop, start + 1), dtype=np.int64)
    ra, rb, ra_next = index.rows(a, frames), index.rows(b, frames), index.rows(a, frames + 1)
    ok = (ra >= 0) & (rb >= 0) & (ra_next >= 0)
    ok[ok] &= index.lane[ra[ok]] == index.merge_lane
    bad = np.flatnonzero(~ok)
    return int(frames[bad[0]]) if len(bad) else int(stop)
