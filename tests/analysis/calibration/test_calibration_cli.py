"""``merge-irl calibrate fit / evaluate / check`` end to end on a few real pairs."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from shared_data import PAIRS_DIR

from analysis.calibration import CFParams, load_pairs, load_result
from analysis.calibration.compare import compare_distributions
from analysis.calibration.states import pair_states, table_states
from merge_irl.units import M_PER_FT

N_PAIRS = 36  # the vendored pairs (tests/data/README.md)


def _cli(*args: str, timeout: float = 300) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "analysis", *args], capture_output=True, text=True, timeout=timeout)


@pytest.fixture(scope="module")
def params(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("cal") / "params.toml"
    r = _cli("calibrate", "fit", "--pairs", str(PAIRS_DIR), "--out", str(out), "--limit", "8", "--no-per-pair",
             "--objective", "rmse")
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == str(out)
    return out


def test_fit_writes_loadable_params(params: Path) -> None:
    res = load_result(params)
    assert res.model == "idm" and res.n_pairs == 8 and res.per_pair == () and res.objective == "rmse"
    assert res.population != CFParams()  # moved away from SUMO's defaults


def test_evaluate_json_and_table(params: Path) -> None:
    r = _cli("calibrate", "evaluate", "--params", str(params), "--pairs", str(PAIRS_DIR), "--json")
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    assert {"median_rmse_m", "default_median_rmse_m"} <= set(d) and d["n_pairs"] == N_PAIRS
    assert 0 < d["median_rmse_m"] < 20 and 0 < d["default_median_rmse_m"] < 20
    r = _cli("calibrate", "evaluate", "--params", str(params), "--pairs", str(PAIRS_DIR))
    assert r.returncode == 0
    title, *lines = r.stdout.splitlines()
    assert title.startswith(f"{d['model']} parameters of {params} beside SUMO's {d['model']} defaults")
    n_iv = len(d["intervals"])  # one line per bootstrap interval, after a heading
    assert lines[0].split() == ["pair", "rmse_m", "default_rmse_m"] and len(lines) == N_PAIRS + 5 + n_iv
    med = lines[N_PAIRS + 1].split()
    assert med[0] == "median" and float(med[1]) == pytest.approx(d["median_rmse_m"], abs=1e-3)
    iv = d["intervals"]["mean_ratio"]
    assert iv["low"] <= iv["value"] <= iv["high"]


def test_user_errors_are_one_line_exit_2(tmp_path: Path) -> None:
    bad = tmp_path / "p.toml"
    bad.write_text("model = 'idm'\n[population]\naccel = 'fast'\n")
    r = _cli("calibrate", "evaluate", "--params", str(bad), "--pairs", str(PAIRS_DIR))
    assert r.returncode == 2 and "accel" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    r = _cli("calibrate", "fit", "--pairs", str(tmp_path), "--out", str(tmp_path / "x.toml"))
    assert r.returncode == 2 and "no pair CSV files" in r.stderr
    for cmd in (("fit", "--out", str(tmp_path / "x.toml")), ("evaluate", "--params", str(bad))):
        for n in ("0", "-2", "two"):
            r = _cli("calibrate", *cmd, "--pairs", str(PAIRS_DIR), "--workers", n)
            assert r.returncode == 2 and "--workers: expected a positive whole number" in r.stderr, r.stderr
    # checked before the pairs are read: the folder does not even exist
    r = _cli("calibrate", "fit", "--cf-model-name", "eidm", "--max-evals", "3", "--pairs", str(tmp_path / "nowhere"),
             "--out", str(tmp_path / "x.toml"))
    assert r.returncode == 2 and "--max-evals: expected at least 7 SUMO runs, got 3" in r.stderr, r.stderr
    r = _cli("calibrate", "fit", "--max-evals", "60", "--pairs", str(tmp_path / "nowhere"),
             "--out", str(tmp_path / "x.toml"))  # idm: fitted by the replica, no SUMO runs to cap
    assert r.returncode == 2 and "--max-evals: caps the SUMO runs of a model fitted through SUMO (eidm); idm" \
        in r.stderr, r.stderr
    (tmp_path / "file").write_text("")
    r = _cli("calibrate", "fit", "--pairs", str(tmp_path / "nowhere"), "--out", str(tmp_path / "file" / "x.toml"))
    assert r.returncode == 2 and f"--out {tmp_path / 'file' / 'x.toml'}: cannot write" in r.stderr, r.stderr
    for n in ("0", "-3"):  # --limit -3 used to fit on all but the last 3 pairs
        r = _cli("calibrate", "fit", "--pairs", str(PAIRS_DIR), "--out", str(tmp_path / "x.toml"), "--limit", n)
        assert r.returncode == 2 and "--limit: expected a positive whole number" in r.stderr, r.stderr
    good = tmp_path / "good.toml"
    good.write_text("model = 'idm'\n[population]\naccel = 1.0\n")
    for cmd in (("fit", "--out", str(tmp_path / "x.toml")), ("evaluate", "--params", str(good))):
        r = _cli("calibrate", *cmd, "--pairs", str(PAIRS_DIR), "--holdout", "-0.3")  # was silently no split
        assert r.returncode == 2 and "--holdout: expected a fraction in (0, 1), got -0.3" in r.stderr, r.stderr
    # check: an unwritable --out is refused before the SUMO run (the report was lost after it)
    r = _cli("calibrate", "check", "--params", str(bad), "--pairs", str(PAIRS_DIR), "--out", str(tmp_path / "file" / "r.md"))
    assert r.returncode == 2 and f"--out {tmp_path / 'file' / 'r.md'}: cannot write" in r.stderr, r.stderr
    assert not (tmp_path / "x.toml").exists()  # nothing written by the refused runs


def test_distribution_comparison_detects_difference() -> None:
    pairs = list(load_pairs(PAIRS_DIR, limit=30))
    real = pair_states(pairs)
    same = compare_distributions(real, real)
    assert all(v.ks == 0 and v.js < 1e-9 for v in same)
    shifted = {k: v * 1.5 for k, v in real.items()}
    diff = compare_distributions(shifted, real)
    assert all(v.ks > 0.1 and v.js > 0.02 for v in diff)
    # a table built from the pairs themselves gives the same states as the pairs
    rows = []
    for i, p in enumerate(pairs[:3]):
        n = len(p)
        rows.append(pd.DataFrame({"Vehicle_ID": 2 * i + 2, "Frame_ID": np.arange(n), "Lane_ID": 3,
                                  "Local_Y": p.x_follower / M_PER_FT, "Preceding": 2 * i + 1, "v_Vel": p.v_follower / M_PER_FT,
                                  "Space_Headway": (p.spacing + p.leader_length) / M_PER_FT, "v_Length": 15.0}))
        rows.append(pd.DataFrame({"Vehicle_ID": 2 * i + 1, "Frame_ID": np.arange(n), "Lane_ID": 3,
                                  "Local_Y": p.x_leader / M_PER_FT, "Preceding": 0,
                                  "v_Vel": p.v_leader / M_PER_FT, "Space_Headway": 0.0, "v_Length": p.leader_length / M_PER_FT}))
    st = table_states(pd.concat(rows, ignore_index=True))
    ref = pair_states(pairs[:3])
    for k in ref:
        np.testing.assert_allclose(np.sort(st[k]), np.sort(ref[k]), rtol=1e-9)


@pytest.mark.sumo
def test_check_runs_i80_with_calibrated_drivers(params: Path, tmp_path: Path) -> None:
    out = tmp_path / "check.md"
    r = _cli("calibrate", "check", "--params", str(params), "--pairs", str(PAIRS_DIR), "--duration", "270",
             "--seed", "2", "--out", str(out), "--json", timeout=600)
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    assert set(d["variables"]) == {"speed_ft_s", "spacing_ft", "time_headway_s"}
    for v in d["variables"].values():
        assert v["n_sim"] > 100 and 0 <= v["ks"] <= 1 and 0 <= v["js"] <= 1
    assert "Jensen-Shannon" in out.read_text()
    assert d["keep_drivers"] is False and d["car_follow_model"] == "EIDM"  # the i80 preset's model (IDM fits)
    assert "Simulated car drivers: resampled from the params file (idm), SUMO's EIDM." in out.read_text()


def test_check_report_says_which_drivers_were_simulated() -> None:
    """--keep-drivers simulates the scenario's own drivers (the i80 preset's are EIDM): the report says so
    instead of naming only the params file's model."""
    from analysis.calibration.check import CalibrationCheck

    def report(keep: bool) -> CalibrationCheck:
        return CalibrationCheck(scenario="i80", seed=0, duration_s=600.0, model="idm", variables=(),
                                median_rmse_m=3.5, default_median_rmse_m=3.6, mean_rmse_m=4.4,
                                default_mean_rmse_m=5.2, n_pairs=302, keep_drivers=keep)

    own, params = report(True), report(False)
    assert "Simulated car drivers: the scenario's own (--keep-drivers)." in own.to_markdown()
    assert "Simulated car drivers: resampled from the params file (idm)." in params.to_markdown()
    assert own.to_json_dict()["keep_drivers"] is True and params.to_json_dict()["keep_drivers"] is False
    assert "302 real pairs of the params file's population (idm)" in own.to_markdown()


