"""The correction figures: bin matches, the response to a 20 % gap error, the replay's commands,
sign changes and W1 of acceleration and jerk."""

import numpy as np
import pandas as pd
import pytest

from analysis.calibration.corrections import (
    bin_match,
    gap_error_response,
    idm_acc_ft_s2,
    idm_desired_gap_ft,
    median_gap_ft,
    planner_desired_gap_ft,
    recorded_commands,
    replay_commands,
    sign_changes,
    w1_acc_jerk,
)
from analysis.calibration.models import SUMO_DEFAULTS, CFParams
from irl.planning.decisions import pair_decisions
from irl.planning.features import Shape
from irl.planning.replay import ReplayPair, replay
from merge_irl.units import FT_PER_M


def pair_frame(T: int, v_f: float, gap: float, acc: float = 0.0) -> pd.DataFrame:
    t = 0.1 * np.arange(T)
    v = np.maximum(v_f + acc * t, 0.0)
    x = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * 0.1)])
    return pd.DataFrame({"t": t, "x_follower": x, "v_follower": v, "x_leader": x + gap + 15.0 + 2.0 * t,
                         "v_leader": v + 2.0, "leader_length": 15.0})


def decisions():
    # pair 0: gap 100 ft and braking; pair 1: gap 40 ft and steady
    return pair_decisions([pair_frame(40, 50.0, 100.0, acc=-3.0), pair_frame(40, 50.0, 40.0)], 0.3)


def test_bin_match_counts_the_persons_bins():
    dec = decisions()
    assert bin_match(dec, dec.acc) == (dec.n, dec.n)
    zero = bin_match(dec, np.zeros(dec.n))
    assert zero == (int(np.sum(dec.actions == 2)), dec.n) and zero[0] < dec.n
    with pytest.raises(ValueError):
        bin_match(dec, np.zeros(dec.n + 1))


def test_gap_error_response_selects_the_decisions_20_percent_off():
    dec = decisions()
    gap = dec.obs[:, 0] - dec.obs[:, 5]
    want = np.where(dec.groups == 0, gap / 1.5, gap * 1.1)  # pair 0 50 % off, pair 1 10 % off
    acc = np.where(dec.groups == 0, 6.0, -9.0)
    r = gap_error_response(dec, acc, want)
    assert r.n_off == int(np.sum(dec.groups == 0)) and r.n == dec.n
    assert r.driver_abs_acc_ft_s2 == pytest.approx(6.0)
    assert r.recorded_abs_acc_ft_s2 == pytest.approx(np.mean(np.abs(dec.acc[dec.groups == 0])))
    assert 0 < r.share_off < 1
    none = gap_error_response(dec, acc, gap)
    assert none.n_off == 0 and np.isnan(none.driver_abs_acc_ft_s2)
    with pytest.raises(ValueError):
        gap_error_response(dec, acc, want, tolerance=0.0)


def test_desired_gaps():
    dec = decisions()
    np.testing.assert_allclose(planner_desired_gap_ft(dec, Shape(s0_ft=10.0, T_s=2.0)), 10.0 + 2.0 * dec.obs[:, 4])
    med = median_gap_ft(dec)
    assert len(np.unique(med)) == 2
    slow = CFParams(maxSpeed=1000.0, delta=4.0)
    v_m = dec.obs[:, 4] / FT_PER_M
    np.testing.assert_allclose(idm_desired_gap_ft(dec, [slow] * dec.n), (2.5 + v_m) * FT_PER_M, rtol=1e-6)
    assert np.isnan(idm_desired_gap_ft(dec, [CFParams(maxSpeed=1.0)] * dec.n)).all()


def test_idm_brakes_when_close_and_accelerates_when_far():
    far = pair_decisions([pair_frame(40, 20.0, 400.0)], 0.3)
    close = pair_decisions([pair_frame(40, 50.0, 10.0)], 0.3)
    assert (idm_acc_ft_s2(far, [SUMO_DEFAULTS] * far.n) > 0).all()
    assert (idm_acc_ft_s2(close, [SUMO_DEFAULTS] * close.n) < 0).all()


def test_replay_commands_are_the_replays_own():
    T = 40
    t = 0.1 * np.arange(T)
    pairs = [ReplayPair(f"p{n}", 50.0 * t[:n], np.full(n, 50.0), 100.0 + 50.0 * t[:n], np.full(n, 50.0), 15.0)
             for n in (T, 20)]

    calls: list[int] = []

    def act(o, p, a):  # alternate signs per call: each series flips every decision
        calls.append(o.shape[0])
        return np.full(o.shape[0], 1.0 if len(calls) % 2 else -1.0)

    res, series = replay_commands(pairs, act, 0.3)
    calls.clear()
    np.testing.assert_array_equal(res.rmse_m, replay(pairs, act, 0.3).rmse_m)
    assert [s.size for s in series] == [13, 7]  # frames 0, 3, ... while a frame follows
    assert series[0][0] == 1.0 and series[0][1] == -1.0
    np.testing.assert_array_equal(series[1], series[0][:7])
    assert sign_changes(series) == (12 + 6, 12 + 6)
    assert sign_changes([np.array([1.0, 0.0, -1.0, -2.0, 3.0])]) == (1, 4)


def test_recorded_commands_and_w1():
    T = 31
    t = 0.1 * np.arange(T)
    v = 50.0 + 3.0 * t  # 3 ft/s^2 throughout
    p = ReplayPair("p", np.cumsum(v) * 0.1, v, 500.0 + 60.0 * t, np.full(T, 60.0), 15.0)
    rec = recorded_commands([p], 0.3)
    assert rec[0].size == 10
    np.testing.assert_allclose(rec[0], 3.0)
    w_acc, w_jerk = w1_acc_jerk(rec, [np.zeros(10)], 0.3)
    assert w_acc == pytest.approx(3.0 / FT_PER_M) and w_jerk == pytest.approx(0.0)
    _, w_jerk = w1_acc_jerk([np.array([0.0, 3.0])], [np.array([0.0, 0.0])], 0.3)
    assert w_jerk == pytest.approx(10.0 / FT_PER_M)
    assert np.isnan(w1_acc_jerk([], rec, 0.3)[0])
