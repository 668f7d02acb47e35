"""Streaming validation of NGSIM rows, one chunk at a time.

:class:`ChunkValidator` sees the chunks of a file in order (as float64 arrays, one per
column, plus the file line number of every row) and

* raises :class:`~sim.errors.TrajectoryFormatError` naming file, line and column for: missing
  values, non-integral ids / frames / classes / lanes / times, negative vehicle length or width,
  a negative speed, a lane number below 1,
  frames out of order for a vehicle, a frame repeated for a vehicle with different values;
* marks exact duplicate rows (a known NGSIM defect) for dropping and counts them;
* counts vehicles with gaps in their frames and the frames missing (reported, data kept);
* accumulates what the units check and the acceleration-noise summary need.

Per-vehicle state (last frame and last row of every vehicle seen so far) is kept in sorted
numpy arrays, so memory grows with the number of vehicles, not of rows.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim.errors import TrajectoryFormatError
from sim.ngsim.format import INT_COLUMNS, NGSIM_COLUMNS

#: NGSIM caps accelerations at +-11.2 ft/s^2; rows at the cap are counted as saturated.
ACC_CAP_FT_S2 = 11.2
#: Mean vehicle length / width below these (ft) means the file is in metres.
MIN_MEAN_LENGTH_FT = 8.0
MIN_MEAN_WIDTH_FT = 3.5

_COL = {c: i for i, c in enumerate(NGSIM_COLUMNS)}


#: Largest integer magnitude accepted in an integer column (exact in float64).
INT_LIMIT = float(2**53)


@dataclass
class ValidationTotals:
    """Running totals; turned into the frozen load report at the end."""

    rows: int = 0
    duplicate_rows: int = 0
    gap_events: int = 0
    missing_frames: int = 0
    max_gap_frames: int = 0
    acc_saturated_rows: int = 0
    length_sum: float = 0.0
    width_sum: float = 0.0
    speed_max: float = 0.0


class ChunkValidator:
    """Validates consecutive chunks of one file. See the module docstring."""

    def __init__(self, path: str) -> None:
        self.path = path
        self.totals = ValidationTotals()
        self._ids = np.empty(0, dtype=np.int64)  # sorted vehicle ids
        self._last = np.empty((0, len(NGSIM_COLUMNS)), dtype=np.float64)  # their last rows
        self._last_line = np.empty(0, dtype=np.int64)
        self._gapped: set[int] = set()

    @property
    def n_vehicles(self) -> int:
        return int(len(self._ids))

    @property
    def vehicles_with_gaps(self) -> tuple[int, ...]:
        return tuple(sorted(self._gapped))

    def _fail(self, line: int, column: str, msg: str) -> TrajectoryFormatError:
        return TrajectoryFormatError(f"{self.path}: line {line}, column {column}: {msg}")

    def check(self, data: np.ndarray, lines: np.ndarray, *, order: bool = True) -> np.ndarray:
        """Validate one chunk; return a keep mask (False for exact duplicate rows).

        Args:
            data: float64[18, N], one row per NGSIM column in schema order.
            lines: int64[N], the 1-based file line of every row.
            order: also check frame order, duplicates and gaps per vehicle (False: values
                only, nothing is tallied; for files read unsorted, checked after sorting).
        Returns:
            bool[N], True for rows to keep.

        Raises:
            TrajectoryFormatError: a missing or non-finite value, a non-integer or out-of-range integer
                column, a negative length or width, or rows out of order (file, line and column named).
        """
        n = data.shape[1]
        keep = np.ones(n, dtype=bool)
        if n == 0:
            return keep
        nan = np.isnan(data)
        if nan.any():
            r = int(np.flatnonzero(nan.any(axis=0))[0])
            j = int(np.flatnonzero(nan[:, r])[0])
            raise self._fail(int(lines[r]), NGSIM_COLUMNS[j], "missing value; expected a number")
        inf = np.isinf(data)
        if inf.any():
            r = int(np.flatnonzero(inf.any(axis=0))[0])
            j = int(np.flatnonzero(inf[:, r])[0])
            raise self._fail(int(lines[r]), NGSIM_COLUMNS[j],
                             f"value {data[j, r]!r} is not finite; expected a number")
        for c in INT_COLUMNS:
            col = data[_COL[c]]
            bad = col != np.round(col)
            if bad.any():
                r = int(np.argmax(bad))
                raise self._fail(int(lines[r]), c, f"value {col[r]!r} is not an integer")
            # float64 holds integers exactly only up to 2**53; ids beyond that are not NGSIM's
            big = np.abs(col) > INT_LIMIT
            if big.any():
                r = int(np.argmax(big))
                raise self._fail(int(lines[r]), c,
                                 f"integer {col[r]:.17g} is out of range; expected |value| <= 2**53")
        for c, lo, expected in (("v_Vel", 0.0, "a speed >= 0 ft/s (NGSIM speeds have no sign)"),
                                ("Lane_ID", 1.0, "a lane number >= 1 (NGSIM numbers lanes from 1)")):
            col = data[_COL[c]]
            if (col < lo).any():
                r = int(np.argmax(col < lo))
                raise self._fail(int(lines[r]), c, f"{c} {col[r]:g}; expected {expected}")
        for c in ("v_Length", "v_Width"):
            col = data[_COL[c]]
            if (col < 0).any():
                r = int(np.argmax(col < 0))
                raise self._fail(int(lines[r]), c, f"negative {c} {col[r]}; expected a length >= 0 ft")
        if not order:
            return keep
        self._check_order(data, lines, keep)
        t = self.totals
        t.rows += n
        t.length_sum += float(data[_COL["v_Length"]][keep].sum())
        t.width_sum += float(data[_COL["v_Width"]][keep].sum())
        t.speed_max = max(t.speed_max, float(np.abs(data[_COL["v_Vel"]]).max(initial=0.0)))
        t.acc_saturated_rows += int((np.abs(data[_COL["v_Acc"]][keep]) >= ACC_CAP_FT_S2 - 1e-9).sum())
        return keep

    def _check_order(self, data: np.ndarray, lines: np.ndarray, keep: np.ndarray) -> None:
        veh = data[_COL["Vehicle_ID"]].astype(np.int64)
        frame = data[_COL["Frame_ID"]].astype(np.int64)
        order = np.lexsort((np.arange(len(veh)), veh))  # by vehicle, file order within
        sv, sf = veh[order], frame[order]
        first = np.ones(len(sv), dtype=bool)
        first[1:] = sv[1:] != sv[:-1]
        # previous frame of the same vehicle: in this chunk, or the state from earlier chunks
        prev_f = np.empty(len(sv), dtype=np.int64)
        prev_f[1:] = sf[:-1]
        prev_line = np.empty(len(sv), dtype=np.int64)
        prev_line[1:] = lines[order][:-1]
        prev_row_src = np.empty(len(sv), dtype=np.int64)  # index into data, -1 = state
        prev_row_src[1:] = order[:-1]
        has_prev = ~first
        fi = np.flatnonzero(first)
        pos = np.searchsorted(self._ids, sv[fi])
        pos_c = np.minimum(pos, max(len(self._ids) - 1, 0))
        known = (pos < len(self._ids)) & (self._ids[pos_c] == sv[fi]) if len(self._ids) else np.zeros(len(fi), bool)
        kfi = fi[known]
        state_pos = pos[known]
        prev_f[kfi] = self._last[state_pos, _COL["Frame_ID"]].astype(np.int64)
        prev_line[kfi] = self._last_line[state_pos]
        prev_row_src[kfi] = -1 - state_pos
        has_prev[kfi] = True
        d = sf - prev_f
        back = has_prev & (d < 0)
        if back.any():
            i = int(np.flatnonzero(back)[0])
            raise self._fail(
                int(lines[order[i]]), "Frame_ID",
                f"vehicle {sv[i]} frame {sf[i]} comes after its frame {prev_f[i]} (line "
                f"{prev_line[i]}); expected increasing frames per vehicle",
            )
        same = np.flatnonzero(has_prev & (d == 0))
        if len(same):
            src = prev_row_src[same]
            prev_rows = np.where((src >= 0)[:, None], data[:, np.maximum(src, 0)].T,
                                 self._last[np.maximum(-1 - src, 0)] if len(self._last) else 0.0)
            rows = data[:, order[same]].T
            equal = (prev_rows == rows).all(axis=1)
            if not equal.all():
                j = int(np.flatnonzero(~equal)[0])
                i = same[j]
                diff = [NGSIM_COLUMNS[c] for c in np.flatnonzero(prev_rows[j] != rows[j])]
                raise self._fail(
                    int(lines[order[i]]), diff[0],
                    f"vehicle {sv[i]} frame {sf[i]} appears again (first on line {prev_line[i]}) "
                    f"with different values in {diff}; expected one row per vehicle and frame",
                )
            keep[order[same]] = False
        self.totals.duplicate_rows += int(len(same))
        gap = has_prev & (d > 1)
        if gap.any():
            g = d[gap] - 1
            self.totals.gap_events += int(gap.sum())
            self.totals.missing_frames += int(g.sum())
            self.totals.max_gap_frames = max(self.totals.max_gap_frames, int(g.max()))
            self._gapped.update(int(v) for v in np.unique(sv[gap]))
        # update state with the last row of every vehicle in this chunk
        last = np.ones(len(sv), dtype=bool)
        last[:-1] = sv[:-1] != sv[1:]
        new_ids = sv[last]
        new_rows = data[:, order[last]].T
        new_lines = lines[order[last]]
        ids = np.concatenate([new_ids, self._ids])
        rows = np.concatenate([new_rows, self._last])
        lns = np.concatenate([new_lines, self._last_line])
        uniq, idx = np.unique(ids, return_index=True)  # first occurrence = the new row
        self._ids, self._last, self._last_line = uniq, rows[idx], lns[idx]

    def check_units(self) -> None:
        """After the last chunk: raise if vehicle sizes look like metres, not feet.

        Raises:
            TrajectoryFormatError: mean vehicle length or width looks like metres, not NGSIM's feet.
        """
        t = self.totals
        rows = t.rows - t.duplicate_rows
        if rows == 0:
            return
        mean_len, mean_wid = t.length_sum / rows, t.width_sum / rows
        if mean_len < MIN_MEAN_LENGTH_FT or mean_wid < MIN_MEAN_WIDTH_FT:
            col, val, lim = (
                ("v_Length", mean_len, MIN_MEAN_LENGTH_FT) if mean_len < MIN_MEAN_LENGTH_FT
                else ("v_Width", mean_wid, MIN_MEAN_WIDTH_FT)
            )
            raise TrajectoryFormatError(
                f"{self.path}: column {col} (all {rows} rows): mean {val:.2f} looks like metres; "
                f"NGSIM files are in feet (expected a mean of at least {lim} ft, cars are about "
                "15 ft long and 6 ft wide). Convert the file to NGSIM units (ft, ft/s) first."
            )


#: Local_Y advance over what v_Vel implies, accepted as consistent (ratio of sums).
KINEMATIC_TOLERANCE = 0.07
#: 99th percentile speed above this (ft/s, ~100 mph) is implausible for NGSIM freeway data.
MAX_P99_SPEED_FT_S = 147.0
#: Adjacent lanes' median Local_X this close (ft) mean Local_X is in metres (lanes ~12 ft).
METRIC_LANE_SPACING_FT = (2.0, 7.5)

#: Known unit mix-ups: Local_Y advance / v_Vel distance ratio -> likely cause.
_RATIO_CAUSES: tuple[tuple[float, str, str], ...] = (
    (0.3048, "Local_Y", "Local_Y in metres with v_Vel in ft/s"),
    (1.0 / 0.3048, "v_Vel", "v_Vel in m/s with Local_Y in feet"),
    (1.0 / 1.09728, "v_Vel", "v_Vel in km/h with Local_Y in feet"),
    (1.0 / 0.681818, "v_Vel", "v_Vel in mph with Local_Y in feet"),
    (1.0 / 3.6, "v_Vel", "v_Vel in km/h with Local_Y in metres"),
)


def check_kinematic_units(vehicle: np.ndarray, frame: np.ndarray, lane: np.ndarray, local_x: np.ndarray,
                          local_y: np.ndarray, speed: np.ndarray, path: str) -> None:
    """Check that positions and speeds are in NGSIM's units (feet, ft/s), not only sizes.

    Arrays are [N] rows sorted by (vehicle, frame). Three tests, each needing enough data:

    * kinematic consistency: over consecutive frames of a vehicle, the sum of ``Local_Y``
      advances must match the distance ``v_Vel`` implies (trapezoid, 0.1 s frames) within
      :data:`KINEMATIC_TOLERANCE`; unit mix-ups give 0.30, 3.28, 0.91 (km/h), ...;
    * plausible speeds: the 99th percentile of ``v_Vel`` at most :data:`MAX_P99_SPEED_FT_S`;
    * lateral scale: adjacent lanes' median ``Local_X`` about a lane width (12 ft) apart, not
      3.7 (skipped when ``Local_X`` does not follow the lanes).

    Raises:
        TrajectoryFormatError: naming the file, the column and the likely cause.
    """
    same = (vehicle[1:] == vehicle[:-1]) & (frame[1:] == frame[:-1] + 1)
    if same.sum() >= 50:
        dy = float(np.sum((local_y[1:] - local_y[:-1])[same]))
        dv = float(np.sum(((speed[1:] + speed[:-1]) * 0.05)[same]))
        if dv > 100.0:
            ratio = dy / dv
            if abs(ratio - 1.0) > KINEMATIC_TOLERANCE:
                col, cause = "Local_Y", "Local_Y and v_Vel in different units"
                for r, c, why in _RATIO_CAUSES:
                    if abs(ratio / r - 1.0) < KINEMATIC_TOLERANCE:
                        col, cause = c, why
                        break
                raise TrajectoryFormatError(
                    f"{path}: column {col}: Local_Y advances {ratio:.3f} times the distance v_Vel "
                    f"implies over {int(same.sum())} consecutive frames (expected 1 +- "
                    f"{KINEMATIC_TOLERANCE}); looks like {cause}. NGSIM files are in ft and ft/s: "
                    "convert the file first."
                )
    if speed.size >= 50:
        p99 = float(np.percentile(speed, 99))
        if p99 > MAX_P99_SPEED_FT_S:
            raise TrajectoryFormatError(
                f"{path}: column v_Vel: 99th percentile speed {p99:.1f}; expected ft/s (at most "
                f"{MAX_P99_SPEED_FT_S:.0f}, about 100 mph): km/h or another unit? Convert to ft/s first."
            )
    lanes, counts = np.unique(lane, return_counts=True)
    lanes = lanes[counts >= 20]
    if lanes.size >= 2:
        med = np.array([np.median(local_x[lane == k]) for k in lanes])
        adj = np.diff(lanes) == 1
        if adj.sum() >= 1:
            spacing = float(np.median(np.abs(np.diff(med))[adj]))
            lo, hi = METRIC_LANE_SPACING_FT
            if lo < spacing < hi:
                raise TrajectoryFormatError(
                    f"{path}: column Local_X: adjacent lanes' median positions are {spacing:.2f} "
                    "apart; lanes are about 12 ft wide, so Local_X looks like metres. Convert the "
                    "file to NGSIM units (ft, ft/s) first."
                )
