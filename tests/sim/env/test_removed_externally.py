"""A controlled car removed between two ``step`` calls (real SUMO, ``session.sumo.vehicle.remove``)
ends its episode as ``removed_externally`` in both environments instead of raising SUMO's
"Vehicle ... is not known"; the multi-agent environment refuses the seeds the single-agent one
refuses, with the same message."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("pettingzoo")  # the [marl] extra; CI installs it with [test]

from sim.closed_loop.records import RELEASE_REASONS  # noqa: E402
from sim.env import MergeEnv  # noqa: E402
from sim.env.multi_agent import MergeParallelEnv  # noqa: E402

SHORT = {"run_s": 200.0}


@pytest.mark.sumo
def test_merge_env_car_removed_between_steps_truncates_the_episode_naming_the_car():
    env = MergeEnv(**SHORT)
    try:
        env.reset(seed=4)
        obs, _, term, trunc, info = env.step(2)
        assert not (term or trunc)
        a_sumo = env._control.a_sumo
        env._session.sumo.vehicle.remove(a_sumo)
        with pytest.raises(ValueError, match="action must be"):  # still refused, episode still running
            env.step(7)
        obs2, reward, term, trunc, info = env.step(2)
        assert (term, trunc) == (False, True)
        assert info["release_reason"] == "removed_externally" in RELEASE_REASONS
        assert info["a_sumo"] == a_sumo and info["a_id"] == env._control.a_id
        assert np.array_equal(obs2, obs) and reward == 0.0  # nothing applied, no decision reward
        with pytest.raises(RuntimeError, match="no episode is running"):
            env.step(2)
        env.reset()  # the run goes on to the next take-over, another car
        assert env._control.a_sumo != a_sumo
        env.step(2)
    finally:
        env.close()


@pytest.mark.sumo
def test_parallel_env_agent_removed_between_steps_is_done_and_the_others_go_on():
    env = MergeParallelEnv(**SHORT)
    try:
        env.reset(seed=3)
        while len(env.agents) < 2:  # a step with two agents, so that one stays
            env.step(dict.fromkeys(env.agents, 2))
        victim, other = env.agents[0], env.agents[1]
        a_sumo = env._live[victim].a_sumo
        env._session.sumo.vehicle.remove(a_sumo)
        obs, rew, term, trunc, info = env.step(dict.fromkeys(env.agents, 2))
        assert (term[victim], trunc[victim]) == (False, True)
        assert info[victim]["release_reason"] == "removed_externally" and info[victim]["a_sumo"] == a_sumo
        assert rew[victim] == 0.0 and obs[victim].shape == (7,)
        assert victim not in env.agents
        assert other in obs and "action_bin" in info[other]  # the other agent's action was applied
        n = 0
        while env.agents and n < 2000:  # the rest of the run steps without SUMO errors
            _, _, term, trunc, info = env.step(dict.fromkeys(env.agents, 2))
            assert all(i.get("release_reason") != "removed_externally" for i in info.values())
            n += 1
        assert env.agents == []
    finally:
        env.close()
