"""The reward's seams: values checked where they enter (NaN, inf, None, arrays, strings, bools
refused naming the reward and the environment), its named terms in ``info["rewards"]``,
``register_reward``, and a misspelled reward name refused instead of read as a file."""

from __future__ import annotations

import math

import numpy as np
import pytest

gym = pytest.importorskip("gymnasium")  # the [gym] extra; CI installs it with [test]

from merge_irl.registry import RegistryError  # noqa: E402
from sim.env import MergeEnv, MergeEnvConfig  # noqa: E402
from sim.env.rewards import Reward, RewardWithOutcome, RewardWithTerms, register_reward, reward_value  # noqa: E402
from sim.env.task_reward import TASK_REWARDS, TaskReward  # noqa: E402
from sim.errors import RewardError  # noqa: E402

SHORT = {"run_s": 240.0}


@pytest.mark.parametrize("good", [0, 3, -0.25, np.float32(0.5), np.int64(2), np.float64(-1.0)])
def test_a_finite_real_number_is_a_reward(good):
    v = reward_value(good, "reward 'r'")
    assert type(v) is float and v == float(good)


@pytest.mark.parametrize("bad,match", [
    (math.nan, "returned nan; a reward must be finite"),
    (math.inf, "returned inf; a reward must be finite"),
    (np.float32(-np.inf), "returned -inf"),
    (None, "returned NoneType None"),
    ("0.5", "returned str '0.5'"),
    (True, "returned bool True"),
    (np.bool_(False), "returned bool"),
    (np.array([0.5]), r"returned ndarray array\(\[0.5\]\)"),
    (np.array(0.5), "returned ndarray"),
    ([1.0], "returned list"),
])
def test_anything_else_is_refused_in_one_line_naming_the_reward(bad, match):
    with pytest.raises(RewardError, match=match) as e:
        reward_value(bad, "reward 'mine' of MergeEnv (scenario 'synthetic')")
    assert str(e.value).startswith("reward 'mine' of MergeEnv") and "\n" not in str(e.value)
    assert isinstance(e.value, ValueError)


def test_a_misspelled_reward_name_is_refused_not_read_as_a_file(tmp_path):
    with pytest.raises(RegistryError, match=r"^unknown reward 'fast'; known: task, progress, zero \(a model file"):
        MergeEnvConfig(reward="fast")
    with pytest.raises(RegistryError, match="unknown reward 'fast'"):
        MergeEnv(reward="fast")
    # what looks like a path is still read as one
    with pytest.raises(FileNotFoundError):
        MergeEnv(reward=str(tmp_path / "fast.json"), **SHORT)
    assert MergeEnvConfig(reward="model.json").reward == "model.json"


def test_the_protocols_say_what_a_reward_has():
    r = TaskReward()
    assert isinstance(r, Reward) and isinstance(r, RewardWithTerms) and isinstance(r, RewardWithOutcome)
    assert isinstance(lambda o, a, acc: 0.0, Reward) and not isinstance(lambda o, a, acc: 0.0, RewardWithTerms)
    from types import SimpleNamespace

    from irl.domains.merge.bins import MergeBins
    from sim.env.rewards import reward_parts

    class OverStates:
        encoder = MergeBins.assumed_authors()
        state_encoding = "driver"
        action_acc_ft_s2 = (-10.0, -2.0, 0.0, 2.0, 6.0)

        def __call__(self, obs, action_bin, acc_ft_s2):
            return 0.0

    parts = reward_parts(OverStates(), "mine")
    assert parts.encoder is OverStates.encoder and parts.state_encoding == "driver"
    assert parts.action_acc_ft_s2 == OverStates.action_acc_ft_s2 and parts.terms is None and parts.outcome is None
    plain = reward_parts(SimpleNamespace(__call__=None), "x")
    assert plain.encoder is None and plain.state_encoding == "paper" and plain.action_acc_ft_s2 == ()


def test_register_reward_makes_a_name_and_refuses_what_is_not_callable():
    try:
        register_reward("slow", TaskReward(w_progress=0.0))
        assert MergeEnvConfig(reward="slow").reward == "slow"
        with pytest.raises(RegistryError, match="registered already"):
            register_reward("slow", TaskReward())
        with pytest.raises(TypeError, match="a reward must be a callable"):
            register_reward("seven", 7)  # type: ignore[arg-type]
    finally:
        TASK_REWARDS.unregister("slow")
    assert "seven" not in TASK_REWARDS


class Settable:
    """A reward returning whatever it is set to."""

    def __init__(self):
        self.value: object = 0.0

    def __call__(self, obs, action_bin, acc_ft_s2):
        return self.value


@pytest.mark.sumo
def test_a_real_environment_refuses_each_bad_reward_value_naming_the_reward_and_the_env():
    """Before: NaN and inf were returned by step as they were, '0.5' became 0.5, None and an
    array raised a raw TypeError naming neither the reward nor the environment."""
    reward = Settable()
    env = MergeEnv(reward=reward, **SHORT)
    try:
        env.reset(seed=1)
        _, r, *_ = env.step(2)
        assert r == 0.0
        for bad in (math.nan, math.inf, None, "0.5", np.array([1.0, 2.0]), True):
            reward.value = bad
            with pytest.raises(RewardError, match=r"^reward 'Settable' of MergeEnv \(scenario 'synthetic'\) returned"):
                env.step(2)
            env.reset()  # the next take-over of the run
        reward.value = np.float32(0.25)
        _, r, *_, info = env.step(2)
        assert r == 0.25 and info["rewards"] == {"reward": 0.25}
    finally:
        env.close()


@pytest.mark.sumo
def test_info_names_the_task_reward_terms_and_they_add_up_to_the_reward():
    env = MergeEnv(**SHORT)  # the default reward, "task"
    try:
        env.reset(seed=3)
        done, last = False, None
        while not done:
            _, r, term, trunc, info = env.step(0)  # High Brake: every term moves
            assert {"progress", "near_miss", "comfort", "jerk"} <= set(info["rewards"])
            assert sum(info["rewards"].values()) == pytest.approx(r)
            done, last = term or trunc, info
        assert last is not None and "outcome" in last["rewards"]  # the collision term, 0 unless A collided
        assert last["rewards"]["comfort"] < 0
    finally:
        env.close()


@pytest.mark.sumo
def test_a_registered_reward_is_chosen_by_name_in_gym_make():
    try:
        register_reward("constant", lambda obs, a, acc: 1.5)
        env = gym.make("MergeIRL/OnRampMerge-v0", reward="constant", **SHORT)
        try:
            env.reset(seed=1)
            _, r, *_ , info = env.step(2)
            assert r == 1.5 and info["rewards"] == {"reward": 1.5}
        finally:
            env.close()
    finally:
        TASK_REWARDS.unregister("constant")


@pytest.mark.sumo
def test_the_multi_agent_env_names_each_agents_terms_too():
    pytest.importorskip("pettingzoo")  # the [marl] extra
    from sim.env import MergeParallelEnv

    env = MergeParallelEnv(run_s=200.0, max_agents=4)
    try:
        env.reset(seed=1)
        ended = 0
        while env.agents:
            _, rewards, terms, truncs, infos = env.step({a: 2 for a in env.agents})
            for agent, info in infos.items():
                if "rewards" not in info:  # an agent's first observation: it has not acted yet
                    assert rewards[agent] == 0.0
                    continue
                assert sum(info["rewards"].values()) == pytest.approx(rewards[agent])
                if terms[agent] or truncs[agent]:
                    ended += 1
                    assert "outcome" in info["rewards"]
        assert ended >= 2
    finally:
        env.close()
