"""The one observation a policy sees (sim.drivers.observe.policy_observation): the Gymnasium environment's,
a callable driver's and the exported transitions' policy_obs, without NaN, and read back by model
files turned into callables."""

from __future__ import annotations

import math

import numpy as np

from irl.planning.features import DEFAULT_LENGTH_FT
from sim.drivers.observe import (
    NO_LEAD_GAP_FT,
    POLICY_OBS_HIGH,
    MergeObservation,
    policy_observation,
    policy_rows,
    unfill_policy_row,
)


def _obs(d_ac: float, v_ac: float, len_c: float) -> MergeObservation:
    return MergeObservation(d_ac, -20.0, v_ac, 3.0, False, -1, 60.0, -1, -1, False, len_c, math.nan, 0.0, 0.0)


def test_no_lead_car_reads_as_a_far_car_at_a_speed_and_back() -> None:
    x = policy_observation(_obs(math.nan, math.nan, math.nan))
    assert np.isfinite(x).all()
    assert x[0] == NO_LEAD_GAP_FT and x[1] == 0.0 and x[5] == DEFAULT_LENGTH_FT and x[6] == DEFAULT_LENGTH_FT
    back = unfill_policy_row(x)
    assert math.isnan(back[0]) and math.isnan(back[1]) and math.isnan(back[5]) and back[2] == -20.0


def test_a_lead_car_is_passed_as_observed_and_clipped_to_the_bounds() -> None:
    x = policy_observation(_obs(80.0, -4.0, 15.0))
    np.testing.assert_array_equal(x[[0, 1, 2, 3, 4, 5]], [80.0, -4.0, -20.0, 3.0, 60.0, 15.0])
    np.testing.assert_array_equal(unfill_policy_row(x)[:6], x[:6])
    rows = policy_rows(np.array([[5e4, 1e3, 0.0, 0.0, 1e3, 1e3, 1e3]]))
    np.testing.assert_array_equal(rows[0], np.minimum([5e4, 1e3, 0.0, 0.0, 1e3, 1e3, 1e3], POLICY_OBS_HIGH))


def test_continuous_filled_is_the_policy_fill() -> None:
    o = _obs(math.nan, math.nan, math.nan)
    np.testing.assert_array_equal(o.continuous(filled=True)[0], policy_observation(o))
    assert np.isnan(o.continuous()[0, 0])
