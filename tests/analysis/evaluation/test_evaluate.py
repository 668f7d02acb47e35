"""Evaluation API and CLI: report, metrics.json, plots, held-out likelihood (real SUMO, short)."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from irl.config import IRLConfig
from irl.domains.merge import mdp as merge_mdp
from irl.domains.merge.bins import MergeBins
from irl.domains.merge.features import FEATURE_NAMES
from irl.result import SavedModel

EDGES = MergeBins.assumed_authors()


def _model(seed=0, beta=1.0) -> SavedModel:
    rng = np.random.default_rng(seed)
    return SavedModel(method="qavg", theta=np.array([1.0, 0.5, -0.2]), loglik=-1.0,
                      q=rng.normal(size=(1250, 5)) * 2, config=IRLConfig(beta=beta), domain="merge",
                      feature_names=FEATURE_NAMES,
                      bin_edges={k: tuple(v) for k, v in EDGES.to_dict().items()})


def _encounters(n=60, seed=1) -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    d_ac = rng.uniform(10, 200, n)
    v_ac = rng.normal(0, 5, n)
    d_ac[:5] = v_ac[:5] = np.nan  # no lead car: open road
    return pd.DataFrame({
        "encounter_id": np.repeat(np.arange(n // 10), 10), "Frame_ID": np.arange(n),
        "d_AC": d_ac, "d_AB": rng.uniform(-20, 120, n), "v_AC": v_ac, "v_AB": rng.normal(0, 5, n),
        "B_is_truck": rng.random(n) < 0.2, "acc_A": rng.normal(0, 4, n),
    })


@pytest.mark.sumo
def test_evaluate_writes_report_metrics_plots(tmp_path):
    from analysis.evaluation.evaluate import evaluate
    from sim.drivers.baselines import default_baselines, training_action_acc
    from sim.drivers.policy import ConstantPolicy

    model_path = _model().save(tmp_path / "m" / "qavg.json")
    demos = _encounters()
    train = _encounters(120, seed=2)
    rep = evaluate([model_path], "synthetic", 2, 3, tmp_path / "out", duration_s=110.0, demos=demos,
                   train_demos=train, baselines=(*default_baselines(), "idm"), policies=[ConstantPolicy(0)], workers=2,
                   progress=False)
    names = ["qavg", "sumo", "uniform", "marginal", "markov", "bc", "idm", "constant-high-brake"]
    assert list(rep.aggregates) == names
    # the IDM reference applies its actions at the training frames' mean per action bin, as the fitted baselines
    applied = pd.concat([e.decisions for e in rep.episodes["idm"]])["acc_cmd"].unique()
    assert len(applied) > 1 and set(applied) <= set(training_action_acc(train))
    assert np.isnan(rep.aggregates["idm"].heldout_loglik_per_step)  # deterministic: no likelihood
    md = rep.report_md.read_text()
    for n in names:
        assert f"| {n} | 2 |" in md
    data = json.loads(rep.metrics_json.read_text())
    assert set(data["policies"]) == set(names)
    assert all(len(v["episodes"]) == 2 for v in data["policies"].values())
    assert [e["seed"] for e in data["policies"]["qavg"]["episodes"]] == [3, 4]
    # held-out log-likelihood, recomputed through irl.domains.merge.mdp's discretisation (no-lead rows too)
    # at the evaluation's decision step: the model's (0.1 s, a model file without decision_step_s)
    demo = merge_mdp.discretize(demos, EDGES, decision_step_s=0.1)
    s, a, _ = demo.flat()
    lp = _model().log_policy()
    expected = lp[s, a].mean()
    assert data["policies"]["qavg"]["aggregate"]["heldout_loglik_per_step"] == pytest.approx(expected)
    assert data["policies"]["uniform"]["aggregate"]["heldout_loglik_per_step"] == pytest.approx(np.log(0.2))
    assert data["policies"]["sumo"]["aggregate"]["heldout_loglik_per_step"] is None
    # the fitted baselines: held-out LL as irl.baselines scores the held-out trajectories
    from irl.baselines import fit_baseline

    train_demo = merge_mdp.discretize(train, EDGES, decision_step_s=0.1)
    for b in ("marginal", "markov", "bc"):
        fit = fit_baseline(b, train_demo)
        assert data["policies"][b]["aggregate"]["heldout_loglik_per_step"] == pytest.approx(fit.loglik(demo) / len(a))
    # collision rate with its Wilson interval, Wasserstein distances, decision step of the model (0.1 s)
    for n in names:
        agg = data["policies"][n]["aggregate"]
        lo, hi = agg["a_collision_ci95"]
        assert 0 <= lo <= agg["a_collision_rate"] <= hi <= 1
        assert agg["w1_acc_A_ft_s2"] >= 0 and agg["w1_d_AC_ft"] >= 0 and agg["w1_ttc_s"] >= 0
        assert agg["w1_speed_A_ft_s"] is None  # the held-out table has no v_A column
        # no fit flags; on these random held-out frames a driver below uniform actions is flagged
        ll = agg["heldout_loglik_per_step"]
        worse = ll is not None and ll < np.log(0.2) - 1e-9
        assert agg["flags"] == (["heldout_worse_than_uniform"] if worse else []) and agg["flagged"] == int(worse)
    assert data["controller"]["decision_step_s"] == pytest.approx(0.1)
    assert data["demos"]["action_counts"] == np.bincount(a, minlength=5).tolist()
    # same traffic for every policy: the SUMO baseline never commands, the others do
    for r in rep.episodes["sumo"]:
        assert not r.controls.commanded.any()
    for r in rep.episodes["qavg"]:
        assert r.controls.commanded.all()
    brake = rep.aggregates["constant-high-brake"]
    assert brake.action_counts[1:] == (0, 0, 0, 0) and brake.action_counts[0] > 0
    for p in rep.plots:
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert set(rep.rrd) == set(names) and all(p.exists() for p in rep.rrd.values())
    # each policy's recording is its own (the viewer would merge files sharing an id)
    from analysis.recording.read import recording_info

    ids = {n: recording_info(p)["recording_id"] for n, p in rep.rrd.items()}
    assert {n: i[:-15] for n, i in ids.items()} == {n: f"merge-irl/synthetic/{n}/seed3" for n in names}
    assert len(set(ids.values())) == len(names) and all("/run-" in i for i in ids.values())
    # provenance: the model file of each policy, the scenario simulated, the versions
    import hashlib

    from merge_irl.provenance import package_version, text_digest
    from scenarios.loader import load_scenario

    prov = data["provenance"]
    assert prov["models"] == {"qavg": {"path": str(model_path), "sha256": hashlib.sha256(model_path.read_bytes()).hexdigest()},
                              **{n: None for n in names[1:]}}
    assert prov["scenario_sha256"] == text_digest(load_scenario("synthetic").to_toml())
    assert prov["merge_irl"] == package_version() and prov["inputs"] == {}  # demos given as a DataFrame
    assert "## Provenance" in md and hashlib.sha256(model_path.read_bytes()).hexdigest() in md
    # wall times are kept out of the results
    assert "wall_time" not in rep.metrics_json.read_text()
    timings = json.loads((tmp_path / "out" / "timings.json").read_text())
    assert all(len(timings["episode_wall_time_s"][n]) == 2 for n in names)


@pytest.mark.sumo
def test_evaluate_cli(tmp_path):
    model_path = _model().save(tmp_path / "model.json")
    out = tmp_path / "ev"
    r = subprocess.run([sys.executable, "-m", "analysis", "evaluate", "--driver", str(model_path), "--episodes", "1",
                        "--duration", "100", "--baselines", "sumo", "--no-rrd", "--no-progress", "--seed", "5",
                        "--executor", "process:2",
                        "--out", str(out), "--fail-if", "sumo.n_episodes<1"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert "ok: sumo.n_episodes = 1; gate sumo.n_episodes<1 not triggered" in r.stderr
    assert "| model | 1 |" in r.stdout and "| sumo | 1 |" in r.stdout
    assert (out / "report.md").exists() and (out / "metrics.json").exists()
    assert not (out / "rerun").exists()
    # a rerun (another executor, another folder) writes byte-identical results: no times in them;
    # a recording an earlier evaluation left in that folder is removed (it is not this one's)
    (tmp_path / "ev2" / "rerun").mkdir(parents=True)
    (tmp_path / "ev2" / "rerun" / "old-policy.rrd").write_bytes(b"earlier")
    again = subprocess.run([sys.executable, "-m", "analysis", "evaluate", "--driver", str(model_path), "--episodes", "1",
                            "--duration", "100", "--baselines", "sumo", "--no-rrd", "--no-progress", "--seed", "5",
                            "--executor", "serial", "--out", str(tmp_path / "ev2")],
                           capture_output=True, text=True, timeout=300)
    assert again.returncode == 0, again.stderr
    for name in ("metrics.json", "report.md"):
        assert (out / name).read_bytes() == (tmp_path / "ev2" / name).read_bytes(), name
    assert not list((tmp_path / "ev2" / "rerun").glob("*.rrd"))
    bad = subprocess.run([sys.executable, "-m", "analysis", "evaluate", "--driver", str(tmp_path / "nope.json"),
                          "--out", str(tmp_path / "x")], capture_output=True, text=True, timeout=120)
    assert bad.returncode == 2 and "nope.json" in bad.stderr and len(bad.stderr.strip().splitlines()) == 1
    bad = subprocess.run([sys.executable, "-m", "analysis", "evaluate", "--baselines", "human",
                          "--out", str(tmp_path / "x")], capture_output=True, text=True, timeout=120)
    assert bad.returncode == 2 and "human" in bad.stderr
    for cmd in (["evaluate", "--baselines", "sumo"], ["demo"]):  # --workers checked by argparse, before any run
        bad = subprocess.run([sys.executable, "-m", "analysis", *cmd, "--workers", "0", "--out", str(tmp_path / "w")],
                             capture_output=True, text=True, timeout=120)
        assert bad.returncode == 2 and "--workers: expected a positive whole number, got 0" in bad.stderr, bad.stderr
        assert not (tmp_path / "w").exists()
    for extra in (["--executor", "process:0"], ["--executor", "serial", "--workers", "2"]):
        bad = subprocess.run([sys.executable, "-m", "analysis", "evaluate", "--baselines", "sumo", *extra,
                              "--out", str(tmp_path / "z")], capture_output=True, text=True, timeout=120)
        assert bad.returncode == 2 and len(bad.stderr.strip().splitlines()) == 1, bad.stderr
    bad = subprocess.run([sys.executable, "-m", "analysis", "evaluate", "--baselines", "sumo", "--fail-if",
                          "collisions>>0", "--out", str(tmp_path / "y")], capture_output=True, text=True, timeout=120)
    assert bad.returncode == 2 and "collisions>>0" in bad.stderr and not (tmp_path / "y").exists()
    gate = subprocess.run([sys.executable, "-m", "analysis", "evaluate", "--baselines", "sumo", "--episodes", "1",
                           "--duration", "100", "--no-rrd", "--no-progress", "--fail-if", "sumo.n_episodes>=1",
                           "--out", str(tmp_path / "gate")], capture_output=True, text=True, timeout=300)
    assert gate.returncode == 1, gate.stderr
    assert "FAIL" in gate.stderr and "n_episodes" in gate.stderr


@pytest.mark.sumo
def test_evaluate_cli_baselines_safety_filter_and_flag_gate(tmp_path):
    from dataclasses import replace

    model_path = replace(_model(), converged=False).save(tmp_path / "qavg.json")
    demos = tmp_path / "demos.parquet"
    held = _encounters(120, seed=4).assign(len_C=15.0)  # C's length: the demonstrations' bumper gaps to C
    held.to_parquet(demos)
    out = tmp_path / "ev"
    r = subprocess.run([sys.executable, "-m", "analysis", "evaluate", "--driver", str(model_path), "--episodes", "1",
                        "--duration", "100", "--baselines", "markov,bc,idm", "--train-demos", str(demos),
                        "--demos", str(demos), "--safety-ttc", "2.5", "--no-rrd", "--no-progress", "--seed", "5",
                        "--executor", "process:2", "--out", str(out), "--fail-if", "flagged>0"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 1, r.stderr  # the not-converged model trips the gate
    assert "qavg: flagged = 1" in r.stderr and "WARNING: model qavg is flagged (not_converged" in r.stderr
    data = json.loads((out / "metrics.json").read_text())
    assert list(data["policies"]) == ["qavg", "markov", "bc", "idm"]
    assert data["policies"]["idm"]["aggregate"]["n_decisions"] > 0  # the IDM reference drove A
    assert data["policies"]["qavg"]["aggregate"]["flags"][0] == "not_converged"  # (and below uniform on these frames)
    assert data["controller"]["safety_ttc_s"] == 2.5
    md = (out / "report.md").read_text()
    assert "FLAGGED: not_converged" in md and "safety filter on (TTC >= 2.5 s)" in md
    assert "below -(4.5 + 0.05) m/s^2" in md and data["metrics_config"]["emergency_tolerance_m_s2"] == 0.05
    assert "fitted decision rule where it has one" in md and data["controller"]["rule"] == "fitted"
    # human likeness: per policy in metrics.json, report.md and the console
    for name, p in data["policies"].items():
        agg = p["aggregate"]
        n = agg["n_controls"]
        assert n > 0, name
        assert agg["emergency_braking_rate"] == pytest.approx(agg["emergency_brakings"] / n)
        assert agg["emergency_brakings"] == sum(agg[f"emergency_brakings_{r}"] for r in ("A", "B", "follower"))
        lo, hi = agg["emergency_braking_ci95"]
        assert 0 <= lo <= agg["emergency_braking_rate"] < hi
        assert 0 <= agg["close_to_c"] <= n and agg["close_to_c_rate"] == pytest.approx(agg["close_to_c"] / n)
        lo, hi = agg["close_to_c_ci95"]
        assert 0 <= lo <= agg["close_to_c_rate"] <= hi <= 1
        assert agg["close_to_c"] == sum(e["close_to_c"] for e in p["episodes"])
        # the demonstrations' accelerations are N(0, 4 ft/s^2) per frame, so their jerks are large
        assert 0 < agg["w1_acc_A_m_s2"] < 3 and 1 < agg["w1_jerk_A_m_s3"] < 60, (name, agg)
    close = (held["d_AC"] - held["len_C"]) < 2 * 3.28084
    expected = held.loc[close, "encounter_id"].nunique()
    assert 0 < expected < 12
    assert data["demos"]["close_to_c"]["close_to_c"] == expected
    assert data["demos"]["close_to_c"]["n_encounters"] == 12
    for text in (md, r.stdout):
        assert "As within 2 m of C [95 % CI]" in text and "W1 jerk (m/s^3)" in text
        assert f"| demonstrations | 12 | - | - | - | {expected}/12 = " in text
        assert "emergency brakings by A / B / A's follower" in text
        assert "| bc | " in text.split("W1 jerk (m/s^3)")[1]  # a row of every policy in the human table


def test_view_cli_prints_recordings(tmp_path):
    from analysis.recording.files import close_recording, open_recording
    from analysis.recording.log import log_training

    rec, tmp = open_recording(tmp_path / "run" / "a.rrd")
    log_training(rec, "qavg", np.array([-3.0, -2.0]), np.zeros((2, 3)))
    close_recording(rec, tmp, tmp_path / "run" / "a.rrd")
    r = subprocess.run([sys.executable, "-m", "analysis", "view", str(tmp_path / "run"), "--print-only"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and "a.rrd" in r.stdout and "rerun" in r.stdout
    r = subprocess.run([sys.executable, "-m", "analysis", "view", str(tmp_path / "empty")],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "empty" in r.stderr


@pytest.mark.parametrize("damage", ["text", "truncated", "zeroed"])
def test_view_refuses_a_file_that_is_not_a_readable_recording(tmp_path, damage):
    """A corrupt or foreign .rrd is one line and exit 2, and no viewer starts."""
    from analysis.recording.files import close_recording, open_recording
    from analysis.recording.log import log_training

    good = tmp_path / "run" / "good.rrd"
    rec, tmp = open_recording(good)
    log_training(rec, "qavg", np.arange(-300.0, 0.0), np.zeros((300, 3)))
    close_recording(rec, tmp, good)
    data = good.read_bytes()
    bad = tmp_path / "run" / "bad.rrd"
    if damage == "text":
        bad.write_text("<html>not a recording</html>\n")
    elif damage == "truncated":
        bad.write_bytes(data[: len(data) // 2])
    else:  # the header kept, the body zeroed
        bad.write_bytes(data[:8] + bytes(len(data) - 8))
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}  # headless: no GUI
    if damage == "text":  # a readable recording still opens
        r = subprocess.run([sys.executable, "-m", "analysis", "view", str(good), "--print-only"], capture_output=True,
                           text=True, timeout=120, env=env)
        assert r.returncode == 0 and "good.rrd" in r.stdout, r.stderr
    r = subprocess.run([sys.executable, "-m", "analysis", "view", str(bad)], capture_output=True, text=True,
                       timeout=120, env=env)
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 1, (r.returncode, r.stderr)
    assert lines[0].startswith("merge-irl view: error: ") and "bad.rrd" in lines[0]
    assert "not a readable rerun recording" in lines[0] and "open with" not in r.stdout
    if damage == "truncated":  # in a run folder: the bad one named, the good one opens
        r = subprocess.run([sys.executable, "-m", "analysis", "view", str(tmp_path / "run")], capture_output=True,
                           text=True, timeout=120, env=env)
        lines = r.stderr.strip().splitlines()
        assert r.returncode == 0 and len(lines) == 1 and "bad.rrd" in lines[0], r.stderr
        assert lines[0].startswith("merge-irl view: warning: left out ") and "not a readable" in lines[0]
        assert "good.rrd" in r.stdout and "bad.rrd" not in r.stdout
