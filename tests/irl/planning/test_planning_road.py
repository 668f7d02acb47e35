"""The planner's road model (irl/planning/model.py ``road_model``): the safe-distance condition,
the margin while closing, B ahead as a leader, and old files loading with the legacy model. No SUMO."""

from __future__ import annotations

import json
from dataclasses import asdict, replace

import numpy as np
import pytest

from irl.errors import ConfigError
from irl.planning.driver import PlanningDriver
from irl.planning.features import Shape, closing_margin, min_gap_braking
from irl.planning.model import PlannerConfig, first_step, path_tensors
from merge_irl.units import FT_PER_M

ACC = (-9.5, -2.2, 0.05, 2.3, 6.0)
NAN = float("nan")
DRIVER = PlannerConfig()
LEGACY = replace(PlannerConfig(), road_model="legacy")


def obs_row(d_AC=NAN, v_AC=NAN, d_AB=NAN, v_AB=NAN, v_A=60.0, len_C=NAN, len_B=NAN) -> np.ndarray:
    return np.array([[d_AC, v_AC, d_AB, v_AB, v_A, len_C, len_B]], dtype=np.float64)


def step_col(obs: np.ndarray, acc: float, config: PlannerConfig, acc_C: float = 0.0) -> float:
    _, col = first_step(obs, np.zeros(1), np.array([acc_C]), np.array([acc]), Shape(), config)
    return float(col[0])


def test_driver_model_is_the_default_and_its_settings_are_checked() -> None:
    assert DRIVER.road_model == "driver"
    assert DRIVER.c_brake_ft_s2 == pytest.approx(4.5 * FT_PER_M)
    assert DRIVER.margin_ft == pytest.approx(FT_PER_M)
    for bad in ({"road_model": "sumo"}, {"c_brake_ft_s2": 0.0}, {"margin_ft": -1.0}, {"margin_ft": True}):
        with pytest.raises(ConfigError):
            PlannerConfig(**bad)


def test_min_gap_braking_by_hand() -> None:
    # equal speeds, follower brakes harder: the gap never closes
    assert float(min_gap_braking(np.array(30.0), 60.0, 60.0, 28.0, 14.0)) == pytest.approx(30.0)
    # follower 10 ft/s faster, brakes 14 ft/s^2 harder: closes 10^2 / (2 * 14) ft before the speeds meet
    assert float(min_gap_braking(np.array(30.0), 70.0, 60.0, 28.0, 14.0)) == pytest.approx(30.0 - 100 / 28)
    # equal decelerations: the closing speed holds until the leader stops; minimum at the follower's stop
    assert float(min_gap_braking(np.array(30.0), 70.0, 56.0, 28.0, 28.0)) == pytest.approx(
        30.0 + 56.0 ** 2 / 56 - 70.0 ** 2 / 56)
    # a stopped leader: the follower's stopping distance
    assert float(min_gap_braking(np.array(30.0), 28.0, 0.0, 28.0, 14.0)) == pytest.approx(30.0 - 14.0)


def test_safe_distance_hand_case_accelerating_unsafe_braking_hard_safe() -> None:
    """A at 20 m/s, C 10 m ahead (front to front, a 4.5 m car) at 20 m/s, seen braking hard
    (-28 ft/s^2). After a +9 ft/s^2 first step (0.3 s) A is at 20.09 ft, 68.32 ft/s; C at
    18.43 ft, 57.22 ft/s; bumper gap 16.38 ft; both braking at 28 ft/s^2 the closing speed holds
    and the stopping gap is 16.38 + 57.22^2/56 - 68.32^2/56 = -8.5 ft: unsafe. Braking hard
    (-28) from the start keeps the gap at 18.04 ft: safe."""
    v = 20.0 * FT_PER_M
    obs = obs_row(d_AC=10.0 * FT_PER_M, v_AC=0.0, v_A=v, len_C=4.5 * FT_PER_M)
    v_A1, x_A1 = v + 9 * 0.3, v * 0.3 + 0.5 * 9 * 0.09
    v_C1, x_C1 = v - 28 * 0.3, v * 0.3 - 0.5 * 28 * 0.09
    assert 5.5 * FT_PER_M + x_C1 - x_A1 + v_C1 ** 2 / 56 - v_A1 ** 2 / 56 == pytest.approx(-8.5, abs=0.05)
    assert step_col(obs, 9.0, DRIVER, acc_C=-28.0) == 1.0  # the step itself ends 16 ft behind C: unsafe only
    assert step_col(obs, 0.0, DRIVER, acc_C=-28.0) == 1.0
    assert step_col(obs, -28.0, DRIVER, acc_C=-28.0) == 0.0
    assert step_col(obs, 9.0, LEGACY, acc_C=-28.0) == 0.0  # the legacy model sees no danger
    # C not seen braking: it may still brake at 4.5 m/s^2, which a +9 first step survives
    assert step_col(obs, 9.0, DRIVER, acc_C=0.0) == 0.0
    # the path tensors carry it: every path of an unsafe first action counts it, while braking
    # hard has a path without a collision (holding it)
    T = path_tensors(obs, np.zeros(1), np.array([-28.0]), ACC, Shape(), DRIVER)
    grid = DRIVER.fine_grid(np.asarray(ACC))
    assert T.Col[0, grid == 9.0].min() >= 1.0 and T.Col[0, grid == -28.0].min() == 0.0


