"""The planning driver fitted by what its driving does (irl.planning.replay_fit):
the gap-tracking feature, the replay fit on pairs of a known follower, the temperature, the
bootstrap intervals and the refusals."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from irl.domains.merge.actions import actions_of
from irl.errors import ConfigError, DemonstrationError
from irl.planning.decisions import PlanningDecisions
from irl.planning.features import CLIP_TRACK, Shape, feature_names, gap_track
from irl.planning.model import PlannerConfig
from irl.planning.replay import ReplayPair, replay
from irl.planning.replay_fit import (
    ReplayFitConfig,
    bootstrap_intervals,
    build_driver,
    fit_by_replay,
    fit_temperature,
    replay_objective,
)

ACC5 = (-8.0, -2.7, 0.0, 2.7, 8.0)


def test_gap_tracking_is_symmetric_zero_at_the_desired_gap_and_bounded():
    shape = Shape(s0_ft=10.0, T_s=1.5)
    v = np.array([40.0])
    s_d = 10.0 + 1.5 * 40.0
    on = np.array([True])
    assert gap_track(np.array([s_d]), v, on, shape)[0] == 0.0
    close, far = gap_track(np.array([0.5 * s_d]), v, on, shape), gap_track(np.array([1.5 * s_d]), v, on, shape)
    assert close[0] == pytest.approx(0.25) and far[0] == pytest.approx(0.25)  # falling behind costs as much
    assert gap_track(np.array([10 * s_d]), v, on, shape)[0] == CLIP_TRACK
    assert gap_track(np.array([0.5 * s_d]), v, np.array([False]), shape)[0] == 0.0
    assert feature_names(False, False, False, True)[8:10] == ("gap_track_C", "gap_track_B")
    assert "gap_track_C" not in PlannerConfig().feature_names  # off by default: earlier files keep meaning


def _cth_pairs(n: int, T: float, seed: int) -> list[ReplayPair]:
    """Pairs whose follower keeps a constant time headway ``T`` behind a leader that slows down
    and speeds up (ft, ft/s, 0.1 s): a known driver to recover."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        steps = 600
        t = np.arange(steps) * 0.1
        v_l = 45.0 + 12.0 * np.sin(2 * np.pi * t / rng.uniform(25, 45) + rng.uniform(0, 6))
        x_l = 200.0 + np.concatenate([[0.0], np.cumsum(0.1 * 0.5 * (v_l[1:] + v_l[:-1]))])
        x_f, v_f = np.empty(steps), np.empty(steps)
        x_f[0], v_f[0] = x_l[0] - 15.0 - (8.0 + T * v_l[0]), v_l[0]
        for k in range(steps - 1):
            gap = x_l[k] - 15.0 - x_f[k]
            a = np.clip(0.6 * (gap - 8.0 - T * v_f[k]) + 1.2 * (v_l[k] - v_f[k]), -15.0, 8.0)
            v_f[k + 1] = max(v_f[k] + a * 0.1, 0.0)
            x_f[k + 1] = x_f[k] + 0.5 * (v_f[k] + v_f[k + 1]) * 0.1
        out.append(ReplayPair(f"p{i}", x_f, v_f, x_l, v_l, 15.0))
    return out


def test_the_replay_fit_moves_towards_the_recorded_followers_gap():
    pairs = _cth_pairs(6, T=2.0, seed=0)
    cfg = ReplayFitConfig(max_evals=18, free=("gap_track_C",), shape_free=("T_s",))
    fit = fit_by_replay(pairs, Shape(v0_ft_s=70.0), ACC5, cfg)
    assert fit.objective < fit.start_objective  # it learned something from the driving
    assert fit.params["T_s"] > 1.3  # from the 1.2 s start towards the followers' 2 s
    assert fit.n_evals <= 18 + 1 and fit.driver.info["fit"] == "replay"
    assert fit.params["gap_track_C"] < 0  # a cost stays a cost
    again = fit_by_replay(pairs, Shape(v0_ft_s=70.0), ACC5, cfg)
    assert again.objective == fit.objective and again.params == fit.params  # deterministic
    res = replay(pairs, fit.driver.act, 0.3)
    assert replay_objective(res, cfg.collision_cost_m, cfg.criterion) == pytest.approx(fit.objective)


