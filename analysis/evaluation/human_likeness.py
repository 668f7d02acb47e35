"""Human likeness of closed-loop driving beside the demonstrations: the
emergency-braking rate per controlled A, the share of As that came within 2 m of their lead car C,
and the Wasserstein-1 distances of A's per-frame acceleration and jerk.

Definitions (NGSIM units in: ft, ft/s; SI out where the name says so; the rates over the policy's
episodes are taken in :func:`analysis.evaluation.aggregate.aggregate`):

* ``emergency_braking_rate``: ``emergency_brakings`` (events by A, B or A's follower while A is
  controlled, :mod:`analysis.evaluation.metrics`) per controlled A (control episode), with the
  exact (Garwood) Poisson 95 % interval of the total count divided by the As
  (:func:`analysis.evaluation.intervals.poisson_rate_ci95`). An A can cause several events, so
  the count is not binomial; the Poisson interval assumes independent events and is too narrow
  when events cluster in a few As.
* ``close_to_c`` / ``close_to_c_rate``: the control episodes whose A came closer than
  ``close_gap_m`` (default 2 m) bumper to bumper to its lead car C while controlled, and their
  share of the controlled As, with the Wilson 95 % interval. C in a frame is the nearest
  merge-lane vehicle ahead of A that is neither A nor B (the rule of the encounter table of a
  simulated run, :mod:`sim.merges.encounters`); the bumper gap is ``Local_Y(C) - Local_Y(A) -
  v_Length(C)``, only in frames where A itself is in the merge lane (a SUMO-driven A that changed
  lane has no lead car C there). A collision with C (gap <= 0) counts as close.
* demonstrations (:func:`demo_close_to_c`): the share of held-out encounters whose A came closer
  than ``close_gap_m`` to C (``d_AC - len_C``, ft; rows without C or without ``len_C`` do not
  count as close; the denominator is every encounter, as the closed loop's is every controlled A).
* ``w1_acc_A_m_s2``, ``w1_jerk_A_m_s3``: Wasserstein-1 distances of A's acceleration (m/s^2) and
  jerk (m/s^3) **per 0.1 s frame** while controlled to the held-out demonstration frames. Both
  sides are the same differences of A's speed over one frame: acceleration ``(v(t+1) - v(t)) /
  0.1 s`` (the demonstrations' ``acc_A``), jerk ``(acc(t+1) - acc(t)) / 0.1 s`` over consecutive
  frames of one control episode (of one encounter, by ``Frame_ID``, in the demonstrations). Per
  frame, not at the decision step: jerk depends on the interval it is differenced over, and the
  demonstrations are per frame; a driver that changes its acceleration only every decision step
  shows each change as one frame's jerk. (The older
  ``w1_acc_A_ft_s2`` of :mod:`analysis.evaluation.distances` compares the accelerations applied at
  the decisions with the demonstration frames, in ft/s^2.)
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from analysis.evaluation.distances import wasserstein
from analysis.evaluation.intervals import rate_ci95
from merge_irl.units import FRAME_S, FT_PER_M
from sim.merges.take_over import TableIndex

#: Bumper gap to C (m) below which an A counts as close to C.
CLOSE_GAP_M = 2.0


def min_gaps_to_c(table: pd.DataFrame, windows: Sequence[tuple[int, int, int, int]], merge_lane: int) -> np.ndarray:
    """``[W]`` smallest bumper gap (ft) of each control episode's A to its lead car C over the
    frames of its window (see the module docstring); ``inf`` when A never had a C in the merge lane.

    Args:
        table: trajectory table with ``Vehicle_ID, Frame_ID, Local_Y, Lane_ID, v_Length``
            (one row per vehicle and frame).
        windows: ``(a_id, b_id, start_frame, end_frame)`` per control episode (end inclusive).
        merge_lane: the site's merge lane code (lane 6 on I-80).
    """
    out = np.full(len(windows), np.inf)
    if not len(windows):
        return out
    index = TableIndex(table, merge_lane)
    length = table["v_Length"].to_numpy(np.float64)
    for i, (a, b, start, end) in enumerate(windows):
        frames = np.arange(start, end + 1, dtype=np.int64)
        ra = index.rows(a, frames)
        ok = ra >= 0
        ok[ok] = index.lane[ra[ok]] == merge_lane
        for f, r in zip(frames[ok], ra[ok]):
            c = index.lead(int(f), float(index.y[r]), (a, b))
            if c:
                rc = int(index.rows(c, np.array([f]))[0])
                out[i] = min(out[i], index.y[rc] - index.y[r] - length[rc])
    return out


@dataclass(frozen=True)
class DemoCloseness:
    """The held-out encounters whose A came within ``gap_m`` of C (:func:`demo_close_to_c`).

    Attributes:
        n_close: encounters whose A came closer than ``gap_m`` to C.
        n_encounters: encounters in the table.
        rate: ``n_close / n_encounters`` (NaN without encounters or without ``len_C``).
        ci95: its Wilson 95 % interval.
        gap_m: the threshold (m).
    """

    n_close: int
    n_encounters: int
    rate: float
    ci95: tuple[float, float]
    gap_m: float = CLOSE_GAP_M

    def to_dict(self) -> dict:
        return {"close_to_c": self.n_close, "n_encounters": self.n_encounters, "close_to_c_rate": self.rate,
                "close_to_c_ci95": list(self.ci95), "close_gap_m": self.gap_m}


def demo_close_to_c(encounters: pd.DataFrame, gap_m: float = CLOSE_GAP_M) -> DemoCloseness:
    """The share of encounters (``encounter_id``) whose A came closer than ``gap_m`` (m) bumper to
    bumper to C: ``d_AC - len_C < gap_m`` (both ft) in any row. Without an ``encounter_id`` or a
    ``len_C`` column the share is NaN (0 of the encounters counted)."""
    if "encounter_id" not in encounters or encounters.empty:
        return DemoCloseness(0, 0, float("nan"), (float("nan"), float("nan")), gap_m)
    n = int(encounters["encounter_id"].nunique())
    if "len_C" not in encounters:
        return DemoCloseness(0, n, float("nan"), (float("nan"), float("nan")), gap_m)
    gap = encounters["d_AC"].to_numpy(np.float64) - encounters["len_C"].to_numpy(np.float64)
    close = np.nan_to_num(gap, nan=np.inf) < gap_m * FT_PER_M
    k = int(encounters.loc[close, "encounter_id"].nunique())
    rate, lo, hi = rate_ci95(k, n)
    return DemoCloseness(k, n, rate, (lo, hi), gap_m)


def _differences(v: np.ndarray, frame: np.ndarray, segment: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-frame forward difference of ``v [N]`` and its forward difference, over rows ordered by
    (segment, frame): ``([M], [K])`` in units of ``v`` per s and per s^2."""
    step = (np.diff(frame) == 1) & (np.diff(segment) == 0)
    d1 = np.diff(v) / FRAME_S
    acc = d1[step]
    both = step[:-1] & step[1:]
    jerk = (np.diff(d1) / FRAME_S)[both]
    return acc, jerk


