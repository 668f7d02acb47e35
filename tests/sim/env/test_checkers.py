"""The standard checkers, called as their users call them: Gymnasium's ``check_env(env.unwrapped)``
with no skip flag (its render check makes a second environment while the first is open, its close
check a third), Stable-Baselines3's ``check_env(env)``, PettingZoo's ``parallel_api_test`` and
``parallel_seed_test`` (two environments at once). A second live environment in one process runs
its SUMO through TraCI; the same seed and actions give the same episode in either backend."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from extras import require_extra

gym = pytest.importorskip("gymnasium")  # the [gym] extra; CI installs it with [test]

from gymnasium.utils.env_checker import check_env  # noqa: E402

import sim.env  # noqa: E402,F401  (registers the id)
from sim.env import ENV_ID, MergeEnv  # noqa: E402

pytestmark = pytest.mark.sumo

SHORT = {"run_s": 240.0}


@pytest.mark.parametrize("render_mode", [None, "rgb_array"])
def test_gymnasium_check_env_passes_with_its_render_and_close_checks(render_mode):
    env = gym.make(ENV_ID, render_mode=render_mode, **SHORT)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # the checker's complaints are warnings: make them fail
            check_env(env.unwrapped)
        assert env.unwrapped._session.backend == "libsumo"  # the checker's own environments are closed
    finally:
        env.close()


def test_stable_baselines3_check_env_passes():
    require_extra("stable_baselines3", "rl")
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    env = gym.make(ENV_ID, **SHORT)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            sb3_check_env(env)
    finally:
        env.close()


def test_pettingzoo_parallel_api_test_and_seed_test_pass():
    pytest.importorskip("pettingzoo")  # the [marl] extra; CI installs it with [test]
    from pettingzoo.test import parallel_api_test, parallel_seed_test

    from sim.env.multi_agent import MergeParallelEnv

    env = MergeParallelEnv(run_s=150.0)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            parallel_api_test(env, num_cycles=2000)
            made = []

            def env_fn():
                made.append(MergeParallelEnv(run_s=150.0))
                return made[-1]

            parallel_seed_test(env_fn)  # while `env` is still open: both of its environments on TraCI
    finally:
        env.close()
    assert len(made) == 2 and all(e._session is None for e in made)  # the test closed both


def test_a_seed_gives_the_same_episode_in_libsumo_and_through_traci():
    first, second = MergeEnv(**SHORT), MergeEnv(**SHORT)
    try:
        obs_1, info_1 = first.reset(seed=5)
        obs_2, info_2 = second.reset(seed=5)
        assert (first._session.backend, second._session.backend) == ("libsumo", "traci")
        assert np.array_equal(obs_1, obs_2) and info_1 == info_2
        actions = np.random.default_rng(0).integers(0, 5, size=200)
        steps = 0
        for action in actions:
            out_1, out_2 = first.step(int(action)), second.step(int(action))
            assert np.array_equal(out_1[0], out_2[0]) and out_1[1:] == out_2[1:]
            steps += 1
            if out_1[2] or out_1[3]:
                break
        assert steps >= 5
        # and both go on to the run's next take-over alike
        assert np.array_equal(first.reset()[0], second.reset()[0])
    finally:
        first.close()
        second.close()
    assert first._session is None and second._session is None
