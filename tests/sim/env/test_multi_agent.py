"""Every lag car an agent: PettingZoo's parallel API test, agents that appear at take-over and
leave at release with the single-agent environment's rewards and release reasons, the same
seed the same run, and the agents in fixed slots for SuperSuit's vector environments: each car's
episode (return, controlled steps) against a count by hand and the controller's, the release and
the next car's seat apart, and Stable-Baselines3's logger receiving the episodes."""

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
                    assert rew[i] == 0 and not (term[i] or trunc[i])
                    assert np.all(obs[i] == 0) or "seated" in inf  # idle, or a car seated in an idle slot
                if term[i] or trunc[i]:
                    ends += 1
                    reasons.add(inf["release_reason"])
                    assert inf["terminal_observation"].shape == (7,)
                    assert inf["TimeLimit.truncated"] == bool(trunc[i])
    finally:
        venv.close()
    assert ends >= 3 and active_steps > 100 and "merge_done" in reasons


def inner_slots(venv):
    """The slots environment inside SuperSuit's SB3 vector environment (SuperSuit steps a copy)."""
    return venv.venv.vec_envs[0]


def slot_episodes(venv, steps, rng):
    """Step ``venv`` (SuperSuit's SB3 vector environment of one slots environment) ``steps`` times
    with random actions; per car: the hand count ``[steps, return]`` from the infos, the
    ``episode`` reported, the controller's record, and the steps where a release and a seat
    shared a slot."""
    slots = inner_slots(venv)
    count, reported, controls, shared = {}, {}, {}, 0
    slots.par_env.reset(seed=7)  # seeds the runs (SuperSuit's SB3 vector env takes no seed)
    venv.reset()
    for _ in range(steps):
        controls.update(((slots.par_env._run_seed, f"A{c.a_id}_B{c.b_id}"), c) for c in slots.par_env._ctl.controls)
        out = venv.step(rng.integers(0, 5, size=slots.num_envs))
        rew, infos = out[1], out[-1]
        done = out[2] if len(out) == 4 else out[2] | out[3]
        for i, inf in enumerate(infos):
            if inf["active"]:  # the slot's car acted: one controlled step, its reward
                agent = inf["seed"], inf["agent"]  # names are a run's: the run's seed too
                assert agent[1] == f"A{inf['a_id']}_B{inf['b_id']}"  # the info is that car's alone
                n_r = count.setdefault(agent, [0, 0.0])
                n_r[0] += 1
                n_r[1] += float(rew[i])
            else:
                assert rew[i] == 0 and not done[i] and "episode" not in inf
            if done[i]:
                reported[inf["seed"], inf["agent"]] = inf["episode"]
                if "seated" in inf:
                    shared += 1
                    assert inf["seated"]["agent"] != inf["agent"]
                    assert inf["seated"]["agent"] == f"A{inf['seated']['a_id']}_B{inf['seated']['b_id']}"
    return count, reported, controls, shared


def test_slot_episodes_count_each_cars_controlled_steps_and_return_and_keep_release_and_seat_apart():
    from tests.extras import require_extra

    require_extra("stable_baselines3", "rl")  # SuperSuit's SB3 vector wrapper imports it
    import supersuit as ss

    venv = ss.concat_vec_envs_v1(AgentSlotsVectorEnv(max_agents=2, **SHORT), 1, base_class="stable_baselines3")
    try:
        count, reported, controls, shared = slot_episodes(venv, 600, np.random.default_rng(0))
        slots = inner_slots(venv)
    finally:
        venv.close()
    assert len(reported) >= 10 and shared >= 1  # a release and a seat in one slot's step: kept apart
    for agent, ep in reported.items():
        assert ep["l"] == count[agent][0] == controls[agent].n_decisions  # idle steps never counted
        assert ep["r"] == pytest.approx(count[agent][1], rel=1e-5, abs=1e-5)
        assert set(ep) == {"r", "l", "t"}
    assert 0 < slots.live_steps < slots.slot_steps == 600 * 2
    assert slots.live_steps == sum(n for n, _ in count.values())


def test_stable_baselines3_logs_the_slots_episodes():
    from tests.extras import require_extra

    require_extra("stable_baselines3", "rl")
    import supersuit as ss
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback

    class Count(BaseCallback):  # the hand count, from what the learner saw
        def __init__(self):
            super().__init__()
            self.count, self.ended = {}, []

        def _on_step(self):
            for i, inf in enumerate(self.locals["infos"]):
                if inf["active"]:  # keyed by run and car (the names are a run's)
                    n_r = self.count.setdefault((inf["seed"], inf["agent"]), [0, 0.0])
                    n_r[0] += 1
                    n_r[1] += float(self.locals["rewards"][i])
                if self.locals["dones"][i]:
                    self.ended.append(self.count.pop((inf["seed"], inf["agent"])))
            return True

    venv = ss.concat_vec_envs_v1(AgentSlotsVectorEnv(max_agents=2, **SHORT), 1, base_class="stable_baselines3")
    inner_slots(venv).par_env.reset(seed=8)  # seeds the runs
    cb = Count()
    try:
        import torch

        torch.manual_seed(0)  # not PPO(seed=): SuperSuit's vector env has no seed()
        model = PPO("MlpPolicy", venv, n_steps=256, batch_size=128, n_epochs=1, device="cpu")
        model.learn(total_timesteps=1024, callback=cb)
    finally:
        venv.close()
    logged = [(ep["l"], ep["r"]) for ep in model.ep_info_buffer]
    assert len(logged) == len(cb.ended) >= 5
    assert [n for n, _ in logged] == [n for n, _ in cb.ended]
    assert np.allclose([r for _, r in logged], [r for _, r in cb.ended], atol=1e-4)