def frame_acc_jerk(profiles: Iterable[pd.DataFrame]) -> tuple[np.ndarray, np.ndarray]:
    """A's per-frame acceleration ``[M]`` (m/s^2) and jerk ``[K]`` (m/s^3) while controlled, from
    the speed profiles of each episode (:attr:`analysis.evaluation.episode.EpisodeResult.speed_profiles`:
    ``a_id, t_s`` since take-over, ``v_ft_s``); a control episode is a run of rows of one A whose
    ``t_s`` grows by one frame (a new take-over restarts it at 0)."""
    accs, jerks = [np.zeros(0)], [np.zeros(0)]
    for sp in profiles:
        if sp.empty:
            continue
        frame = np.rint(sp["t_s"].to_numpy(np.float64) / FRAME_S).astype(np.int64)
        a_id = sp["a_id"].to_numpy(np.int64)
        # a new segment where the A changes or t_s does not go on by one frame
        new = np.ones(len(sp), dtype=bool)
        new[1:] = (a_id[1:] != a_id[:-1]) | (frame[1:] != frame[:-1] + 1)
        acc, jerk = _differences(sp["v_ft_s"].to_numpy(np.float64), frame, np.cumsum(new))
        accs.append(acc)
        jerks.append(jerk)
    return np.concatenate(accs) / FT_PER_M, np.concatenate(jerks) / FT_PER_M


def demo_acc_jerk(encounters: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
    """The demonstrations' per-frame acceleration ``[M]`` (``acc_A``, m/s^2) and jerk ``[K]`` (m/s^3,
    the forward difference of ``acc_A`` over consecutive ``Frame_ID`` of one encounter; empty
    without ``encounter_id`` and ``Frame_ID`` columns)."""
    acc = encounters["acc_A"].to_numpy(np.float64) / FT_PER_M
    if not {"encounter_id", "Frame_ID"} <= set(encounters.columns) or encounters.empty:
        return acc, np.zeros(0)
    df = encounters.sort_values(["encounter_id", "Frame_ID"], kind="stable")
    a = df["acc_A"].to_numpy(np.float64) / FT_PER_M
    frame = df["Frame_ID"].to_numpy(np.int64)
    seg = df["encounter_id"].to_numpy(np.int64)
    step = (np.diff(frame) == 1) & (np.diff(seg) == 0)
    return acc, (np.diff(a) / FRAME_S)[step]


def w1_acc_jerk(profiles: Iterable[pd.DataFrame], encounters: pd.DataFrame) -> dict[str, float]:
    """``{"w1_acc_A_m_s2", "w1_jerk_A_m_s3"}``: Wasserstein-1 distances of A's per-frame
    acceleration and jerk while controlled (:func:`frame_acc_jerk` of the episodes' speed
    profiles) to the held-out demonstrations' (:func:`demo_acc_jerk`); NaN where either side has
    no sample."""
    acc, jerk = frame_acc_jerk(profiles)
    d_acc, d_jerk = demo_acc_jerk(encounters)
    return {"w1_acc_A_m_s2": wasserstein(acc, d_acc), "w1_jerk_A_m_s3": wasserstein(jerk, d_jerk)}
