"""The Gymnasium environment on the stepped session: Gymnasium's checker on both action spaces,
same seed same episode, a constant High Brake episode ends with its release reason, rewards of
learned models, two worker processes through AsyncVectorEnv."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

gym = pytest.importorskip("gymnasium")  # the [gym] extra; CI installs it with [test]

from gymnasium.utils.env_checker import check_env  # noqa: E402

import sim.env  # noqa: E402,F401  (registers the id)
from irl.domains.merge.actions import HIGH_BRAKE  # noqa: E402
from scenarios.errors import SpecError  # noqa: E402
from sim.closed_loop.config import ControllerConfig  # noqa: E402
from sim.closed_loop.records import RELEASE_REASONS  # noqa: E402
from sim.env import ENV_ID, MergeEnv  # noqa: E402

pytestmark = pytest.mark.sumo

SHORT = {"run_s": 240.0}


def episode(env, seed, action):
    obs, info = env.reset(seed=seed)
    observations, infos, rewards = [obs], [info], []
    while True:
        obs, r, term, trunc, info = env.step(action)
        observations.append(obs)
        infos.append(info)
        rewards.append(r)
        if term or trunc:
            return np.array(observations), infos, np.array(rewards), term, trunc


@pytest.mark.parametrize("action_type", ["discrete", "continuous"])
def test_gymnasium_env_checker_passes_without_warnings(action_type):
    env = gym.make(ENV_ID, action_type=action_type, **SHORT)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # the checker's complaints are warnings: make them fail
            # but its advice: the continuous action is in m/s^2 by contract, not normalised
            # (gymnasium.wrappers.RescaleAction normalises it, docs/environment.md)
            warnings.filterwarnings("ignore", message=".*symmetric and normalized space.*")
            # skip_render_check: both action types here; the checker as users call it, render and
            # close checks included, runs in test_checkers.py
            check_env(env.unwrapped, skip_render_check=True)
    finally:
        env.close()
    assert isinstance(env.action_space, gym.spaces.Discrete if action_type == "discrete" else gym.spaces.Box)


def test_same_seed_gives_the_same_episode_and_another_seed_another():
    env = MergeEnv(**SHORT)
    try:
        a, ia, _, _, _ = episode(env, 5, 3)
        b, ib, _, _, _ = episode(env, 5, 3)
        c, _, _, _, _ = episode(env, 6, 3)
    finally:
        env.close()
    assert a.shape == b.shape and np.array_equal(a, b)
    assert [i["state"] for i in ia] == [i["state"] for i in ib]
    assert a.shape != c.shape or not np.array_equal(a, c)
    assert np.all(np.isfinite(a)) and a.shape[1] == 7


def test_constant_high_brake_episode_terminates_with_its_release_reason():
    env = MergeEnv(controller=ControllerConfig(decision_step_s=0.3, high_brake="mean"), **SHORT)
    try:
        obs, infos, _, term, trunc = episode(env, 3, HIGH_BRAKE)
    finally:
        env.close()
    last = infos[-1]
    assert term and not trunc
    assert last["release_reason"] in RELEASE_REASONS and last["release_reason"] not in ("timeout", "end_of_run")
    # A braked: its speed (column v_A, ft/s) fell over the episode, and every step applied High Brake
    assert obs[-1, 4] < obs[0, 4] - 5.0
    assert all(i["action_bin"] == HIGH_BRAKE for i in infos[1:])


def test_continuous_action_is_applied_in_metres_per_second_squared():
    env = MergeEnv(action_type="continuous", **SHORT)
    try:
        obs0, _ = env.reset(seed=2)
        obs1, _, term, trunc, info = env.step(np.array([-2.0], dtype=np.float32))
    finally:
        env.close()
    assert info["acc_ft_s2"] == pytest.approx(-2.0 * 3.28084, rel=1e-4)
    if not (term or trunc):  # 0.3 s at -2 m/s^2: A's speed fell by about 0.6 m/s = 2 ft/s
        assert obs1[4] - obs0[4] == pytest.approx(-2.0 * 3.28084 * 0.3, abs=0.5)


def test_a_callable_reward_sees_each_decision():
    seen = []

    def reward(obs, action, acc_ft_s2):
        seen.append((obs.state, action, acc_ft_s2))
        return float(action)

    env = MergeEnv(reward=reward, **SHORT)
    try:
        _, infos, rewards, _, _ = episode(env, 4, 4)
    finally:
        env.close()
    assert len(seen) == len(rewards) > 0
    assert list(rewards) == [float(a) for _, a, _ in seen]
    assert [s for s, _, _ in seen][0] == infos[0]["state"] >= 0


def test_async_vector_env_with_two_workers_runs():
    envs = gym.vector.AsyncVectorEnv([sim.env.make_env(**SHORT)] * 2, context="spawn")
    try:
        obs, info = envs.reset(seed=[11, 12])
        assert obs.shape == (2, 7) and np.all(np.isfinite(obs))
        ends = 0
        for _ in range(40):
            obs, r, term, trunc, info = envs.step(np.array([2, 2]))
            assert obs.shape == (2, 7) and r.shape == (2,)
            ends += int(np.sum(term | trunc))
        assert ends >= 1  # at least one episode ended (and the worker reset itself)
    finally:
        envs.close()
    assert not np.array_equal(obs[0], obs[1])  # two different runs


def test_tabular_model_reward_is_theta_dot_phi_of_the_state_in_info(tmp_path):
    from irl.config import IRLConfig
    from irl.domains.merge.bins import MergeBins
    from irl.domains.merge.features import feature_set
    from irl.result import SavedModel

    bins = MergeBins.assumed_authors()
    theta = np.array([1.0, -2.0, 0.5])
    model = SavedModel(method="qavg", theta=theta, loglik=-1.0, q=np.zeros((1250, 5)), config=IRLConfig(),
                       domain="merge", bin_edges={k: tuple(v) for k, v in bins.to_dict().items()},
                       decision_step_s=0.3, feature_set="paper")
    path = model.save(tmp_path / "model.json")
    phi = feature_set("paper", bins, "paper", decision_step_s=0.3).array
    env = MergeEnv(reward=path, **SHORT)
    try:
        _, infos, rewards, _, _ = episode(env, 7, 1)
    finally:
        env.close()
    states = [i["state"] for i in infos[:-1]]  # the state of each decision, before its step
    expected = [float(phi[s, i["action_bin"]] @ theta) for s, i in zip(states, infos[1:])]
    assert min(states) >= 0 and len(set(states)) >= 1
    np.testing.assert_allclose(rewards, expected, rtol=1e-12)


def test_planning_driver_reward_from_its_file_depends_on_the_action(tmp_path):
    from irl.domains.merge.actions import ACTION_ACC_FT_S2
    from irl.planning.driver import PlanningDriver
    from irl.planning.features import Shape
    from irl.planning.model import PlannerConfig
    from sim.env import PlanningReward, load_reward

    cfg = PlannerConfig()
    theta = np.random.default_rng(0).normal(size=len(cfg.feature_names))
    drv = PlanningDriver(theta, cfg.feature_names, cfg, Shape(), cfg.decision_step_s, tuple(ACTION_ACC_FT_S2))
    path = drv.save(tmp_path / "planner.json")
    assert isinstance(load_reward(path), PlanningReward)
    first = {}
    for a in (0, 4):
        env = MergeEnv(reward=path, **SHORT)
        try:
            env.reset(seed=8)
            _, r, _, _, info = env.step(a)
        finally:
            env.close()
        assert np.isfinite(r)
        first[a] = r
    assert first[0] != first[4]


@pytest.mark.parametrize("kwargs,error,match", [
    ({"reward": 3}, TypeError, "reward must be a reward name, a model file path, a callable"),
    ({"controller": {"decision_step_s": 0.3}}, TypeError, "controller must be a sim.closed_loop.config"),
    ({"run_s": -5.0}, SpecError, r"simulation\.duration_s: must be positive"),
    ({"run_s": float("nan")}, SpecError, r"simulation\.duration_s: must be finite"),
    ({"run_s": 30.0}, SpecError, "must be longer than the scenario's simulation.warmup_s"),
    ({"run_s": 1e9}, SpecError, "is implausible"),
])
def test_bad_constructor_arguments_are_refused_at_construction_not_at_the_first_reset(kwargs, error, match):
    """Before, each of these made an environment and failed later: at reset (a SUMO run then left
    open) or at the first step (``'int' object is not callable``)."""
    with pytest.raises(error, match=match):
        MergeEnv(**kwargs)


def test_actions_outside_the_space_are_refused_not_truncated():
    """Discrete: 2.7 was applied as 2 and True as 1; continuous: [0.3, 5] as 0.3 and inf as the bound."""
    env = MergeEnv(**SHORT)
    cont = MergeEnv(action_type="continuous", **SHORT)
    try:
        env.reset(seed=1)
        for bad in (2.7, True, np.array([1, 2]), "2", None):
            with pytest.raises(ValueError, match=r"action must be an integer in 0\.\.4"):
                env.step(bad)
        assert env.step(np.int64(2))[4]["action_bin"] == 2  # an integer of any dtype, or 2.0, is fine
        env.step(2.0)
        env.close()
        cont.reset(seed=1)
        for bad in ([0.3, 5.0], np.inf, np.array([np.nan]), "x", True):
            with pytest.raises(ValueError, match=r"action must be one finite acceleration"):
                cont.step(bad)
        cont.step(np.array([0.5], dtype=np.float32))
    finally:
        env.close()
        cont.close()
