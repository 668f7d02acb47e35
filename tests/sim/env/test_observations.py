"""Observations by name: the default ``"policy"`` as before, an unknown name refused with the
names, and a new observation added in one file, each of the three ways (a module of the
package folder, ``"module:Class"`` of the user's own, ``register_observation``), run in the env."""

from __future__ import annotations

import numpy as np
import pytest

gym = pytest.importorskip("gymnasium")  # the [gym] extra; CI installs it with [test]

import sim.env.observations as observations  # noqa: E402
from merge_irl.registry import RegistryError  # noqa: E402
from sim.drivers.observe import POLICY_OBS_HIGH  # noqa: E402
from sim.env import MergeEnv, MergeEnvConfig  # noqa: E402
from sim.env.observations import OBSERVATIONS, observation_names, register_observation  # noqa: E402

SHORT = {"run_s": 240.0}

#: One file: a two-column observation (A's speed and the bumper gap to C, ft/s and ft).
SPEED_GAP = '''
import numpy as np
from gymnasium import spaces

from sim.env.observations import register_observation


class SpeedGap:
    def __init__(self, config):
        self.config = config

    def space(self):
        return spaces.Box(np.array([0.0, -1e4]), np.array([300.0, 1e4]), dtype=np.float64)

    def observe(self, obs):
        gap = obs.d_AC - obs.len_C if np.isfinite(obs.d_AC) and np.isfinite(obs.len_C) else 1e4
        return np.array([obs.speed_A, gap], dtype=np.float64)


register_observation(__name__.rpartition(".")[2], SpeedGap)
'''


def test_the_default_is_the_policy_observation_and_an_unknown_name_is_refused_with_the_names():
    assert MergeEnvConfig().observation == "policy" and "policy" in observation_names()
    space = MergeEnv(**SHORT).observation_space
    assert space.shape == (7,) and np.array_equal(space.high, POLICY_OBS_HIGH)
    assert np.allclose(MergeEnv(units="si", **SHORT).observation_space.high, POLICY_OBS_HIGH * 0.3048)
    with pytest.raises(RegistryError, match=r"^unknown observation 'lidar'; known: policy.* \(or 'module:Class'"):
        MergeEnvConfig(observation="lidar")
    with pytest.raises(RegistryError, match="unknown observation 'lidar'"):
        gym.make("MergeIRL/OnRampMerge-v0", observation="lidar")
    with pytest.raises(RegistryError, match="does not name an importable object"):
        MergeEnvConfig(observation="no_such_module_x:Obs")
    with pytest.raises(TypeError, match="observation must be a name or a factory"):
        MergeEnvConfig(observation=3)  # type: ignore[arg-type]


def _run(observation):
    env = gym.make("MergeIRL/OnRampMerge-v0", observation=observation, **SHORT)
    try:
        assert env.observation_space.shape == (2,)
        obs, _ = env.reset(seed=1)
        seen = [obs]
        for _ in range(5):
            obs, *_ = env.step(2)
            seen.append(obs)
        return np.array(seen)
    finally:
        env.close()


@pytest.mark.sumo
def test_an_observation_in_one_file_of_the_package_folder_is_found_by_name(tmp_path, monkeypatch):
    (tmp_path / "speed_gap.py").write_text(SPEED_GAP)  # the one file
    monkeypatch.setattr(observations, "__path__", [*observations.__path__, str(tmp_path)])
    try:
        assert "speed_gap" in observation_names()
        seen = _run("speed_gap")
        assert seen.shape == (6, 2) and np.all(seen[:, 0] > 0)  # A's speed, ft/s
    finally:
        OBSERVATIONS.unregister("speed_gap")


@pytest.mark.sumo
def test_an_observation_of_ones_own_module_or_registered_in_ones_code_runs(tmp_path, monkeypatch):
    (tmp_path / "my_obs.py").write_text(SPEED_GAP)  # registers "my_obs" on import too
    monkeypatch.syspath_prepend(str(tmp_path))
    try:
        by_ref = _run("my_obs:SpeedGap")
        from my_obs import SpeedGap  # type: ignore[import-not-found]

        register_observation("speed-gap", SpeedGap)
        by_name = _run("speed-gap")
        np.testing.assert_array_equal(by_ref, by_name)  # same seed, same actions: same episode
        with pytest.raises(RegistryError, match="registered already"):
            register_observation("speed-gap", SpeedGap)
    finally:
        for name in ("speed-gap", "my_obs"):
            OBSERVATIONS.unregister(name)


class WrongShape:
    """Says two columns, returns three (or a list)."""

    def __init__(self, config):
        self.as_list = False

    def space(self):
        from gymnasium import spaces

        return spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float64)

    def observe(self, obs):
        return [0.0, 0.0] if self.as_list else np.zeros(3)


def test_an_observation_that_does_not_fit_its_own_space_is_refused_naming_it():
    from sim.drivers.observe import MergeObservation
    from sim.env.config import MergeEnvConfig as Config
    from sim.env.core import EnvCore
    from sim.errors import ObservationError

    core = EnvCore(Config(observation=WrongShape, run_s=240.0))
    obs = MergeObservation(d_AC=200.0, d_AB=-50.0, v_AC=0.0, v_AB=0.0, b_is_truck=False, speed_A=60.0)
    with pytest.raises(ObservationError, match=r"observation <class .*WrongShape'> returned shape \(3,\); its space"):
        core.observation(obs)
    core.observer.as_list = True
    with pytest.raises(ObservationError, match="returned list"):
        core.observation(obs)
    assert EnvCore(Config(run_s=240.0)).observation(obs).shape == (7,)
