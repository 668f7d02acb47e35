"""Observe the merge variables of car A (with merging car B and lead car C) in a frame.

Conventions (the paper's section 4.2, as in ``sim.merges.encounters``; NGSIM units):

* ``d_AC = Local_Y(C) - Local_Y(A)`` and ``d_AB = Local_Y(B) - Local_Y(A)`` (ft, front bumper
  to front bumper along the road; positive when the other car is ahead of A).
* ``v_AC = v(A) - v(C)`` and ``v_AB = v(A) - v(B)`` (ft/s; positive when A is faster).
* ``B_is_truck``: B's NGSIM class is 3.

When there is no lead car C, ``d_AC`` and ``v_AC`` are NaN: the no-lead-car rule of
:mod:`irl.domains.merge.bins`, whose :class:`~irl.domains.merge.bins.MergeBins` encodes the state with
the model's saved bin edges (state = 625 truck + 125 x1 + 25 x2 + 5 x3 + x4).
"""

from __future__ import annotations

import math
from bisect import bisect_left, bisect_right
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from irl.domains.merge.car_following import OBS_COLUMNS
from sim.runtime.hooks import FrameState
from sim.runtime.schema import RIGHTMOST_MAIN_LANE, V_CLASS_TRUCK

#: The columns of :meth:`MergeObservation.continuous` (the observation a policy callable, the
#: exported transitions and the car-following and planning drivers see), in order: the encounter
#: table's names (:data:`irl.domains.merge.car_following.OBS_COLUMNS`).
CONTINUOUS_NAMES: tuple[str, ...] = tuple(OBS_COLUMNS)
#: The unit of each of :data:`CONTINUOUS_NAMES` (NGSIM's feet; ``d_AC``, ``v_AC`` and ``len_C``
#: NaN without a lead car C, a length NaN when unknown).
CONTINUOUS_UNITS: tuple[str, ...] = ("ft", "ft/s", "ft", "ft/s", "ft/s", "ft", "ft")
#: ``d_AC`` (ft) of the filled continuous observation without a lead car C
#: (:meth:`MergeObservation.continuous`): farther than any car-following interaction at freeway
#: speeds (about 10 s at 100 ft/s), shorter than the section.
NO_LEAD_GAP_FT = 1000.0
#: Bounds of the policy observation (columns of :data:`CONTINUOUS_NAMES`; ft, ft/s): wider than
#: any section and freeway speed; :func:`policy_rows` clips to them (no test run reached them).
POLICY_OBS_LOW = np.array([-1e4, -300.0, -1e4, -300.0, 0.0, 0.0, 0.0])
POLICY_OBS_HIGH = np.array([1e4, 300.0, 1e4, 300.0, 300.0, 200.0, 200.0])


def fill_policy_rows(rows: np.ndarray) -> np.ndarray:
    """``[N, 7] -> [N, 7]``: continuous observation rows (:data:`CONTINUOUS_NAMES`) without NaN.

    No lead car C (``d_AC`` or ``v_AC`` not finite) reads as a car :data:`NO_LEAD_GAP_FT` ahead at
    A's speed (``v_AC = 0``); an unknown length (``len_C`` without C too) as the planning driver's
    :data:`irl.planning.features.DEFAULT_LENGTH_FT` (4.5 m); any other NaN as 0.
    A copy; ``rows`` is not changed.
    """
    from irl.planning.features import DEFAULT_LENGTH_FT  # scipy: only when asked

    out = np.array(rows, dtype=np.float64, copy=True).reshape(-1, len(CONTINUOUS_NAMES))
    no_c = ~(np.isfinite(out[:, 0]) & np.isfinite(out[:, 1]))
    out[no_c, 0], out[no_c, 1], out[no_c, 5] = NO_LEAD_GAP_FT, 0.0, DEFAULT_LENGTH_FT
    out[:, 5:7] = np.where(np.isfinite(out[:, 5:7]), out[:, 5:7], DEFAULT_LENGTH_FT)
    return np.nan_to_num(out, nan=0.0, posinf=0.0, neginf=0.0)


def policy_rows(rows: np.ndarray) -> np.ndarray:
    """``[N, 7] -> [N, 7]`` float64: what a policy sees of continuous observation rows, the one
    contract of the Gymnasium environment (:mod:`sim.env`), a callable driver
    (:mod:`sim.drivers.callables`) and the exported transitions' ``policy_obs``
    (:mod:`sim.merges.transitions`): :func:`fill_policy_rows`, clipped to
    :data:`POLICY_OBS_LOW`..:data:`POLICY_OBS_HIGH`. ft and ft/s, columns :data:`CONTINUOUS_NAMES`.
    """
    return np.clip(fill_policy_rows(rows), POLICY_OBS_LOW, POLICY_OBS_HIGH)


def policy_observation(obs: MergeObservation) -> np.ndarray:
    """``[7]`` float64: what a policy sees of ``obs`` (:func:`policy_rows` of its continuous row)."""
    return policy_rows(obs.continuous())[0]


def unfill_policy_row(x: np.ndarray) -> np.ndarray:
    """``[7] -> [7]``: a policy observation back to a continuous row, ``d_AC``/``v_AC``/``len_C``
    NaN where it reads as no lead car C (``d_AC >= NO_LEAD_GAP_FT``). A copy."""
    out = np.array(x, dtype=np.float64, copy=True).reshape(-1)
    if out.size == len(CONTINUOUS_NAMES) and out[0] >= NO_LEAD_GAP_FT:
        out[0] = out[1] = out[5] = math.nan
    return out


