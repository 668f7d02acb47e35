"""``reset(options=...)`` refuses keys it does not read (they were ignored silently), and a second
environment refused its SUMO session in the same process says how to run several (spawn, not
fork) and is left in a clean state: ``step`` says to reset, and once the first is closed it runs."""

from __future__ import annotations

import pytest

gym = pytest.importorskip("gymnasium")

import sim.env  # noqa: E402,F401  (registers the id)
from sim.env import ENV_ID  # noqa: E402
from sim.errors import SimulationError  # noqa: E402

pytestmark = pytest.mark.sumo


def test_unknown_reset_options_are_refused_and_empty_ones_are_fine() -> None:
    env = gym.make(ENV_ID, scenario="synthetic", run_s=240.0)
    try:
        with pytest.raises(ValueError, match=r"options \['reward', 'scenario'\] are not read .*reset\(seed=\.\.\.\)"):
            env.reset(seed=1, options={"scenario": "i80", "reward": "x"})
        obs, _ = env.reset(seed=1, options={})
        assert obs.shape == (7,)
        obs2, _ = env.reset(seed=1, options=None)
        assert (obs == obs2).all()
    finally:
        env.close()


def test_a_second_environment_in_one_process_is_refused_then_clean() -> None:
    first = gym.make(ENV_ID, scenario="synthetic", run_s=240.0)
    second = gym.make(ENV_ID, scenario="synthetic", run_s=240.0)
    try:
        first.reset(seed=1)
        with pytest.raises(SimulationError, match=r"another SUMO session is open.*'spawn'.*forked"):
            second.reset(seed=2)
        with pytest.raises(RuntimeError, match="no episode is running; call reset"):
            second.step(2)  # through gym.make's wrappers: the environment's own error, not a checker's TypeError
        first.close()
        obs, _ = second.reset(seed=2)
        assert obs.shape == (7,)
        second.step(2)
    finally:
        first.close()
        second.close()
