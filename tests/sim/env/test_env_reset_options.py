"""``reset(options=...)`` refuses keys it does not read (they were ignored silently), and an
environment whose reset was refused is left in a clean state: ``step`` says to reset, and a
reset runs. (A second environment in one process runs: ``test_checkers.py``.)"""

from __future__ import annotations

import pytest

gym = pytest.importorskip("gymnasium")

import sim.env  # noqa: E402,F401  (registers the id)
from sim.env import ENV_ID  # noqa: E402

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


def test_an_environment_whose_reset_failed_is_left_clean() -> None:
    env = gym.make(ENV_ID, scenario="synthetic", run_s=240.0)
    try:
        with pytest.raises(ValueError, match="are not read"):
            env.reset(seed=2, options={"scenario": "i80"})
        with pytest.raises(RuntimeError, match="no episode is running; call reset"):
            env.step(2)  # through gym.make's wrappers: the environment's own error, not a checker's TypeError
        obs, _ = env.reset(seed=2)
        assert obs.shape == (7,)
        env.step(2)
    finally:
        env.close()
