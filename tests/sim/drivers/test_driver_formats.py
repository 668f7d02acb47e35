"""A new driver type is one registration: a toy format registered from this test alone is read by
``load_driver``, drives A in ``merge-irl evaluate --driver`` (real SUMO), replays real I-80 pairs
in ``merge-irl calibrate evaluate --driver``, is the environment's reward and a policy callable,
with no edit anywhere else. The registry's refusals name the file, its format and the option
that takes it."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from analysis.cli.main import main
from irl.domains.merge.actions import N_ACTIONS, actions_of
from irl.errors import ModelFileError
from sim.drivers.formats import (
    FORMATS,
    DriverFormat,
    check_role,
    driver_policy,
    driver_reward,
    format_of,
    load_driver,
    policy_callable,
    register_format,
    replay_act,
    unregister_format,
)
from sim.drivers.observe import MergeObservation
from sim.drivers.policy import NO_LIKELIHOOD, PolicyDefaults

PAIRS = Path(__file__).resolve().parents[2] / "data" / "ngsim_i80_car_following" / "train"


@dataclass(frozen=True)
class ToyDriver:
    """Constant time headway: ``acc = gain (d_AC - headway v_A)``, clipped (ft, ft/s, ft/s^2)."""

    headway_s: float
    gain: float = 0.3

    def acc(self, obs: np.ndarray) -> np.ndarray:
        """``[N, 7] -> [N]``: the columns ``d_AC, v_AC, d_AB, v_AB, v_A, len_C, len_B``."""
        gap = np.where(np.isfinite(obs[:, 0]), obs[:, 0], 1000.0)
        return np.clip(self.gain * (gap - self.headway_s * obs[:, 4]), -12.0, 6.0)

    @classmethod
    def load(cls, path: Path) -> ToyDriver:
        data = json.loads(path.read_text())
        if not isinstance(data.get("headway_s"), (int, float)):
            raise ModelFileError(f"{path}: missing field 'headway_s'")
        return cls(float(data["headway_s"]))


@dataclass(frozen=True)
class ToyPolicy(PolicyDefaults):
    driver: ToyDriver
    name: str = "toy"
    controls: bool = True
    source: str = ""
    decision_step_s: float = 0.3

    def _acc(self, obs: MergeObservation) -> float:
        return float(self.driver.acc(obs.continuous())[0])

    def probs(self, obs: MergeObservation) -> np.ndarray:
        p = np.zeros(N_ACTIONS)
        p[int(actions_of(np.array([self._acc(obs)]))[0])] = 1.0
        return p

    def acceleration(self, obs: MergeObservation, action: int) -> float:
        return self._acc(obs)

    def heldout_loglik(self, encounters: pd.DataFrame, *, decision_step_s: float, where: str) -> tuple[float, float]:
        return NO_LIKELIHOOD


def _toy_reward(driver: ToyDriver):
    def reward(obs: MergeObservation, action: int, acc_ft_s2: float) -> float:
        return -abs(acc_ft_s2 - float(driver.acc(obs.continuous())[0]))
    return reward


@pytest.fixture
def toy(tmp_path):
    register_format(DriverFormat(
        "toy-headway", "toy driver (this test)", load=ToyDriver.load,
        policy=lambda d, name, source: ToyPolicy(d, name=name, source=source),
        replay_act=lambda d: ((lambda obs, prev_acc, acc_C: d.acc(obs)), 0.3),
        reward=_toy_reward))
    path = tmp_path / "toy.json"
    path.write_text(json.dumps({"format": "toy-headway/1", "headway_s": 1.5}))
    yield path
    unregister_format("toy-headway")


def test_the_built_in_formats_are_registered_by_their_modules():
    assert {"merge-irl-model", "merge-irl-cf-logit", "merge-irl-planner"} <= set(FORMATS)
    assert FORMATS["merge-irl-model"].role == "model"
    assert FORMATS["merge-irl-planner"].reward is not None and FORMATS["merge-irl-cf-logit"].reward is None


def test_a_registered_format_loads_builds_its_policy_and_replays(toy):
    assert load_driver(toy) == ToyDriver(1.5)
    pol = driver_policy(toy)
    assert isinstance(pol, ToyPolicy) and pol.name == "toy" and pol.source == str(toy)
    act, step = replay_act(toy)
    assert step == 0.3
    np.testing.assert_allclose(act(np.array([[100.0, 0, 50, 0, 60.0, 15, 15]]), np.zeros(1), np.zeros(1)), [3.0])
    fn = policy_callable(toy)
    assert fn(np.array([100.0, 0, 50, 0, 60.0, 15, 15])) == int(actions_of(np.array([3.0]))[0])


def test_refusals_name_the_file_its_format_and_the_option(toy, tmp_path):
    unknown = tmp_path / "x.json"
    unknown.write_text(json.dumps({"format": "nobody/1"}))
    with pytest.raises(ModelFileError, match=r"x\.json: format 'nobody/1' is not a registered .*toy-headway/\.\.\."):
        load_driver(unknown)
    with pytest.raises(ModelFileError, match=r"--model.*is not a model's: it is a toy driver.*evaluate --driver"):
        format_of(toy, "model", option="--model")
    with pytest.raises(ModelFileError, match="no string 'format'"):
        format_of(_write(tmp_path / "n.json", {"headway_s": 1}))
    check_role(_write(tmp_path / "legacy.json", {"method": "qavg"}), "model")  # no format: left to the loader
    with pytest.raises(ModelFileError, match="is not a model's"):
        check_role(toy, "model")
    with pytest.raises(ValueError, match="registered already"):
        register_format(FORMATS["toy-headway"])
    with pytest.raises(ValueError, match="without '/'"):
        register_format(DriverFormat("a/b", "bad", load=ToyDriver.load, policy=lambda d, n, s: ToyPolicy(d)))


def _write(path: Path, data: dict) -> Path:
    path.write_text(json.dumps(data))
    return path


def test_a_format_without_replay_or_reward_says_so(tmp_path):
    register_format(DriverFormat("toy-bare", "bare toy", load=ToyDriver.load,
                                 policy=lambda d, name, source: ToyPolicy(d, name=name)))
    try:
        path = _write(tmp_path / "bare.json", {"format": "toy-bare/1", "headway_s": 1.0})
        with pytest.raises(ModelFileError, match="does not replay car-following pairs"):
            replay_act(path)
        with pytest.raises(ModelFileError, match="bare toy has no reward; the environment's rewards come from"):
            driver_reward(path)
    finally:
        unregister_format("toy-bare")


def test_a_registered_format_replays_real_pairs_in_calibrate_evaluate(toy, tmp_path, capsys):
    assert main(["calibrate", "evaluate", "--driver", str(toy), "--pairs", str(PAIRS), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["driver"] == str(toy) and out["n_pairs"] > 0 and np.isfinite(out["median_rmse_m"])


@pytest.mark.sumo
def test_a_registered_format_drives_in_evaluate(toy, tmp_path, capsys):
    out = tmp_path / "ev"
    assert main(["evaluate", "--driver", str(toy), "--scenario", "synthetic", "--episodes", "1", "--seed", "3",
                 "--duration", "110", "--baselines", "", "--workers", "1", "--no-progress", "--no-rrd",
                 "--out", str(out)]) == 0
    metrics = json.loads((out / "metrics.json").read_text())
    assert "toy" in json.dumps(metrics)
    assert "toy" in (out / "report.md").read_text()


@pytest.mark.sumo
def test_a_registered_format_is_the_environments_reward(toy):
    pytest.importorskip("gymnasium")
    from sim.env import MergeEnv

    env = MergeEnv(reward=toy, run_s=240.0)
    try:
        env.reset(seed=8)
        _, r, _, _, _ = env.step(2)
    finally:
        env.close()
    assert np.isfinite(r) and r <= 0.0


def test_names_that_moved_out_of_the_evaluations_policies_say_where_they_went():
    import analysis.evaluation.policies as policies

    with pytest.raises(ImportError, match=r"policies.BASELINES moved to sim.drivers.baselines"):
        from analysis.evaluation.policies import BASELINES  # noqa: F401
    with pytest.raises(ImportError, match=r"load_driver moved to sim.drivers.formats"):
        policies.load_driver  # noqa: B018
    with pytest.raises(AttributeError):
        policies.nothing_here  # noqa: B018


def test_a_driver_module_in_the_folder_registers_itself_when_its_family_is_first_read(tmp_path, monkeypatch):
    """A new driver type needs no entry in formats.py: a file of a family the registry does not
    know makes it import the folder's modules once, and a module's own register_format counts."""
    import sim.drivers as package
    from sim.drivers import formats

    folder = tmp_path / "more_drivers"
    folder.mkdir()
    (folder / "toy_scan_driver.py").write_text(
        "from sim.drivers.formats import DriverFormat, register_format\n"
        "register_format(DriverFormat('toy-scan', 'toy scanned driver', load=lambda p: 'loaded', "
        "policy=lambda d, name, source: d))\n")
    monkeypatch.setattr(package, "__path__", [*package.__path__, str(folder)])
    monkeypatch.setattr(formats, "_SCANNED", [])
    f = tmp_path / "d.json"
    f.write_text(json.dumps({"format": "toy-scan/1"}))
    try:
        assert formats.load_driver(f) == "loaded"
    finally:
        formats.unregister_format("toy-scan")
        import sys
        sys.modules.pop("sim.drivers.toy_scan_driver", None)
