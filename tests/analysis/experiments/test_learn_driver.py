"""``merge-irl learn-driver``, ``evaluate --driver`` and ``calibrate evaluate --driver``: a planning
driver learned from demonstrations alone, replayed on real pairs and driven in SUMO for real."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from analysis.cli.main import main
from analysis.evaluation.outcome import UNIFORM_LL_PER_STEP
from analysis.experiments.learn_driver import flag_lines
from irl.planning.decisions import encounter_decisions
from irl.planning.driver import PLANNER_FORMAT, PlanningDriver

PAIRS = Path(__file__).resolve().parents[2] / "data" / "ngsim_i80_car_following" / "train"


def _pair_folder(tmp_path: Path, n: int = 6) -> Path:
    d = tmp_path / "pairs"
    d.mkdir()
    for f in sorted(PAIRS.glob("*.csv"))[:n]:
        shutil.copy(f, d / f.name)
    return d


def _following_demos(n=8, rows=90, seed=0) -> pd.DataFrame:
    """Encounters of a follower closing on a slower lead car C and braking when near (ft, ft/s)."""
    rng = np.random.default_rng(seed)
    parts = []
    for e in range(n):
        v_a = 50.0 + rng.normal(0, 3)
        v_c = v_a - rng.uniform(0, 8)
        d_ac = rng.uniform(80, 160)
        rows_ = []
        for t in range(rows):
            gap = d_ac - 15.0
            acc = -6.0 if gap < 1.2 * v_a else (2.0 if v_a < 55 else 0.0)
            rows_.append((e + 1, t, d_ac, v_a - v_c, 60.0 - t, v_a - 45.0, v_a, acc, 15.0, 15.0, 7))
            v_a = max(v_a + acc * 0.1, 0.0)
            d_ac += (v_c - v_a) * 0.1
        parts.append(pd.DataFrame(rows_, columns=["encounter_id", "Frame_ID", "d_AC", "v_AC", "d_AB", "v_AB", "v_A",
                                                  "acc_A", "len_C", "len_B", "C_id"]))
    df = pd.concat(parts, ignore_index=True)
    df["B_is_truck"] = False
    return df


def test_learn_driver_on_pairs_then_calibrate_evaluate_scores_it(tmp_path, capsys):
    pairs = _pair_folder(tmp_path)
    drv = tmp_path / "driver.json"
    assert main(["learn-driver", "--demos", str(pairs), "--out", str(drv), "--no-selection", "--no-progress"]) == 0
    out, err = capsys.readouterr()
    assert "wrote" in out and "per decision" in out
    # --no-progress: no progress lines; the default budget of 100 replays ends this fit, which is said
    assert err.splitlines() == ["WARNING: the fit did not converge (stopped: budget (100 replays of max_evals 100))"]
    driver = PlanningDriver.load(drv)
    assert json.loads(drv.read_text())["format"] == PLANNER_FORMAT
    assert driver.info["n_decisions"] > 100 and np.isfinite(driver.loglik)
    assert driver.info["provenance"]["inputs"]["demos"]["path"] == str(pairs)
    assert main(["calibrate", "evaluate", "--driver", str(drv), "--pairs", str(pairs), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    for key in ("median_rmse_m", "mean_rmse_m", "default_median_rmse_m", "default_mean_rmse_m", "collisions", "n_pairs"):
        assert key in summary
    assert summary["n_pairs"] == 6 and summary["median_rmse_m"] > 0 and summary["default_median_rmse_m"] > 0
    lo, hi = summary["intervals"]["median_rmse_m"][1:]
    assert lo <= summary["median_rmse_m"] <= hi
    # the table form names every pair and the collisions
    assert main(["calibrate", "evaluate", "--driver", str(drv), "--pairs", str(pairs)]) == 0
    text = capsys.readouterr().out
    assert "collisions:" in text and text.count("\n") >= 6 + 3


def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys):
    assert main(["learn-driver", "--demos", str(tmp_path / "none.parquet"), "--out", str(tmp_path / "d.json")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no such file or directory" in err[0]
    assert not (tmp_path / "d.json").exists()
    not_a_driver = tmp_path / "model.json"
    not_a_driver.write_text(json.dumps({"format": "merge-irl-model/1"}))
    assert main(["evaluate", "--driver", str(not_a_driver), "--baselines", "", "--out", str(tmp_path / "ev")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    # --driver takes a file of any registered format: a tabular model's file is read as one, and its fault named
    assert len(err) == 1 and "model.json: method: missing" in err[0]
    assert main(["calibrate", "evaluate", "--pairs", str(PAIRS)]) == 2
    assert "--params FILE" in capsys.readouterr().err


@pytest.mark.sumo
def test_a_driver_learned_from_encounters_drives_in_evaluate(tmp_path, capsys):
    table = tmp_path / "train.parquet"
    demos = _following_demos()
    demos.to_parquet(table)
    drv = tmp_path / "follow.json"
    assert main(["learn-driver", "--demos", str(table), "--out", str(drv), "--no-selection", "--no-progress"]) == 0
    ev = tmp_path / "ev"
    assert main(["evaluate", "--driver", str(drv), "--baselines", "uniform", "--episodes", "1", "--seed", "3",
                 "--duration", "150", "--demos", str(table), "--no-rrd", "--no-progress", "--out", str(ev)]) == 0
    metrics = json.loads((ev / "metrics.json").read_text())
    agg = metrics["policies"]["follow"]["aggregate"]  # named after the file's stem
    assert agg["n_controls"] > 0 and agg["n_decisions"] > 0 and agg["need_brakes"] == 0  # physical actuation
    driver = PlanningDriver.load(drv)
    dec = encounter_decisions(demos, driver.decision_step_s)
    expected = driver.bin_log_policy(dec.obs, dec.prev_acc, dec.acc_C)[np.arange(dec.n), dec.actions].sum()
    assert agg["heldout_loglik"] == pytest.approx(expected)
    assert "actuation physical" in (ev / "report.md").read_text()


def test_learn_driver_fits_real_pairs_by_replay_with_a_held_out_split(tmp_path, capsys):
    out = tmp_path / "replay.json"
    assert main(["learn-driver", "--demos", str(PAIRS), "--holdout", "0.3", "--seed", "0", "--max-evals", "4",
                 "--out", str(out)]) == 0
    captured = capsys.readouterr()
    assert "replay fit:" in captured.err and "held out (" in captured.err  # progress lines on stderr
    assert "fitted by replay" in captured.out and "held out (" in captured.out
    drv = PlanningDriver.load(out)
    assert drv.info["fit"] == "replay" and drv.config.gap_track and not drv.config.jerk
    assert 0 < drv.config.temperature and drv.info["temperature"] == drv.config.temperature
    h = drv.info["heldout"]
    assert h["pairs"] > 0 and np.isfinite(h["median_rmse_m"]) and np.isfinite(h["idm_defaults_median_rmse_m"])
    assert 0 <= h["close_share"] <= 1 and h["ll_per_decision"] < 0
    # 4 replays is the optimiser's budget, not its tolerance: said, and written as not converged
    assert not drv.converged and drv.info["stopped"] == "budget (4 replays of max_evals 4)"
    assert json.loads(out.read_text())["converged"] is False
    assert "(stopped at its budget: not converged)" in captured.err and "NOT converged" in captured.out
    assert "WARNING: the fit did not converge (stopped: budget" in captured.err
    # the held-out likelihood is checked as evaluate checks a policy's
    below = h["ll_per_decision"] < UNIFORM_LL_PER_STEP
    assert drv.info["flags"] == (["heldout_worse_than_uniform"] if below else [])
    assert ("heldout_worse_than_uniform" in captured.err) == below
    w = dict(zip(drv.feature_names, drv.theta))
    assert w["gap_track_C"] < 0 and w["gap_track_B"] == w["gap_track_C"]  # the merging car: the lead car's rule
    # the held-out followers are the ones calibrate fit --holdout 0.3 --seed 0 holds out
    from analysis.calibration.pairs import load_pairs, split_by_follower
    _, test = split_by_follower(load_pairs(PAIRS), 0.3, 0)
    assert h["pairs"] == len(test)


def test_learn_driver_refuses_replay_of_an_encounter_table_and_holdout_without_replay(tmp_path, capsys):
    table = tmp_path / "enc.parquet"
    _following_demos().to_parquet(table)
    assert main(["learn-driver", "--demos", str(table), "--fit", "replay", "--out", str(tmp_path / "d.json")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--fit replay needs folders of car-following pair CSVs" in err[0]
    assert main(["learn-driver", "--demos", str(table), "--holdout", "0.3", "--out", str(tmp_path / "d.json")]) == 2
    assert "goes with --fit replay" in capsys.readouterr().err
    assert not (tmp_path / "d.json").exists()


def test_a_held_out_likelihood_below_uniform_is_flagged_as_evaluate_flags_it():
    from analysis.experiments.learn_driver import _flag_heldout

    info: dict = {}
    _flag_heldout(info, -2.0, "the held-out pairs")  # below log 1/5 = -1.609
    assert info["flags"] == ["heldout_worse_than_uniform"]
    lines = flag_lines(type("D", (), {"converged": True, "info": info})())
    assert len(lines) == 1 and "-2.000, is below uniform actions' (-1.609)" in lines[0]
    ok: dict = {}
    _flag_heldout(ok, -1.0, "the held-out pairs")
    assert ok["flags"] == [] and flag_lines(type("D", (), {"converged": True, "info": ok})()) == []
    _flag_heldout(ok, None, "nothing held out")
    assert ok["flags"] == []