def test_margin_counts_only_while_the_gap_closes() -> None:
    m = DRIVER.margin_ft
    assert closing_margin(np.array(2.0), 5.0, 0.0, np.array(True), m)  # small and closing
    assert not closing_margin(np.array(2.0), 0.0, 5.0, np.array(True), m)  # small but opening
    assert not closing_margin(np.array(5.0), 5.0, 0.0, np.array(True), m)  # closing, above the margin
    assert closing_margin(np.array(-1.0), 0.0, 5.0, np.array(True), m)  # contact
    assert not closing_margin(np.array(-1.0), 5.0, 0.0, np.array(False), m)  # no leader
    # A stopped 2 ft behind a stopped C: holding costs nothing, creeping forward counts
    obs = obs_row(d_AC=17.0, v_AC=0.0, v_A=0.0, len_C=15.0)
    assert step_col(obs, 0.0, DRIVER) == 0.0
    assert step_col(obs, 4.0, DRIVER) >= 1.0
    assert step_col(obs, 4.0, LEGACY) == 0.0
    # C pulling away from 2 ft: A may start as long as it stays slower
    assert step_col(obs_row(d_AC=17.0, v_AC=-8.0, v_A=0.0, len_C=15.0), 4.0, DRIVER, acc_C=0.0) == 0.0


def test_b_ahead_is_a_leader_and_never_driven_through() -> None:
    # no C; B stopped 40 ft (bumper) ahead of A at 40 ft/s: braking hard now stops A 11 ft short
    obs = obs_row(d_AB=55.0, v_AB=40.0, v_A=40.0, len_B=15.0)
    assert step_col(obs, 9.0, DRIVER) >= 1.0
    assert step_col(obs, -28.0, DRIVER) == 0.0
    assert step_col(obs, 9.0, LEGACY) == 0.0
    grid = DRIVER.fine_grid(np.asarray(ACC))
    T_new = path_tensors(obs, np.zeros(1), np.zeros(1), ACC, Shape(), DRIVER)
    T_old = path_tensors(obs, np.zeros(1), np.zeros(1), ACC, Shape(), LEGACY)
    assert np.all(T_new.Col[0, grid == 9.0] >= 1.0) and np.all(T_old.Col == 0.0)
    # past B in the nominal prediction: the legacy features forget it, the driver's do not
    j = DRIVER.feature_names.index("gap_need_B")
    assert np.all(T_new.Phi[0, grid == 9.0, ..., j] > T_old.Phi[0, grid == 9.0, ..., j])
    # B alongside (bumper gap not positive at the observation, the other lane): no collision partner
    assert step_col(obs_row(d_AB=5.0, v_AB=0.0, v_A=40.0, len_B=15.0), 0.0, DRIVER) == 0.0
    # B stopped beside C (its front beyond C's rear): not between A and C, so C is the leader
    beside_C = obs_row(d_AC=200.0, v_AC=0.0, d_AB=190.0, v_AB=40.0, v_A=40.0, len_C=15.0, len_B=15.0)
    between = obs_row(d_AC=200.0, v_AC=0.0, d_AB=55.0, v_AB=40.0, v_A=40.0, len_C=15.0, len_B=15.0)
    T_beside = path_tensors(beside_C, np.zeros(1), np.zeros(1), ACC, Shape(), DRIVER)
    assert np.all(T_beside.Phi[0, ..., j] == 0.0) and np.all(T_beside.Col == 0.0)
    assert step_col(between, 9.0, DRIVER) >= 1.0