def test_the_merging_cars_terms_take_the_lead_cars_weights():
    cfg = ReplayFitConfig()
    drv = build_driver(cfg, {"gap_track_C": -3.0, "inv_ttc_C": -2.0, "speed_dev": -1.0}, {"T_s": 1.4}, Shape(), ACC5)
    w = dict(zip(drv.feature_names, drv.theta))
    assert w["gap_track_B"] == w["gap_track_C"] == -3.0 and w["inv_ttc_B"] == -2.0 and w["comfort"] == -1.0
    assert drv.shape.T_s == 1.4
    untied = build_driver(replace(cfg, tie_B=False), {"gap_track_C": -3.0}, {}, Shape(), ACC5)
    assert dict(zip(untied.feature_names, untied.theta))["gap_track_B"] == 0.0


def test_the_temperature_raises_the_likelihood_and_keeps_the_most_likely_action():
    pairs = _cth_pairs(3, T=1.5, seed=1)
    drv = build_driver(ReplayFitConfig(), {"gap_track_C": -2.0, "inv_ttc_C": -1.0, "speed_dev": -1.0}, {"T_s": 1.5},
                       Shape(v0_ft_s=70.0), ACC5)
    rows = []
    for p in pairs:  # decisions of the recorded followers, every 0.3 s
        k = np.arange(0, p.x_follower.size - 3, 3)
        acc = (p.v_follower[k + 3] - p.v_follower[k]) / 0.3
        obs = np.column_stack([p.x_leader[k] - p.x_follower[k], p.v_follower[k] - p.v_leader[k],
                               np.full(k.size, np.nan), np.full(k.size, np.nan), p.v_follower[k],
                               np.full(k.size, 15.0), np.full(k.size, np.nan)])
        rows.append((obs, np.r_[0.0, acc[:-1]], np.zeros(k.size), acc))
    obs, prev, acc_c, acc = (np.concatenate([r[j] for r in rows]) for j in range(4))
    dec = PlanningDecisions(obs, prev, acc_c, actions_of(acc), acc, np.zeros(acc.size, dtype=np.int64), 0.3)
    fitted, ll = fit_temperature(drv, dec, chunk=50)
    assert ll >= drv.heldout_ll_per_decision(dec) - 1e-9
    assert ll == pytest.approx(fitted.heldout_ll_per_decision(dec))
    assert fitted.config.temperature != 1.0 and fitted.info["temperature"] == fitted.config.temperature
    np.testing.assert_array_equal(fitted.act(obs, prev, acc_c), drv.act(obs, prev, acc_c))


def test_bootstrap_intervals_bracket_each_fitted_parameter():
    pairs = _cth_pairs(4, T=2.0, seed=2)
    cfg = ReplayFitConfig(max_evals=6, free=("gap_track_C",), shape_free=("T_s",))
    fit = fit_by_replay(pairs, Shape(v0_ft_s=70.0), ACC5, cfg)
    iv = bootstrap_intervals(pairs, ["a", "b", "c", "d"], fit, Shape(v0_ft_s=70.0), ACC5, cfg, n_boot=3, evals=4)
    assert set(iv) == {"gap_track_C", "T_s"}
    assert all(lo <= hi for lo, hi in iv.values())
    with pytest.raises(DemonstrationError, match="one group per pair"):
        bootstrap_intervals(pairs, ["a"], fit, Shape(), ACC5, cfg)


def test_bad_settings_are_refused():
    with pytest.raises(ConfigError, match="not one of the planner's"):
        ReplayFitConfig(free=("gap_track_C", "bias_high_brake"))
    with pytest.raises(ConfigError, match="comfort is the scale"):
        ReplayFitConfig(free=("comfort",))
    with pytest.raises(ConfigError, match="shape parameter 'a_ft_s2'"):
        ReplayFitConfig(shape_free=("a_ft_s2",))
    with pytest.raises(ConfigError, match="temperature must be"):
        PlannerConfig(temperature=0.0)
    with pytest.raises(DemonstrationError, match="no pairs"):
        fit_by_replay([], Shape(), ACC5)
    with pytest.raises(ConfigError, match="criterion must be one of"):
        ReplayFitConfig(criterion="max")


def test_the_criteria_are_the_statistics_they_name():
    from irl.planning.replay import ReplayResult

    r = ReplayResult(("a", "b", "c"), np.array([1.0, 2.0, 6.0]), np.array([False, False, True]), np.ones(3))
    assert replay_objective(r, 10.0, "mean") == pytest.approx(19.0 / 3)
    assert replay_objective(r, 10.0, "median") == 2.0
    assert replay_objective(r, 10.0, "mean+median") == pytest.approx(0.5 * (19.0 / 3 + 2.0))
