"""The planning driver's decisions builders, driver file and pair replay
(irl/planning: decisions, driver, replay). No SUMO."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pandas as pd
import pytest
from irl_testdata import planning_encounters

from irl.domains.merge.actions import actions_of
from irl.domains.merge.car_following import car_following_decisions
from irl.errors import ConfigError, DemonstrationError, ModelFileError
from irl.planning.decisions import PlanningDecisions, encounter_decisions, pair_decisions, split_groups
from irl.planning.driver import PLANNER_FORMAT, PlanningDriver, learn_planning_driver
from irl.planning.model import PlannerConfig
from irl.planning.replay import ReplayPair, replay


def pair_frame(T: int = 40, v_f: float = 50.0, gap: float = 100.0, acc: float = 0.0) -> pd.DataFrame:
    t = 0.1 * np.arange(T)
    vf = v_f + acc * t
    return pd.DataFrame({"t": t, "x_follower": v_f * t + 0.5 * acc * t * t, "v_follower": vf,
                         "x_leader": gap + 50.0 * t, "v_leader": np.full(T, 50.0), "leader_length": 15.0})


def test_encounter_decisions_are_the_rows_learning_uses() -> None:
    df = planning_encounters()
    d = encounter_decisions(df)
    cf = car_following_decisions(df)
    np.testing.assert_array_equal(d.obs, cf.obs)
    np.testing.assert_array_equal(d.actions, cf.actions)
    known = np.isfinite(d.prev_acc)
    np.testing.assert_array_equal(actions_of(d.prev_acc[known]), cf.prev[known])
    assert d.groups.tolist() == sorted(d.groups.tolist()) and np.unique(d.groups).size == 4
    # first decision of an encounter: row 3; acc_C from rows 0 and 3 of the same C
    v_C = df.v_A - df.v_AC
    assert d.acc_C[0] == pytest.approx((v_C[3] - v_C[0]) / 0.3)
    assert d.acc[0] == pytest.approx(df.acc_A[3:6].mean()) and d.prev_acc[0] == pytest.approx(df.acc_A[0:3].mean())
    with pytest.raises(DemonstrationError, match="v_A"):
        encounter_decisions(df.drop(columns="v_A"), where="t.parquet")


def test_encounter_decisions_zero_acc_C_when_C_changes() -> None:
    df = planning_encounters(n=1, rows=31)
    df["C_id"] = np.where(np.arange(31) < 15, 1, 2)
    d = encounter_decisions(df)
    rows = 3 * np.arange(1, d.n + 1)
    crossing = (rows >= 15) & (rows - 3 < 15)
    assert crossing.any() and np.all(d.acc_C[crossing] == 0.0)


def test_pair_decisions_and_bad_input() -> None:
    d = pair_decisions([pair_frame(acc=2.0), pair_frame(T=31)], groups=["a", "a"])
    assert d.n == 12 + 9 and set(d.groups.tolist()) == {0}
    np.testing.assert_allclose(d.acc[:12], 2.0)
    np.testing.assert_allclose(d.prev_acc[:12], 2.0)
    assert np.all(d.actions[:12] == 3) and np.all(np.isnan(d.obs[:, 2]))
    np.testing.assert_allclose(d.obs[:12, 0], 100.0 + 50.0 * 0.1 * 3 * np.arange(1, 13)
                               - (50.0 * 0.3 * np.arange(1, 13) + 0.5 * 2.0 * (0.3 * np.arange(1, 13)) ** 2))
    with pytest.raises(DemonstrationError, match="missing column"):
        pair_decisions([pair_frame().drop(columns="v_leader")])
    bad = pair_frame()
    bad.loc[5, "v_follower"] = np.nan
    with pytest.raises(DemonstrationError, match=r"table 0, row 5, column 'v_follower'"):
        pair_decisions([bad])
    with pytest.raises(DemonstrationError, match="0.1 s apart"):
        pair_decisions([pair_frame().assign(t=lambda f: f.t * 2)])
    with pytest.raises(DemonstrationError, match="rows one decision needs"):
        pair_decisions([pair_frame(T=5)])
    with pytest.raises(DemonstrationError, match="actions must be"):
        PlanningDecisions(d.obs, d.prev_acc, d.acc_C, (d.actions + 1) % 5, d.acc, d.groups)
    tr, te = split_groups(np.repeat(np.arange(10), 3), 0.3, 0)
    assert te.sum() == 9 and not (tr & te).any()


def small_driver() -> tuple[PlanningDriver, PlanningDecisions]:
    d = encounter_decisions(planning_encounters(n=6))
    return learn_planning_driver(d, selection=PlannerConfig(grid="g13", horizon_s=0.9)), d


def test_learn_save_load_round_trip(tmp_path) -> None:
    drv, d = small_driver()
    assert drv.converged and np.isfinite(drv.loglik)
    path = drv.save(tmp_path / "planner.json")
    back = PlanningDriver.load(path)
    np.testing.assert_array_equal(back.theta, drv.theta)
    assert back.config == drv.config and back.shape == drv.shape
    np.testing.assert_allclose(back.bin_log_policy(d.obs, d.prev_acc, d.acc_C),
                               drv.bin_log_policy(d.obs, d.prev_acc, d.acc_C))
    b, a = drv.choose(d.obs[0], d.prev_acc[0], d.acc_C[0])
    assert b == actions_of(a) and a in drv.fine_grid
    b2, a2 = drv.choose(d.obs[0], 0.0, 0.0, mode=np.random.default_rng(0))
    assert b2 == actions_of(a2)
    data = json.loads(path.read_text())
    for change, field in (({"format": "merge-irl-planner/0"}, "format"), ({"theta": [1.0]}, "theta"),
                          ({"config": {**data["config"], "grid": "g7"}}, "config"),
                          ({"action_acc_ft_s2": [0, 1, 2, 3, "x"]}, "action_acc_ft_s2")):
        bad = tmp_path / "bad.json"
        bad.write_text(json.dumps({**data, **change}))
        with pytest.raises(ModelFileError, match=f"bad.json.*{field}"):
            PlanningDriver.load(bad)
    with pytest.raises(ModelFileError, match="no such"):
        PlanningDriver.load(tmp_path / "none.json")
    assert data["format"] == PLANNER_FORMAT


def test_learn_with_heldout_selection_is_deterministic() -> None:
    d = encounter_decisions(planning_encounters(n=8))
    opts = {"grids": ("g13",), "horizons": (0.9,), "gammas": (1.0,)}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        a, b = (learn_planning_driver(d, seed=3, select_options=opts) for _ in range(2))
    np.testing.assert_array_equal(a.theta, b.theta)
    assert a.config == b.config and len(a.info["selection"]) >= 3


def test_replay_on_a_tiny_pair() -> None:
    T = 60
    t = 0.1 * np.arange(T)
    same = ReplayPair("p", 50.0 * t, np.full(T, 50.0), 100.0 + 50.0 * t, np.full(T, 50.0), 15.0)
    res = replay([same], lambda o, p, a: np.zeros(o.shape[0]))
    assert res.rmse_m[0] < 1e-9 and not res.collided[0]
    stopped = ReplayPair("q", 50.0 * t, np.full(T, 50.0), np.full(T, 40.0), np.zeros(T), 15.0)
    res = replay([stopped, same], lambda o, p, a: np.zeros(o.shape[0]))
    assert res.collided.tolist() == [True, False] and res.summary()["collisions"] == 1
    seen = []

    def brake(o, p, a):  # prev_acc is what the driver applied last
        seen.append(p.copy())
        return np.full(o.shape[0], -3.0)

    replay([same], brake)
    assert seen[0][0] == 0.0 and seen[1][0] == -3.0
    with pytest.raises(DemonstrationError):
        ReplayPair("r", np.zeros(3), np.zeros(2), np.zeros(3), np.zeros(3), 15.0)


def test_lagged_driver_acts_with_its_lag_and_old_files_load(tmp_path) -> None:
    d = encounter_decisions(planning_encounters())
    cfg = PlannerConfig(horizon_s=0.9, grid="g13", jerk=False, free_road=True, lag=0.5, v0_ft_s=90.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        drv = learn_planning_driver(d, selection=cfg)
    assert drv.shape.v0_ft_s == 90.0 and "free_road" in drv.feature_names
    prev = np.full(d.n, 4.0)
    g = drv.fine_grid[np.argmax(drv.fine_log_policy(d.obs, prev, d.acc_C), axis=1)]
    np.testing.assert_allclose(drv.act(d.obs, prev, d.acc_C), 2.0 + 0.5 * g)
    b, a = drv.choose(d.obs[0], 4.0, d.acc_C[0])
    assert a == pytest.approx(2.0 + 0.5 * g[0]) and b == actions_of(a)
    back = PlanningDriver.load(drv.save(tmp_path / "lag.json"))
    assert back.config == drv.config
    # a file written before the optional config keys existed loads with their defaults
    old = learn_planning_driver(d, selection=PlannerConfig(grid="g13", horizon_s=0.9, jerk=True))
    data = old.to_json_dict()
    for k in ("jerk", "free_road", "lag", "v0_ft_s", "jerk_weight"):
        del data["config"][k]
    (tmp_path / "old.json").write_text(json.dumps(data))
    assert PlanningDriver.load(tmp_path / "old.json").config == old.config and "jerk" in old.feature_names
    assert not PlannerConfig().jerk  # the default reward has no action history (the copycat; see the driver)


def test_step_reward_is_the_first_step_of_a_planner_path() -> None:
    from dataclasses import replace

    from irl.planning.features import Shape
    from irl.planning.model import _paths_chunk, first_step

    cfg = PlannerConfig()
    obs = np.array([[80.0, 5.0, 30.0, -2.0, 60.0, 15.0, 15.0], [np.nan, np.nan, -20.0, 3.0, 60.0, np.nan, 15.0]])
    acc = np.array([-3.0, 2.0])
    phi, col = first_step(obs, np.zeros(2), np.zeros(2), acc, Shape(), cfg)
    # a whole path (acceleration held) discounted to almost nothing after its first step
    leaves = np.repeat(acc[:, None, None], 3, axis=2)
    path_phi, _ = _paths_chunk(obs, np.zeros(2), np.zeros(2), leaves, Shape(), replace(cfg, gamma=1e-12))
    np.testing.assert_allclose(phi, path_phi[:, 0, :], rtol=1e-9, atol=1e-9)
    assert phi.shape == (2, len(cfg.feature_names)) and not col.any()
    with pytest.raises(ConfigError):
        first_step(obs, np.zeros(3), np.zeros(2), acc, Shape(), cfg)
