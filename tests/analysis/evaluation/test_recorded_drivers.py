"""The recorded drivers' row of an evaluation (--pairs): W1 helpers on hand-made arrays, the
recorded distributions of real I-80 pairs in SI units, the plan's refusal of a bad folder, and a
real short i80 evaluation whose report shows the row."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from analysis.calibration.pairs import load_pairs
from analysis.evaluation.config import EvaluationConfig
from analysis.evaluation.distances import wasserstein
from analysis.evaluation.plan import plan_evaluation
from analysis.evaluation.recorded import (
    HEADWAY_CAP_S,
    RecordedDrivers,
    decision_gap_headway,
    recorded_drivers,
    time_headway,
    w1_to_recorded,
)
from merge_irl.units import FT_PER_M
from scenarios.errors import SpecError

PAIRS = Path(__file__).resolve().parents[2] / "data" / "ngsim_i80_car_following"


def test_wasserstein_and_time_headway_on_hand_made_arrays():
    assert wasserstein([0.0, 1.0], [1.0, 2.0]) == pytest.approx(1.0)  # a shift by 1
    assert wasserstein([0.0, 0.0, 3.0], [0.0, 0.0, 0.0]) == pytest.approx(1.0)  # one third moved by 3
    assert np.isnan(wasserstein([], [1.0]))
    # 10 m at 5 m/s: 2 s; a crawling car (0.5 m/s) has no headway; a long gap is capped; NaN dropped
    h = time_headway(np.array([10.0, 5.0, 900.0, np.nan, -1.0]), np.array([5.0, 0.5, 1.0, 3.0, 2.0]))
    assert h.tolist() == [2.0, HEADWAY_CAP_S, 0.0]


def test_decision_gap_headway_is_the_bumper_gap_in_metres():
    d = pd.DataFrame({"d_AC": [50.0, np.nan, 35.0], "len_C": [15.0, 15.0, 15.0], "speed_A": [35.0, 30.0, 0.0]})
    gap, headway = decision_gap_headway(d)
    assert gap == pytest.approx([35.0 / FT_PER_M, 20.0 / FT_PER_M])  # ft -> m, the decision without C left out
    assert headway == pytest.approx([1.0])  # 35 ft at 35 ft/s; the stopped A has no headway
    assert decision_gap_headway(pd.DataFrame())[0].size == 0


def test_w1_to_recorded_known_distances():
    # A speeds up by 1 m/s^2 every frame (jerk 0) for 6 frames; decisions at 10 m gap and 10 m/s
    v = 10.0 * FT_PER_M + FT_PER_M * 0.1 * np.arange(6)
    profile = pd.DataFrame({"a_id": 7, "t_s": 0.1 * np.arange(6), "v_ft_s": v})
    decisions = pd.DataFrame({"d_AC": [10.0 * FT_PER_M + 15.0] * 2, "len_C": [15.0] * 2,
                              "speed_A": [10.0 * FT_PER_M] * 2})
    rec = RecordedDrivers("hand", 1, 1, 0, 0.3, acc=np.zeros(4), jerk=np.zeros(3), gap=np.array([8.0, 8.0]),
                          headway=np.array([3.0]))
    out = w1_to_recorded([profile], decisions, rec)
    assert out.w1["w1_acc_recorded_m_s2"] == pytest.approx(1.0)
    assert out.w1["w1_jerk_recorded_m_s3"] == pytest.approx(0.0, abs=1e-9)
    assert out.w1["w1_gap_recorded_m"] == pytest.approx(2.0)
    assert out.w1["w1_headway_recorded_s"] == pytest.approx(2.0)
    assert out.summary == pytest.approx({"mean_abs_acc_m_s2": 1.0, "median_gap_m": 10.0, "median_headway_s": 1.0})
    none = w1_to_recorded([], pd.DataFrame(), rec)  # a driver without a controlled A: no distance
    assert all(np.isnan(x) for x in none.w1.values())


def test_recorded_drivers_of_two_real_pairs_in_si_units():
    pairs = load_pairs(PAIRS, limit=2)
    rec = recorded_drivers(pairs, 0.3, source=str(PAIRS))
    files = sorted((PAIRS / "train").glob("*.csv"))[:2]
    raw = [pd.read_csv(f) for f in files]
    v = [df["v_follower"].to_numpy() / FT_PER_M for df in raw]  # ft/s -> m/s
    acc = np.concatenate([np.diff(x) / 0.1 for x in v])
    assert rec.acc == pytest.approx(acc)
    assert rec.jerk == pytest.approx(np.concatenate([np.diff(np.diff(x) / 0.1) / 0.1 for x in v]))
    gap = np.concatenate([((df["x_leader"] - df["leader_length"] - df["x_follower"]).to_numpy() / FT_PER_M)[::3]
                          for df in raw])  # every third 0.1 s frame: the 0.3 s decision step
    assert rec.gap == pytest.approx(gap)
    assert rec.gap.size == sum(-(-len(df) // 3) for df in raw)
    assert 1.0 < np.median(rec.gap) < 60.0 and 0.1 < np.median(np.abs(rec.acc)) < 3.0  # metres, m/s^2
    speed = np.concatenate([x[::3] for x in v])
    assert rec.headway == pytest.approx(np.minimum(gap[speed >= 1.0] / speed[speed >= 1.0], HEADWAY_CAP_S))
    assert rec.n_pairs == 2 and rec.to_dict()["n_gap"] == gap.size
    with pytest.raises(ValueError, match="multiple of 0.1"):
        recorded_drivers(pairs, 0.25)


def test_plan_refuses_a_bad_pairs_folder(tmp_path):
    (tmp_path / "a.csv").write_text("t\n")
    for bad, said in ((tmp_path / "nope", "no such folder"), (tmp_path / "a.csv", "a file")):
        with pytest.raises(SpecError, match=said):
            plan_evaluation(EvaluationConfig("i80", 1, 1, tmp_path / "out", baselines=("sumo",), pairs=bad))
    assert not (tmp_path / "out").exists()
    out = tmp_path / "ev"
    r = subprocess.run([sys.executable, "-m", "analysis", "evaluate", "--scenario", "i80", "--baselines", "sumo",
                        "--pairs", str(tmp_path / "nope"), "--out", str(out)],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode != 0 and "nope" in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert not out.exists()


@pytest.mark.sumo
def test_i80_evaluation_shows_the_recorded_drivers_row(tmp_path):
    out = tmp_path / "ev"
    r = subprocess.run([sys.executable, "-m", "analysis", "evaluate", "--scenario", "i80", "--episodes", "1",
                        "--duration", "300", "--baselines", "sumo", "--pairs", str(PAIRS), "--no-rrd",
                        "--no-progress", "--executor", "serial", "--out", str(out),
                        "--fail-if", "sumo.w1_gap_recorded_m>100"],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    report = (out / "report.md").read_text()
    row = next(line for line in report.splitlines() if line.startswith("| recorded drivers |"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert cells[1] == "36" and cells[5].startswith("3/36")  # pairs; pairs within 2 m of their leader
    assert cells[-1] == "0.46 / 11.12 / 2.08"  # mean abs acc (m/s^2) / median gap (m) / median headway (s)
    assert "W1 to recorded acc / jerk / gap / headway" in report and "| recorded drivers |" in r.stdout
    data = json.loads((out / "metrics.json").read_text())
    assert data["recorded_drivers"]["n_pairs"] == 36 and data["recorded_drivers"]["decision_step_s"] == 0.3
    sumo = data["policies"]["sumo"]["aggregate"]
    assert all(sumo[k] is not None and sumo[k] >= 0 for k in ("w1_acc_recorded_m_s2", "w1_jerk_recorded_m_s3",
                                                                "w1_gap_recorded_m", "w1_headway_recorded_s"))
    assert "input pairs:" in report  # the folder's digest in the provenance
