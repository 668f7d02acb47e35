"""Every lag car an agent: PettingZoo's parallel API test, agents that appear at take-over and
leave at release with the single-agent environment's rewards and release reasons, the same
seed the same run, and the agents in fixed slots for SuperSuit's vector environments."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

pytest.importorskip("pettingzoo")  # the [marl] extra; CI installs it with [test]

from sim.closed_loop.records import RELEASE_REASONS  # noqa: E402
from sim.env.agent_slots import AgentSlotsVectorEnv  # noqa: E402
from sim.env.multi_agent import MergeParallelEnv  # noqa: E402

pytestmark = pytest.mark.sumo

SHORT = {"run_s": 150.0}


def run(env, seed, action=2):
    """A whole run with ``action`` for every agent: per step (agents before, returns)."""
    obs, infos = env.reset(seed=seed)
    steps = [(list(env.agents), obs, {}, {}, {}, infos)]
    while env.agents:
        acting = list(env.agents)
        obs, rew, term, trunc, info = env.step(dict.fromkeys(acting, action))
        steps.append((acting, obs, rew, term, trunc, info))
    return steps


def test_pettingzoo_parallel_api_test_passes_without_warnings():
    from pettingzoo.test import parallel_api_test

    env = MergeParallelEnv(**SHORT)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            parallel_api_test(env, num_cycles=2000)
    finally:
        env.close()


def test_agents_appear_at_take_over_and_leave_at_release_with_the_task_reward():
    seen = []

    def reward(obs, action, acc):
        seen.append(action)
        return 1.0

    env = MergeParallelEnv(reward=reward, **SHORT)
    try:
        steps = run(env, 3)
        assert env.agents == []
        with pytest.raises(RuntimeError, match="no agent to step"):
            env.step({})
    finally:
        env.close()
    appeared, ended, decisions = [], {}, 0
    appeared += list(steps[0][1])  # the agents of reset
    for acting, obs, rew, term, trunc, info in steps[1:]:
        decisions += len(acting)
        for agent in obs:
            assert obs[agent].shape == (7,) and np.all(np.isfinite(obs[agent]))
            if agent not in acting:  # new: its first observation, reward 0
                assert rew[agent] == 0.0 and not term[agent] and not trunc[agent]
        appeared += [a for a in obs if a not in acting]
        for agent in acting:  # every agent that acted gets its decision's reward (1.0 here)
            assert rew[agent] == 1.0
            if term[agent] or trunc[agent]:
                ended[agent] = info[agent]["release_reason"]
    assert len(appeared) >= 2 and len(set(appeared)) == len(appeared)  # unique names, never revived
    assert set(ended) == set(appeared) and set(ended.values()) <= set(RELEASE_REASONS)
    assert any(r == "merge_done" for r in ended.values())
    assert len(seen) == decisions > 0  # one reward per agent per step, one step applies every action
    assert all(a.startswith("A") and "_B" in a for a in appeared)


def test_same_seed_same_run_and_steps_only_on_the_decision_clock():
    env = MergeParallelEnv(**SHORT)
    try:
        a = run(env, 5, action=3)
        b = run(env, 5, action=3)
        c = run(env, 6, action=3)
    finally:
        env.close()
    assert [s[0] for s in a] == [s[0] for s in b]
    assert all(np.array_equal(x[1][k], y[1][k]) for x, y in zip(a, b) for k in x[1])
    assert [s[0] for s in a] != [s[0] for s in c]
    times = [inf["time_s"] for s in a[1:] for inf in s[5].values() if "release_reason" not in inf]
    frames = np.round(np.array(times) / 0.1).astype(int)
    assert np.all(frames % 3 == 0)  # every decision on the 0.3 s clock


def test_actions_must_match_the_agents():
    env = MergeParallelEnv(**SHORT)
    try:
        env.reset(seed=1)
        with pytest.raises(ValueError, match="missing"):
            env.step({})
        with pytest.raises(ValueError, match="not agents"):
            env.step({**dict.fromkeys(env.agents, 2), "A0_B0": 2})
        with pytest.raises(ValueError, match=r"action must be an integer in 0\.\.4"):
            env.step(dict.fromkeys(env.agents, 2.5))
    finally:
        env.close()


def test_agent_slots_vector_env_runs_across_the_end_of_the_run_and_through_supersuit():
    import supersuit as ss

    venv = ss.concat_vec_envs_v1(AgentSlotsVectorEnv(max_agents=3, **SHORT), 1, base_class="gymnasium")
    try:
        obs, infos = venv.reset(seed=2)
        assert obs.shape == (3, 7) and len(infos) == 3
        ends, active_steps, reasons = 0, 0, set()
        for _ in range(700):  # past the end of the first 150 s run: a second run starts by itself
            obs, rew, term, trunc, infos = venv.step(np.full(3, 2))
            assert obs.shape == (3, 7) and rew.shape == term.shape == (3,)
            for i, inf in enumerate(infos):
                active_steps += inf["active"]
                if not inf["active"]:
                    assert np.all(obs[i] == 0) and rew[i] == 0 and not (term[i] or trunc[i])
                if term[i] or trunc[i]:
                    ends += 1
                    reasons.add(inf["release_reason"])
                    assert inf["terminal_observation"].shape == (7,)
                    assert inf["TimeLimit.truncated"] == bool(trunc[i])
    finally:
        venv.close()
    assert ends >= 3 and active_steps > 100 and "merge_done" in reasons