def test_evaluate_refuses_a_held_out_split_that_is_not_the_fits(tmp_path: Path) -> None:
    """The params file records its training followers: an evaluation whose --holdout/--seed/--limit
    differ from the fit's would score training drivers as held-out (it did, silently)."""
    out = tmp_path / "p.toml"
    split = ("--holdout", "0.3", "--limit", "20")
    r = _cli("calibrate", "fit", "--pairs", str(PAIRS_DIR), "--out", str(out), *split, "--no-per-pair")
    assert r.returncode == 0, r.stderr
    fitted_on = load_result(out).train_followers
    assert len(fitted_on) > 0
    r = _cli("calibrate", "evaluate", "--params", str(out), "--pairs", str(PAIRS_DIR), *split, "--json")
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["n_pairs_in_fit"] == 0 and "note:" not in r.stderr
    r = _cli("calibrate", "evaluate", "--params", str(out), "--pairs", str(PAIRS_DIR), *split, "--seed", "1")
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert "held-out pairs" in r.stderr and "give 'evaluate' the fit's --holdout, --seed and --limit" in r.stderr
    r = _cli("calibrate", "evaluate", "--params", str(out), "--pairs", str(PAIRS_DIR), "--limit", "20", "--json")
    assert r.returncode == 0, r.stderr  # no split asked for: scored, the training followers' pairs counted
    n_in_fit = json.loads(r.stdout)["n_pairs_in_fit"]
    assert n_in_fit > 0 and f"note: {n_in_fit} of the 20 pairs have a follower" in r.stderr


def test_warnings_are_one_line(tmp_path: Path) -> None:
    part = tmp_path / "part.toml"
    part.write_text("model = 'idm'\n[population]\naccel = 1.0\n")
    r = _cli("calibrate", "evaluate", "--params", str(part), "--pairs", str(PAIRS_DIR), "--limit", "3", "--json")
    assert r.returncode == 0, r.stderr
    lines = [ln for ln in r.stderr.splitlines() if "Warning" in ln or ln.startswith("merge-irl calibrate: warning")]
    assert lines == [f"merge-irl calibrate: warning: {part}: population: has no decel, tau, minGap, maxSpeed, delta, "
                     "emergencyDecel: SUMO's defaults are used (decel = 4.5, tau = 1, minGap = 2.5, maxSpeed = 29.06, "
                     "delta = 4, emergencyDecel = 9)"], r.stderr
