"""Neighbour search inside one frame (lead / lag car, lane order) and lane numbering, without SUMO.

The fast paths (sorted Python lists + bisect, one searchsorted) are checked against a
brute-force search over random frames (ties and empty lanes included) and the floor rule.
"""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from sim.drivers.observe import lag_of, lead_of
from sim.runtime.hooks import FrameState
from sim.runtime.lanes import lane_numbers


def make_frame(lanes: np.ndarray, ys: np.ndarray) -> FrameState:
    v = lanes.size
    z = np.zeros(v)
    return FrameState(
        frame=10, time_s=1.0, sumo_ids=tuple(f"v{i}" for i in range(v)),
        vehicle_id=np.arange(1, v + 1), local_x=z, local_y=ys.astype(np.float64), global_x=ys.astype(np.float64),
        global_y=z, speed=z, acc=z, length=z + 15.0, width=z + 6.0, lane_id=lanes.astype(np.int64),
        v_class=np.full(v, 2),
    )


def brute_lead(frame, y_ref, lane, exclude):
    mask = (frame.lane_id == lane) & (frame.local_y > y_ref)
    for row in exclude:
        if row is not None:
            mask[row] = False
    rows = np.flatnonzero(mask)
    return None if rows.size == 0 else int(rows[np.argmin(frame.local_y[rows])])


def brute_lag(frame, y_ref, lane, max_gap):
    mask = (frame.lane_id == lane) & (frame.local_y < y_ref) & (frame.local_y >= y_ref - max_gap)
    rows = np.flatnonzero(mask)
    return None if rows.size == 0 else int(rows[np.argmax(frame.local_y[rows])])


@settings(max_examples=300, deadline=None)
@given(
    n=st.integers(0, 25),
    seed=st.integers(0, 2**32 - 1),
    y_ref=st.sampled_from([-1.0, 0.0, 10.0, 50.0, 99.0, 200.0]),
    max_gap=st.sampled_from([0.0, 10.0, 40.0, np.inf]),
)
def test_lead_and_lag_match_a_brute_force_search(n, seed, y_ref, max_gap):
    rng = np.random.default_rng(seed)
    lanes = rng.integers(5, 8, size=n)
    ys = rng.integers(0, 12, size=n) * 10.0  # coarse grid: many ties and exact hits of y_ref
    frame = make_frame(lanes, ys)
    exclude = tuple(int(r) for r in rng.choice(n, size=min(n, 2), replace=False)) if n else ()
    for lane in (5, 6, 7):
        assert lead_of(frame, y_ref, lane=lane, exclude=exclude) == brute_lead(frame, y_ref, lane, exclude)
        assert lead_of(frame, y_ref, lane=lane, exclude=(None,)) == brute_lead(frame, y_ref, lane, ())
        assert lag_of(frame, y_ref, lane=lane, max_gap_ft=max_gap) == brute_lag(frame, y_ref, lane, max_gap)


def test_lane_order_is_sorted_and_cached():
    frame = make_frame(np.array([6, 7, 6, 6]), np.array([30.0, 5.0, 10.0, 30.0]))
    ys, rows = frame.lane_order(6)
    assert ys == [10.0, 30.0, 30.0] and rows == [2, 0, 3]
    assert frame.lane_order(6) is frame.lane_order(6)
    assert frame.lane_order(3) == ([], [])


def test_lane_numbers_follow_the_floor_rule():
    """Lane k (0-based from the left) covers [k w, (k + 1) w); left of the road -> lane 1, right of
    the main lanes -> lane 7 (ramp / auxiliary)."""
    width_ft = 12.0
    x_ft = np.linspace(-30, 100, 1301)
    for n_main in (3, 6):
        k = [min(max(int(np.floor(x / width_ft)), 0), n_main) for x in x_ft]
        expected = [7 if j == n_main else 6 - n_main + 1 + j for j in k]
        np.testing.assert_array_equal(lane_numbers(x_ft, n_main, width_ft), expected)
    np.testing.assert_array_equal(lane_numbers(np.array([-5.0, 0.0, 6.0, 12.0, 18.0, 66.0, 72.0, 73.0]), 6, 12.0),
                                  [1, 1, 1, 2, 2, 6, 7, 7])
    np.testing.assert_array_equal(lane_numbers(np.array([6.0, 18.0, 40.0]), 3, 12.0), [4, 5, 7])
