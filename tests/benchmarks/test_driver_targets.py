"""The driver-targets benchmark runs as a script (tests do not import the script folders): its
pairs table and cost line on the test pairs, and its argument checks."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np

from irl.domains.merge.actions import ACTION_ACC_FT_S2
from irl.planning.driver import PlanningDriver
from irl.planning.features import Shape
from irl.planning.model import PlannerConfig

ROOT = Path(__file__).resolve().parents[2]
PAIRS = ROOT / "tests" / "data" / "ngsim_i80_car_following"


def run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "benchmarks.driver_targets", *args], cwd=ROOT, capture_output=True,
                          text=True, timeout=600)


def test_pairs_table_and_cost_line(tmp_path):
    cfg = PlannerConfig()
    theta = np.random.default_rng(0).normal(size=len(cfg.feature_names))
    path = PlanningDriver(theta, cfg.feature_names, cfg, Shape(), cfg.decision_step_s,
                          tuple(ACTION_ACC_FT_S2)).save(tmp_path / "planner.json")
    out = tmp_path / "out.json"
    r = run("--driver", str(path), "--pairs", str(PAIRS), "--skip", "i80,synthetic", "--json", str(out))
    assert r.returncode == 0, r.stderr
    assert "| planner.json |" in r.stdout and "sign changes / 100 decisions" in r.stdout
    data = json.loads(out.read_text())
    assert set(data) == {"pairs", "cost_ms_per_decision"}
    (row,) = data["pairs"]["rmse"]
    assert row["n_all_pairs"] == 36 and 0 <= row["collisions_all_pairs"] <= 36
    lo, med, hi = row["median_rmse_m"][1], row["median_rmse_m"][0], row["median_rmse_m"][2]
    assert 0 < lo <= med <= hi
    assert row["targets"]["median <= calibrated"] is None  # no --params: not judged
    names = [c["driver"] for c in data["pairs"]["corrections"]]
    assert names == ["planner.json", "IDM SUMO defaults", "recorded drivers"]
    rec = data["pairs"]["corrections"][-1]
    assert rec["bin_match_ci95"][0] == 1.0 and rec["w1_acc_m_s2"] == 0.0
    for c in data["pairs"]["corrections"]:
        assert 0 <= c["bin_match_ci95"][0] <= 1 and 0 <= c["sign_changes_per_100_ci95"][0] <= 1
        assert c["abs_acc_off_m_s2"] >= 0
    assert data["cost_ms_per_decision"]["planner.json"] > 0


def test_bad_arguments_are_refused():
    r = run("--driver", "x.json", "--skip", "pairs,bogus")
    assert r.returncode == 2 and "bogus" in r.stderr
    r = run("--driver", "x.json", "--skip", "i80,synthetic")
    assert r.returncode == 2 and "--pairs" in r.stderr
