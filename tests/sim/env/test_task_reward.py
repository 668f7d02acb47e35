"""The task reward by name (its terms each pushing the right way, the collision penalty at the
end), the config surface (keywords, a mapping, the dataclass), SI units, the spec's
max_episode_steps."""

from __future__ import annotations

import math

import numpy as np
import pytest

gym = pytest.importorskip("gymnasium")  # the [gym] extra; CI installs it with [test]

import sim.env  # noqa: E402,F401  (registers the id)
from merge_irl.units import FT_PER_M  # noqa: E402
from sim.drivers.observe import MergeObservation  # noqa: E402
from sim.env import ENV_ID, MAX_EPISODE_STEPS, MergeEnv, MergeEnvConfig, TaskReward  # noqa: E402
from sim.env.config import resolve_config  # noqa: E402
from sim.env.task_reward import TASK_REWARDS, ZeroReward, task_reward  # noqa: E402


def obs(**kw):
    base = {"d_AC": 200.0, "d_AB": -50.0, "v_AC": 0.0, "v_AB": 0.0, "b_is_truck": False, "speed_A": 60.0,
            "len_C": 15.0, "len_B": 15.0, "acc_prev": 0.0}
    return MergeObservation(**{**base, **kw})


def test_each_term_of_the_task_reward_pushes_its_way():
    r = TaskReward()
    assert r(obs(speed_A=80.0), 2, 0.0) > r(obs(speed_A=40.0), 2, 0.0) > 0  # progress
    full = r(obs(speed_A=200.0), 2, 0.0)
    assert full == pytest.approx(r.w_progress)  # clipped at v_ref
    # near miss: closing on C at 1 s TTC (bumper gap 30 ft at 30 ft/s) costs half of w_near_miss
    t = r.terms(obs(d_AC=45.0, v_AC=30.0), 2, 0.0)
    assert t["near_miss"] == pytest.approx(-r.w_near_miss * 0.5)
    assert r.terms(obs(d_AC=45.0, v_AC=-5.0), 2, 0.0)["near_miss"] == 0.0  # opening gap
    assert r.terms(obs(d_AC=10.0), 2, 0.0)["near_miss"] == -r.w_near_miss  # overlapping: TTC 0
    # B counts once merged ahead of A; before, it does not
    assert r.terms(obs(d_AB=40.0, v_AB=25.0, b_merged=True), 2, 0.0)["near_miss"] < 0
    assert r.terms(obs(d_AB=40.0, v_AB=25.0, b_merged=False), 2, 0.0)["near_miss"] == 0
    # comfort: harder acceleration or a larger change costs more
    hard = r.terms(obs(), 0, -3.0 * FT_PER_M)
    assert hard["comfort"] == pytest.approx(-r.w_comfort) and hard["jerk"] == pytest.approx(-r.w_jerk)
    assert r(obs(), 2, 0.0) > r(obs(), 3, 1.0)
    assert r.outcome("collision", "A into C") == -r.collision_penalty and r.outcome("merge_done") == 0.0
    assert math.isfinite(r(obs(d_AC=math.nan, v_AC=math.nan, len_C=math.nan), 2, 0.0))  # no C


def test_named_rewards_and_bad_weights():
    assert task_reward("task") == TaskReward() and isinstance(task_reward("zero"), ZeroReward)
    p = TASK_REWARDS["progress"]
    assert isinstance(p, TaskReward) and p.w_near_miss == p.w_comfort == 0 and p.collision_penalty > 0
    with pytest.raises(KeyError, match="unknown reward .fast.; expected one of: task, progress, zero"):
        task_reward("fast")
    with pytest.raises(ValueError, match="w_progress"):
        TaskReward(w_progress=-1.0)
    with pytest.raises(ValueError, match="ttc_near_miss_s"):
        TaskReward(ttc_near_miss_s=0.0)


def test_config_from_keywords_a_mapping_or_the_dataclass():
    c = resolve_config({"run_s": 600.0, "units": "si"}, {"units": "ft"})
    assert c == MergeEnvConfig(run_s=600.0) and c.reward == "task"  # the default reward
    assert resolve_config(MergeEnvConfig(max_agents=2), {}).max_agents == 2
    with pytest.raises(TypeError, match=r"unknown environment setting\(s\) \['speed'\]"):
        resolve_config({"speed": 1}, {})
    with pytest.raises(ValueError, match="units must be one of"):
        MergeEnvConfig(units="mph")
    with pytest.raises(ValueError, match="max_agents"):
        MergeEnvConfig(max_agents=0)
    assert gym.spec(ENV_ID).max_episode_steps == MAX_EPISODE_STEPS == 200


@pytest.mark.sumo
def test_si_units_scale_the_observation_and_the_default_reward_is_the_task_reward():
    ft = MergeEnv(run_s=240.0)
    try:
        o_ft, _ = ft.reset(seed=4)
        _, r_ft, *_ = ft.step(3)
    finally:
        ft.close()
    env = gym.make(ENV_ID, config={"units": "si", "run_s": 240.0})
    try:
        o_si, _ = env.reset(seed=4)
        _, r_si, *_, info = env.step(3)
    finally:
        env.close()
    np.testing.assert_allclose(o_si, o_ft * 0.3048)
    assert env.observation_space.contains(o_si) and env.observation_space.high[0] == pytest.approx(1e4 * 0.3048)
    assert r_si == r_ft != 0.0 and info["acc_mps2"] == pytest.approx(info["acc_ft_s2"] * 0.3048)


@pytest.mark.sumo
def test_a_collision_costs_the_penalty_on_the_last_step():
    """High Accel into the lead car: the episode ends in a collision and the last reward carries
    the collision penalty."""
    env = MergeEnv(run_s=300.0)
    try:
        for seed in range(1, 6):
            env.reset(seed=seed)
            while True:
                _, r, term, trunc, info = env.step(4)
                if term or trunc:
                    break
            if info["release_reason"] == "collision":
                break
    finally:
        env.close()
    assert info["release_reason"] == "collision"
    assert r < -TaskReward().collision_penalty + TaskReward().w_progress