@dataclass(frozen=True)
class MergeObservation:
    """What car A sees at one decision step.

    Attributes:
        d_AC, d_AB: gaps (ft); v_AC, v_AB: relative speeds (ft/s); see the module docstring
            (d_AC and v_AC NaN without car C).
        b_is_truck: whether B is a truck.
        state: discrete state index in ``[0, 1250)`` (-1 when no encoder was given).
        speed_A: A's speed (ft/s): logged, and the car-following logit driver's input.
        prev_action: A's action at the previous decision of this control episode (-1: none).
        initial_action: before the first decision, the bin of A's acceleration over the last
            simulation step (how the driver encoding and the car-following driver take A's
            previous action there, as training takes it from A's speed history); -1 afterwards
            or when not finite.
        b_merged: B has entered lane 6 (the controller's merge frame is behind this decision).
        len_C, len_B: the lengths of C and B (ft; NaN: unknown, or no C). ``d_AC - len_C`` is the
            bumper gap A follows C at; the car-following logit driver's input.
        acc_prev: A's acceleration over the previous decision (ft/s^2): what the controller
            applied; before the first decision, A's acceleration over the last simulation step
            (NaN: not known).
        acc_C: C's acceleration as A sees it (ft/s^2): C's speed change over the previous
            decision divided by its length, as a driver sees brake lights; 0 at the first
            decision, without C, or when C is another car than at the previous decision.
    """

    d_AC: float
    d_AB: float
    v_AC: float
    v_AB: float
    b_is_truck: bool
    state: int = -1
    speed_A: float = 0.0
    prev_action: int = -1
    initial_action: int = -1
    b_merged: bool = False
    len_C: float = math.nan
    len_B: float = math.nan
    acc_prev: float = math.nan
    acc_C: float = 0.0

    def continuous(self, *, filled: bool = False) -> np.ndarray:
        """``[1, 7]``: ``d_AC, v_AC, d_AB, v_AB, v_A, len_C, len_B`` (ft, ft/s), the continuous
        observation of the car-following and planning drivers
        (:data:`irl.domains.merge.car_following.OBS_COLUMNS`), as one row.

        ``filled=True``: without NaN (:func:`fill_policy_rows`); what a policy sees is
        :func:`policy_observation`."""
        row = np.array([[self.d_AC, self.v_AC, self.d_AB, self.v_AB, self.speed_A, self.len_C, self.len_B]],
                       dtype=np.float64)
        return fill_policy_rows(row) if filled else row


def observe(frame: FrameState, ia: int, ib: int, ic: int | None) -> tuple[float, float, float, float, bool]:
    """The merge variables at ``frame`` for rows ``ia`` (A), ``ib`` (B), ``ic`` (C or None).

    Returns ``(d_AC, d_AB, v_AC, v_AB, B_is_truck)``.
    """
    ya, va = float(frame.local_y[ia]), float(frame.speed[ia])
    d_ab = float(frame.local_y[ib]) - ya
    v_ab = va - float(frame.speed[ib])
    if ic is None:
        d_ac = v_ac = math.nan
    else:
        d_ac = float(frame.local_y[ic]) - ya
        v_ac = va - float(frame.speed[ic])
    return d_ac, d_ab, v_ac, v_ab, bool(frame.v_class[ib] == V_CLASS_TRUCK)


def lag_lead_positions(ys: Sequence[float], y_b: float) -> tuple[int, int]:
    """The one A/C selection rule of the merge (shared by :mod:`sim.merges.encounters` and the
    closed-loop controller): in ``ys`` (the lane-6 ``Local_Y`` values, ascending, ft), the
    position of the lag car A (the last one strictly behind B's ``y_b``) and of the lead car C
    (the first one strictly ahead of it); -1 where there is none. A car level with B is
    neither."""
    lag = bisect_left(ys, y_b) - 1
    lead = bisect_right(ys, y_b)
    return lag, (lead if lead < len(ys) else -1)


def lead_of(frame: FrameState, y_ref: float, *, lane: int = RIGHTMOST_MAIN_LANE, exclude: Sequence[int | None] = ()) -> int | None:
    """Row of the nearest vehicle in ``lane`` strictly ahead of ``y_ref`` (ft), or None.

    Rows in ``exclude`` are skipped; among vehicles at the same position the lowest row wins.
    """
    ys, rows = frame.lane_order(lane)
    for k in range(bisect_right(ys, y_ref), len(rows)):
        if rows[k] not in exclude:
            return rows[k]
    return None


def lag_of(frame: FrameState, y_ref: float, *, lane: int = RIGHTMOST_MAIN_LANE, max_gap_ft: float = np.inf) -> int | None:
    """Row of the nearest vehicle in ``lane`` strictly behind ``y_ref`` within ``max_gap_ft``, or
    None (the lag car A of :func:`lag_lead_positions`).

    Among vehicles at the same position the lowest row wins.
    """
    ys, rows = frame.lane_order(lane)
    k, _ = lag_lead_positions(ys, y_ref)
    if k < 0 or ys[k] < y_ref - max_gap_ft:
        return None
    while k > 0 and ys[k - 1] == ys[k]:
        k -= 1
    return rows[k]
