"""``merge-irl calibrate preset``: a ``calibrate fit`` params file to a scenario one runs, and
``calibrate check``'s diagnosis of which variable misses the KS target and why."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from shared_data import PAIRS_DIR

from analysis.calibration import load_pairs, load_result
from analysis.calibration.check import CalibrationCheck, run_calibration_check
from analysis.calibration.compare import KS_TARGET, compare_distributions, diagnose
from analysis.calibration.models import EIDM_NOISE_OFF
from analysis.calibration.pairs import pair_files
from analysis.calibration.states import pair_states
from analysis.calibration.vtypes import SIM_RANGE, every_member, resample_members, scenario_car_model
from scenarios.loader import load_scenario


def _cli(*args: str, timeout: float = 300) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "analysis", *args], capture_output=True, text=True, timeout=timeout)


@pytest.fixture(scope="module")
def params(tmp_path_factory) -> Path:
    """A default ``calibrate fit`` (IDM, per-pair fits) on 6 real pairs."""
    out = tmp_path_factory.mktemp("fit") / "P.toml"
    r = _cli("calibrate", "fit", "--pairs", str(PAIRS_DIR), "--out", str(out), "--limit", "6", "--workers", "1",
             "--no-progress")
    assert r.returncode == 0, r.stderr
    return out


def test_preset_command_writes_the_fitted_drivers_under_the_scenarios_eidm(params: Path, tmp_path: Path) -> None:
    out = tmp_path / "my_i80.toml"
    r = _cli("calibrate", "preset", "--params", str(params), "--out", str(out))
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == str(out) and f"generate --scenario {out}" in r.stderr
    spec, shipped, res = load_scenario(out), load_scenario("i80"), load_result(params)
    assert spec.name == "my_i80" and out.read_text().startswith("# Scenario i80 with calibrated car drivers")
    assert spec.road == shipped.road and spec.demand == shipped.demand  # the scenario is kept, drivers replaced
    cars = spec.drivers.car
    # the shipped i80 preset drives its cars with EIDM: so does the written one, SUMO's driver noise on
    assert {c.car_follow_model for c in cars} == {"EIDM"}
    assert not any(k in EIDM_NOISE_OFF for c in cars for k, _ in c.cf_params)
    # one driver type per per-pair fit, equally likely, clipped to the simulation range
    assert len(cars) == len(res.per_pair) == 6 and {c.probability for c in cars} == {1 / 6}
    assert [(c.tau, c.accel, c.min_gap_m) for c in cars] == [
        (m.params.tau, m.params.accel, m.params.minGap) for m in every_member(res)]
    assert [c.tau for c in cars] == [min(max(f.params.tau, SIM_RANGE["tau"][0]), SIM_RANGE["tau"][1]) for f in res.per_pair]
    assert all(dict(c.lc_params) == dict(shipped.drivers.car[0].lc_params) for c in cars)
    assert spec.drivers.truck == shipped.drivers.truck
    # an explicit model of the same family, and a resample of N driver types
    r = _cli("calibrate", "preset", "--params", str(params), "--out", str(tmp_path / "idm.toml"),
             "--car-follow-model", "IDM", "--drivers", "4", "--seed", "3")
    assert r.returncode == 0, r.stderr
    idm = load_scenario(tmp_path / "idm.toml").drivers.car
    assert {c.car_follow_model for c in idm} == {"IDM"}
    assert [c.tau for c in idm] == [m.params.tau for m in resample_members(res, 4, seed=3)]
    assert scenario_car_model("idm", ["IDM"]) == "IDM" and scenario_car_model("krauss", ["EIDM"]) == "Krauss"


@pytest.mark.sumo
def test_written_preset_runs_in_generate(params: Path, tmp_path: Path) -> None:
    out = tmp_path / "my_i80.toml"
    assert _cli("calibrate", "preset", "--params", str(params), "--out", str(out)).returncode == 0
    run = tmp_path / "run"
    r = _cli("generate", "--scenario", str(out), "--duration", "250", "--out", str(run), "--no-progress", timeout=600)
    assert r.returncode == 0, r.stderr
    table = pd.read_parquet(run / "trajectories.parquet")
    assert len(table) > 1000 and table["Vehicle_ID"].nunique() > 50
    written = (run / "scenario.toml").read_text()
    assert 'name = "my_i80"' in written and 'car_follow_model = "EIDM"' in written


def test_preset_bad_input_is_one_line_exit_2(params: Path, tmp_path: Path) -> None:
    bad_toml = tmp_path / "bad.toml"
    bad_toml.write_text("model = 3\n")
    (tmp_path / "dir.toml").mkdir()
    cases = [
        ("--params", str(tmp_path / "missing.toml"), "--out", str(tmp_path / "a.toml")),
        ("--params", str(bad_toml), "--out", str(tmp_path / "a.toml")),
        ("--params", str(params), "--out", str(tmp_path / "a.txt")),
        ("--params", str(params), "--out", str(tmp_path / "dir.toml")),  # a folder
        ("--params", str(params), "--out", str(tmp_path / "a.toml"), "--car-follow-model", "Krauss"),
        ("--params", str(params), "--out", str(tmp_path / "a.toml"), "--scenario", "no_such_preset"),
        ("--params", str(params), "--out", str(tmp_path / "a.toml"), "--seed", "3"),  # a seed with nothing to draw
    ]
    for args in cases:
        r = _cli("calibrate", "preset", *args)
        assert r.returncode == 2, (args, r.stderr)
        assert len(r.stderr.strip().splitlines()) == 1 and r.stderr.startswith("merge-irl calibrate: error:"), r.stderr
    assert not (tmp_path / "a.toml").exists()


# ----------------------------------------------------------------------------- the diagnosis


def _real(n: int = 4000, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).normal(20.0, 5.0, n)


@pytest.mark.parametrize("make, kind, cause", [
    (lambda r, g: r + 4.0, "location", "demand"),                                   # shifted
    (lambda r, g: 20.0 + (r - 20.0) * 1.8, "spread", "driver spread"),               # wider
    (lambda r, g: 20.0 + (r - 20.0) * 0.5, "spread", "driver spread"),               # narrower
    (lambda r, g: np.where(g.random(len(r)) < 0.5, g.normal(11, 1.5, len(r)), g.normal(29, 1.5, len(r))),
     "shape", "model"),                                                              # two modes
    (lambda r, g: g.normal(20.0, 5.0, len(r)), "ok", "-"),                            # another sample of the same
])
def test_diagnosis_tells_location_width_and_shape_apart(make, kind, cause) -> None:
    g = np.random.default_rng(1)
    real = _real()
    sim = make(_real(seed=2), g)
    states = {n: x for n, x in zip(("speed_ft_s", "spacing_ft", "time_headway_s"), (sim, sim, sim))}
    refs = {n: real for n in states}
    comps = compare_distributions(states, refs)
    (d, *_) = diagnose(comps)
    assert (d.kind, d.cause) == (kind, cause), d.text
    assert (comps[0].ks > KS_TARGET) == (kind != "ok")
    if kind == "location":
        assert "median" in d.text and "higher" in d.text and comps[0].ks_shifted <= KS_TARGET
    if kind == "spread":
        assert ("wider" in d.text) == (np.std(sim) > 5)


def test_check_report_names_the_missing_variable_and_why(tmp_path: Path) -> None:
    """The report of a simulated table whose speeds are the real ones shifted up, spacing as real:
    speed misses, for a location shift (demand); spacing meets the target (time headway, spacing /
    speed, moves with the speed)."""
    from analysis.calibration import save_result
    from analysis.calibration.result import CalibrationResult

    pairs = list(load_pairs(PAIRS_DIR, limit=12))
    rows = []
    for i, p in enumerate(pairs):
        n = len(p)
        ft = 1 / 0.3048
        rows.append(pd.DataFrame({"Vehicle_ID": 2 * i + 2, "Frame_ID": np.arange(n), "Lane_ID": 3,
                                  "Local_Y": 100.0, "Preceding": 2 * i + 1, "Following": 0, "v_Vel": p.v_follower * ft + 8.0,
                                  "Space_Headway": (p.spacing + p.leader_length) * ft, "v_Length": 15.0}))
        rows.append(pd.DataFrame({"Vehicle_ID": 2 * i + 1, "Frame_ID": np.arange(n), "Lane_ID": 3,
                                  "Local_Y": 200.0, "Preceding": 0, "Following": 2 * i + 2, "v_Vel": p.v_leader * ft, "Space_Headway": 0.0,
                                  "v_Length": p.leader_length * ft}))
    table = pd.concat(rows, ignore_index=True)
    # the pairs folder for the check: the same 12 pairs
    folder = tmp_path / "pairs"
    folder.mkdir()
    for f in pair_files(PAIRS_DIR, limit=12):
        (folder / f.name).write_bytes(f.read_bytes())
    res = CalibrationResult(model="idm", fitted=(), population=load_result(_hand_params(tmp_path)).population,
                            population_median_rmse_m=1.0, per_pair=(), spread=(), n_pairs=0,
                            seconds_population=0.0, seconds_per_pair=0.0)
    p = save_result(res, tmp_path / "P.toml")
    report = run_calibration_check(params_path=p, pairs_dir=folder, scenario="i80", table=table, keep_drivers=True)
    assert len(pair_states(list(load_pairs(folder)))["speed_ft_s"]) > 100
    d = report.to_json_dict()
    assert "speed_ft_s" in d["misses"] and "spacing_ft" not in d["misses"], d["variables"]
    assert d["variables"]["speed_ft_s"]["diagnosis"]["cause"] == "demand"
    assert d["variables"]["spacing_ft"]["diagnosis"]["kind"] == "ok"
    md = report.to_markdown()
    assert "| likely why |" in md and "- speed_ft_s misses: a location shift" in md
    assert "spacing_ft misses" not in md
    json.dumps(d)  # JSON-serialisable
    ok = CalibrationCheck(scenario="i80", seed=0, duration_s=600.0, model="idm",
                          variables=tuple(v for v in report.variables if v.name not in d["misses"]), median_rmse_m=1.0,
                          default_median_rmse_m=1.0, mean_rmse_m=1.0, default_mean_rmse_m=1.0, n_pairs=12)
    assert "Every variable meets the KS target." in ok.to_markdown() and ok.to_json_dict()["misses"] == []


def _hand_params(tmp_path: Path) -> Path:
    p = tmp_path / "hand.toml"
    p.write_text('model = "idm"\n[population]\naccel = 1.2\ndecel = 1.5\ntau = 1.2\nminGap = 2.0\nmaxSpeed = 18.0\n'
                 'emergencyDecel = 9.0\ndelta = 4.0\n')
    return p


def test_scenario_drivers_keep_the_scenarios_eidm_noise_not_the_fits() -> None:
    """As a scenario's drivers (car_follow_model given) EIDM keeps the template's noise keys (none:
    SUMO's default noise) even for an EIDM fit, whose own vTypes have the noise off; IDM drops them."""
    from analysis.calibration import CalibrationResult, CFParams, driver_members
    from analysis.calibration.vtypes import to_vtype_specs
    from scenarios.spec.model import VTypeSpec

    res = CalibrationResult(model="eidm", fitted=(), population=CFParams(tau=1.3), population_median_rmse_m=1.0,
                            per_pair=(), spread=(), n_pairs=1, seconds_population=0.0, seconds_per_pair=0.0)
    noisy = VTypeSpec(id="car", car_follow_model="EIDM", cf_params=(("delta", 4.0), ("sigmagap", 0.2)))
    quiet = VTypeSpec(id="car", car_follow_model="EIDM", cf_params=(("delta", 4.0),))
    (own,) = to_vtype_specs(driver_members(res, 1), quiet, "eidm")
    assert dict(own.cf_params)["sigmagap"] == 0.0  # as fitted
    (scen,) = to_vtype_specs(driver_members(res, 1), quiet, "eidm", car_follow_model="EIDM")
    assert dict(scen.cf_params) == {"delta": 4.0} and scen.tau == 1.3
    (kept,) = to_vtype_specs(driver_members(res, 1), noisy, "eidm", car_follow_model="EIDM")
    assert dict(kept.cf_params) == {"delta": 4.0, "sigmagap": 0.2}
    (idm,) = to_vtype_specs(driver_members(res, 1), noisy, "eidm", car_follow_model="IDM")
    assert idm.car_follow_model == "IDM" and dict(idm.cf_params) == {"delta": 4.0}