def legacy_file_of(driver: PlanningDriver) -> dict:
    data = json.loads(json.dumps(driver.to_json_dict()))
    for key in ("road_model", "c_brake_ft_s2", "margin_ft"):
        del data["config"][key]
    return data


def test_old_files_load_with_the_legacy_model_and_act_as_before(tmp_path) -> None:
    rng = np.random.default_rng(3)
    obs = np.column_stack([rng.uniform(20, 200, 40), rng.uniform(-10, 15, 40), rng.uniform(-50, 80, 40),
                           rng.uniform(-10, 10, 40), rng.uniform(0, 70, 40), np.full(40, 15.0), np.full(40, 15.0)])
    obs[:4, 0] = [24.0, 20.0, 30.0, 18.0]  # close to C
    obs[:4, 4] = 60.0
    prev, acc_C = rng.uniform(-3, 3, 40), rng.uniform(-10, 2, 40)
    theta = rng.normal(0, 0.5, len(LEGACY.feature_names))
    old = PlanningDriver(theta, LEGACY.feature_names, LEGACY, Shape(), 0.3, ACC)
    path = tmp_path / "old.json"
    path.write_text(json.dumps(legacy_file_of(old)))
    loaded = PlanningDriver.load(path)
    assert loaded.config.road_model == "legacy" and loaded.config == LEGACY
    np.testing.assert_array_equal(loaded.act(obs, prev, acc_C), old.act(obs, prev, acc_C))
    # a file with the new fields keeps them, and the driver's model acts otherwise on close leaders
    new = PlanningDriver(theta, DRIVER.feature_names, replace(DRIVER, margin_ft=2.0), Shape(), 0.3, ACC)
    new.save(tmp_path / "new.json")
    assert PlanningDriver.load(tmp_path / "new.json").config == new.config
    assert asdict(new.config)["margin_ft"] == 2.0
    assert np.any(new.act(obs, prev, acc_C) != old.act(obs, prev, acc_C))


def test_a_b_on_the_ramp_is_no_collision_partner_until_it_has_merged():
    """B just ahead of a fast A: with B merged the driver's road model brakes for it; with B still
    on the ramp (b_merged False) A's plan does not count B as a car in its lane."""
    cfg = PlannerConfig(road_model="driver")
    # no C; B 6 m ahead (front to front, a 4.5 m car: 1.5 m bumper gap), 8 m/s slower than A
    obs = np.array([[np.nan, np.nan, 6.0 * FT_PER_M, 8.0 * FT_PER_M, 25.0 * FT_PER_M, np.nan, 4.5 * FT_PER_M]] * 2)
    zeros = np.zeros(2)
    T = path_tensors(obs, zeros, zeros, np.array([-12.0, -4.0, 0.0, 4.0, 8.0]), Shape(), cfg,
                     b_merged=np.array([True, False]))
    merged, ramp = T.Col[0], T.Col[1]
    assert merged.min() > 0  # every plan predicts a collision or an unsafe gap behind a merged B
    assert ramp.max() == 0  # none behind a B still on the ramp
    with pytest.raises(ConfigError, match="b_merged"):
        path_tensors(obs, zeros, zeros, np.array([-12.0, -4.0, 0.0, 4.0, 8.0]), Shape(), cfg, b_merged=np.ones(3))


def test_a_value_out_of_range_in_a_planner_file_names_its_field_path(tmp_path):
    """config.gamma 1.5 (the right type, a wrong value): the message names config.gamma."""
    from irl.errors import ModelFileError

    driver = PlanningDriver(np.zeros(len(PlannerConfig().feature_names)), PlannerConfig().feature_names,
                            PlannerConfig(), Shape(), PlannerConfig().decision_step_s, (-12.0, -4.0, 0.0, 4.0, 8.0))
    data = driver.to_json_dict()
    data["config"]["gamma"] = 1.5
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(data))
    with pytest.raises(ModelFileError, match=r"bad\.json: config\.gamma: must be in \(0, 1\], got 1\.5"):
        PlanningDriver.load(path)
