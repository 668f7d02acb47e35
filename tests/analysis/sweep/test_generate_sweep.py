"""``generate`` as a sweep: seeds x demand scales, executors agree, reruns skip, failures reported."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tomllib

import pandas as pd
import pytest

from analysis.sweep.generate import generate_tasks, parse_scales, parse_seeds, run_name
from scenarios.errors import SpecError
from scenarios.loader import load_scenario
from scenarios.spec.parse import with_overrides


def cli(args, cache):
    env = dict(os.environ, MERGE_IRL_CACHE=str(cache))
    return subprocess.run([sys.executable, "-m", "analysis", "generate", *args, "--no-progress"],
                          capture_output=True, text=True, env=env)


def test_parse_seeds_and_scales():
    assert parse_seeds("1,2,3") == (1, 2, 3)
    assert parse_seeds("1-4") == (1, 2, 3, 4)
    assert parse_seeds("5, 1-3,2") == (5, 1, 2, 3)
    for bad in ("", "a", "3-1", "1-", "-2", "1.5"):
        with pytest.raises(ValueError, match="seeds"):
            parse_seeds(bad)
    assert parse_scales("0.5,1,2") == (0.5, 1.0, 2.0)
    for bad in ("0", "-1", "x", "inf", "nan", "1,,2"):
        with pytest.raises(ValueError, match="demand scales"):
            parse_scales(bad)


def test_demand_scale_multiplies_every_flow_and_is_validated():
    spec = load_scenario("synthetic")
    scaled = with_overrides(spec, demand_scale=0.5)
    assert scaled.demand.main_veh_h == tuple(x * 0.5 for x in spec.demand.main_veh_h)
    assert scaled.demand.ramp_veh_h == spec.demand.ramp_veh_h * 0.5
    assert scaled.demand.truck_share == spec.demand.truck_share
    for bad in (0, -1.0, float("nan"), float("inf"), "2", True):
        with pytest.raises(SpecError, match="demand_scale"):
            with_overrides(spec, demand_scale=bad)


def test_task_names_and_early_validation(tmp_path):
    spec = load_scenario("synthetic")
    tasks = generate_tasks(spec, (1, 2), (0.5, 2.0), tmp_path)
    assert [t.key for t in tasks] == ["synthetic-seed1-demand0.5", "synthetic-seed1-demand2",
                                      "synthetic-seed2-demand0.5", "synthetic-seed2-demand2"]
    assert [t.key for t in generate_tasks(spec, (7,), None, tmp_path)] == [run_name("synthetic", 7, None)]
    with pytest.raises(SpecError, match="seed"):
        generate_tasks(spec, (1, -3), None, tmp_path)  # caught before anything runs
    assert not any(tmp_path.iterdir())


@pytest.mark.sumo
def test_sweep_process_pool_equals_serial_and_rerun_skips(tmp_path):
    cache = tmp_path / "cache"
    common = ["--seeds", "1-2", "--demand-scale", "1,2", "--duration", "75"]
    a = cli([*common, "--executor", "process:2", "--out", str(tmp_path / "a")], cache)
    assert a.returncode == 0, a.stderr
    b = cli([*common, "--executor", "serial", "--out", str(tmp_path / "b")], cache)
    assert b.returncode == 0, b.stderr
    names = ["synthetic-seed1-demand1", "synthetic-seed1-demand2", "synthetic-seed2-demand1",
             "synthetic-seed2-demand2"]
    for n in names:
        ta = pd.read_parquet(tmp_path / "a" / n / "trajectories.parquet")
        tb = pd.read_parquet(tmp_path / "b" / n / "trajectories.parquet")
        assert len(ta) > 0
        pd.testing.assert_frame_equal(ta, tb)
        pd.testing.assert_frame_equal(pd.read_parquet(tmp_path / "a" / n / "merges.parquet"),
                                      pd.read_parquet(tmp_path / "b" / n / "merges.parquet"))
        used = load_scenario(tmp_path / "a" / n / "scenario.toml")
        assert used.simulation.seed == int(n.split("seed")[1][0])
    sa = pd.read_csv(tmp_path / "a" / "sweep.csv")
    sb = pd.read_csv(tmp_path / "b" / "sweep.csv")
    assert list(sa["run"]) == names
    assert list(sa["table_sha256"]) == list(sb["table_sha256"])
    assert len(set(sa["table_sha256"])) == 4  # different seeds / demands: different runs
    # provenance: the scenario each run simulated, the versions; no wall time (that is in sweep.timings.json)
    import hashlib

    from merge_irl.provenance import package_version

    for n, sha in zip(sa["run"], sa["scenario_sha256"]):
        assert sha == hashlib.sha256((tmp_path / "a" / n / "scenario.toml").read_bytes()).hexdigest()
    assert set(sa["merge_irl"]) == {package_version()}
    pd.testing.assert_frame_equal(sa.drop(columns="out_dir"), sb.drop(columns="out_dir"))
    timings = json.loads((tmp_path / "a" / "sweep.timings.json").read_text())["sim_wall_time_s"]
    assert set(timings) == set(names) and all(t > 0 for t in timings.values())
    # doubling demand gives more vehicles for the same seed
    n_veh = dict(zip(sa["run"], sa["n_vehicles"]))
    assert n_veh["synthetic-seed1-demand2"] > n_veh["synthetic-seed1-demand1"]
    # rerun: everything from the store, nothing rewritten
    mtimes = {n: (tmp_path / "a" / n / "trajectories.parquet").stat().st_mtime_ns for n in names}
    again = cli([*common, "--executor", "process:2", "--out", str(tmp_path / "a")], cache)
    assert again.returncode == 0, again.stderr
    assert "4 from the store, 0 run" in again.stderr
    assert mtimes == {n: (tmp_path / "a" / n / "trajectories.parquet").stat().st_mtime_ns for n in names}
    # a run folder that lost its table is run again (and only that one)
    (tmp_path / "a" / names[2] / "trajectories.parquet").unlink()
    third = cli([*common, "--executor", "serial", "--out", str(tmp_path / "a")], cache)
    assert third.returncode == 0, third.stderr
    assert "3 from the store, 1 run" in third.stderr
    pd.testing.assert_frame_equal(pd.read_parquet(tmp_path / "a" / names[2] / "trajectories.parquet"),
                                  pd.read_parquet(tmp_path / "b" / names[2] / "trajectories.parquet"))


@pytest.mark.sumo
def test_a_folder_rewritten_by_another_setting_is_run_again(tmp_path):
    cache, out = tmp_path / "cache", tmp_path / "sw"
    run = out / "synthetic-seed1"

    def sweep(rule, duration="75"):
        r = cli(["--seeds", "1", "--duration", duration, "--encounter-rule", rule, "--executor", "serial",
                 "--out", str(out)], cache)
        assert r.returncode == 0, r.stderr
        return r.stderr

    sweep("take-over")
    first = pd.read_parquet(run / "encounters.parquet")
    assert tomllib.loads((run / "run.toml").read_text())["run"]["encounter_rule"] == "take-over"
    assert "1 from the store, 0 run" in sweep("take-over")
    sweep("merge-frame")  # writes the same folder
    assert tomllib.loads((run / "run.toml").read_text())["run"]["encounter_rule"] == "merge-frame"
    assert "0 from the store, 1 run" in sweep("take-over")  # not the merge-frame files any more
    pd.testing.assert_frame_equal(pd.read_parquet(run / "encounters.parquet"), first)
    sweep("take-over", duration="80")
    assert "0 from the store, 1 run" in sweep("take-over")  # the 80 s files are not the 75 s run's


@pytest.mark.sumo
def test_failed_run_is_retried_reported_and_exits_nonzero(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "synthetic-seed2").write_text("a file where the run folder should go")
    r = cli(["--seeds", "1,2", "--duration", "70", "--executor", "process:2", "--out", str(out)],
            tmp_path / "cache")
    assert r.returncode == 1, r.stderr
    assert "1 failed" in r.stderr
    assert "FAILED synthetic-seed2 after 2 attempt(s)" in r.stderr
    assert (out / "synthetic-seed1" / "trajectories.parquet").is_file()
    assert list(pd.read_csv(out / "sweep.csv")["run"]) == ["synthetic-seed1"]


@pytest.mark.sumo
def test_killed_sweep_resumes_to_the_same_tables(tmp_path):
    import signal
    import time

    cache = tmp_path / "cache"
    args = ["--seeds", "1-3", "--duration", "90", "--executor", "serial"]
    out = tmp_path / "killed"
    env = dict(os.environ, MERGE_IRL_CACHE=str(cache))
    proc = subprocess.Popen([sys.executable, "-m", "analysis", "generate", *args, "--no-progress", "--out", str(out)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env)
    store = out / ".sweep-store"
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and proc.poll() is None:
        if store.is_dir() and any(p.suffix == ".json" and not p.name.startswith(".") for p in store.iterdir()):
            break
        time.sleep(0.05)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    n_done = sum(1 for p in store.iterdir() if p.suffix == ".json" and not p.name.startswith("."))  # not temporaries
    assert n_done >= 1
    # whatever was in flight left no file under a final name that is not complete
    for run in out.glob("synthetic-seed*"):
        for f in run.glob("*.parquet"):
            pd.read_parquet(f)
    resumed = cli([*args, "--out", str(out)], cache)
    assert resumed.returncode == 0, resumed.stderr
    assert f"{n_done} from the store, {3 - n_done} run" in resumed.stderr
    ref = cli([*args, "--out", str(tmp_path / "ref")], cache)
    assert ref.returncode == 0, ref.stderr
    a = pd.read_csv(out / "sweep.csv")
    b = pd.read_csv(tmp_path / "ref" / "sweep.csv")
    assert list(a["run"]) == list(b["run"]) == ["synthetic-seed1", "synthetic-seed2", "synthetic-seed3"]
    assert list(a["table_sha256"]) == list(b["table_sha256"])
