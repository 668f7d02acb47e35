"""``merge-irl evaluate --policy ... --policy-vecnormalize FILE``: a real Stable-Baselines3
``VecNormalize.save`` file with its observation statistics edited is refused at exit 2 in one
line naming the file and the field, before SUMO starts; the unedited file is evaluated."""

from __future__ import annotations

import pickle
import subprocess
import sys

import numpy as np
import pytest

from tests.extras import require_extra

RULE = '''
def zero(obs):
    return 2  # Zero
'''


def _cli(*args, timeout=300):
    return subprocess.run([sys.executable, "-m", "analysis", "evaluate", *args], capture_output=True, text=True,
                          timeout=timeout)


@pytest.fixture(scope="module")
def saved_stats(tmp_path_factory):
    """A VecNormalize of the merge environment, saved by Stable-Baselines3 (statistics from 7-column
    observations: the environment's own, drawn in its box; no SUMO run needed to update them)."""
    require_extra("stable_baselines3", "rl")
    pytest.importorskip("gymnasium")
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    from sim.env import MergeEnv

    venv = VecNormalize(DummyVecEnv([lambda: MergeEnv(run_s=240.0)]), norm_reward=False)
    rng = np.random.default_rng(0)
    venv.obs_rms.update(rng.normal([200.0, 0.0, -50.0, 0.0, 90.0, 15.0, 15.0], 10.0, size=(64, 7)))
    path = tmp_path_factory.mktemp("vn") / "vecnormalize.pkl"
    venv.save(str(path))
    venv.close()
    return path


def _edited(src, dst, field, column, value):
    """``src`` loaded by Stable-Baselines3, one statistic edited, saved by it again as ``dst``."""
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    from sim.env import MergeEnv

    vn = VecNormalize.load(str(src), DummyVecEnv([lambda: MergeEnv(run_s=240.0)]))
    if field == "count":
        vn.obs_rms.count = value
    else:
        arr = getattr(vn.obs_rms, field).copy()
        arr[column] = value
        setattr(vn.obs_rms, field, arr)
    vn.save(str(dst))
    vn.close()
    assert pickle.loads(dst.read_bytes()).obs_rms.count == pytest.approx(value if field == "count" else 64.0001)
    return dst


@pytest.mark.parametrize("field,column,value,match", [
    ("var", 1, -4.0, "obs_rms.var must be finite numbers >= 0, got v_AC -4.0"),
    ("mean", 0, np.nan, "obs_rms.mean must be finite numbers, got d_AC nan"),
    ("var", 0, np.inf, "obs_rms.var must be finite numbers >= 0, got d_AC inf"),
    ("count", None, 0.0, "obs_rms.count must be a positive finite number, got 0.0"),
])
def test_edited_statistics_exit_2_naming_the_file_and_the_field(saved_stats, tmp_path, field, column, value, match):
    rule = tmp_path / "rules.py"
    rule.write_text(RULE)
    bad = _edited(saved_stats, tmp_path / "bad.pkl", field, column, value)
    out = tmp_path / "ev"
    r = _cli("--policy", f"{rule}:zero", "--policy-vecnormalize", str(bad), "--baselines", "", "--episodes", "1",
             "--duration", "100", "--no-progress", "--no-rrd", "--out", str(out))
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and str(bad) in lines[0] and match in lines[0], r.stderr
    assert not out.exists()  # refused before the output folder is made


@pytest.mark.sumo
def test_the_saved_statistics_as_written_are_evaluated(saved_stats, tmp_path):
    rule = tmp_path / "rules.py"
    rule.write_text(RULE)
    r = _cli("--policy", f"{rule}:zero", "--policy-vecnormalize", str(saved_stats), "--baselines", "",
             "--episodes", "1", "--duration", "100", "--seed", "5", "--no-progress", "--no-rrd",
             "--out", str(tmp_path / "ev"))
    assert r.returncode == 0, r.stderr
    assert "| zero | 1 |" in r.stdout
