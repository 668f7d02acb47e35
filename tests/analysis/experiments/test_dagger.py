"""DAgger for the car-following logit (analysis/experiments/dagger.py) and the SUMO expert's records
(sim/merges/expert_labels.py), with SUMO run for real."""

from __future__ import annotations

import hashlib
import json

import numpy as np
import pandas as pd
import pytest

from analysis.cli.main import main
from analysis.experiments import dagger as dagger_module
from analysis.experiments.dagger import DaggerConfig, labelling_duration_s, labels_as_decisions, train_cf_driver
from irl.domains.merge.car_following import CF_FEATURES, car_following_decisions
from irl.domains.merge.cf_logit import CarFollowingLogit
from irl.errors import ConfigError, DemonstrationError
from scenarios.errors import SpecError
from scenarios.loader import load_scenario
from sim.closed_loop.config import ControllerConfig
from sim.closed_loop.controller import Controller
from sim.drivers.learned import CarFollowingLogitPolicy
from sim.errors import SimError
from sim.merges.expert_labels import ExpertLabels
from sim.runtime.run import run_scenario

ACC = (-12.3, -4.0, 0.0, 3.0, 8.0)


def _gas_driver() -> CarFollowingLogit:
    """Takes High Accel (almost) always."""
    theta = np.zeros(len(CF_FEATURES))
    theta[CF_FEATURES.index("bias_high_accel")] = 20.0
    return CarFollowingLogit(theta, ACC, 0.3)


def _accelerating_demos(n=6, rows=60, seed=0) -> pd.DataFrame:
    """Demonstrators who always take High Accel: their driver never learns to brake by itself."""
    rng = np.random.default_rng(seed)
    return pd.DataFrame({
        "encounter_id": np.repeat(np.arange(n) + 1, rows), "d_AC": rng.uniform(40, 300, n * rows),
        "v_AC": rng.normal(0, 5, n * rows), "d_AB": rng.uniform(-50, 100, n * rows),
        "v_AB": rng.normal(0, 5, n * rows), "B_is_truck": False, "acc_A": 9.0, "v_A": rng.uniform(20, 80, n * rows),
    })


@pytest.mark.sumo
def test_expert_records_are_the_decisions_observations():
    ctl = Controller(CarFollowingLogitPolicy(_gas_driver()), ControllerConfig(decision_step_s=0.3))
    hook = ExpertLabels(ctl)
    run_scenario(load_scenario("synthetic"), seed=3, duration_s=120, hooks=[ctl, hook])
    dec, rec = ctl.decision_table(), hook.table()
    assert len(dec) > 50 and len(rec) == len(dec)
    for col, other in (("d_AC", "d_AC"), ("v_AC", "v_AC"), ("d_AB", "d_AB"), ("v_AB", "v_AB"), ("v_A", "speed_A"),
                       ("len_C", "len_C"), ("len_B", "len_B")):
        np.testing.assert_array_equal(rec[col].to_numpy(), dec[other].to_numpy())
    assert np.isfinite(rec["len_B"]).all() and np.isfinite(rec["len_C"]).any()
    # prev: A's action at its previous decision in the same control episode (A, B); at its first,
    # the bin of A's acceleration before the take-over (SUMO drove it: not always Zero)
    expected = dec.groupby(["a_id", "b_id"], sort=False)["action"].shift(1).fillna(-1).astype(int).to_numpy()
    first = expected < 0
    np.testing.assert_array_equal(rec["prev"].to_numpy()[~first], expected[~first])
    assert rec["prev"].to_numpy()[first].min() >= 0 and len(set(rec["prev"].to_numpy()[first])) > 1
    assert (rec["action"] == 0).any(), "the expert never brakes hard behind a car A runs into"
    assert (rec["state"] == -1).all()  # the car-following policy has no state encoder


@pytest.mark.sumo
def test_one_round_adds_only_critical_labels_and_teaches_braking():
    demos = _accelerating_demos()
    cfg = DaggerConfig(rounds=1, episodes_per_round=1, duration_s=150.0, label_seed=11)
    r0, r1 = train_cf_driver(demos, "synthetic", cfg, progress=False)
    assert r0.info["dagger_round"] == 0 and r0.info["n_label_steps"] == 0
    kept = r1.info["labels_per_round"]
    assert r1.info["dagger_round"] == 1 and len(kept) == 1 and kept[0] > 0
    assert r1.info["n_label_steps"] == kept[0] and r1.info["critical_actions"] == [0]
    # the same labelling run by hand: the kept labels are exactly its High Brake records
    ctl = Controller(CarFollowingLogitPolicy(r0), ControllerConfig(decision_step_s=0.3))
    hook = ExpertLabels(ctl)
    run_scenario(load_scenario("synthetic"), seed=11, duration_s=150.0, hooks=[ctl, hook])
    table = hook.table()
    assert int((table["action"] == 0).sum()) == kept[0] < len(table)
    dec = car_following_decisions(demos)
    by_hand = CarFollowingLogit.fit(dec, l2=cfg.l2, labels=labels_as_decisions(table[table["action"] == 0], dec))
    np.testing.assert_allclose(by_hand.theta, r1.theta)
    # where the demonstrators never braked, the round-1 driver brakes hard on a close, closing C
    close = np.array([[30.0, 25.0, -40.0, 0.0, 60.0, 14.8, 14.8]])
    p0, p1 = (np.exp(m.log_policy(close, np.array([4])))[0, 0] for m in (r0, r1))
    assert p1 > p0 + 0.2


def test_config_is_checked():
    for kw in ({"rounds": -1}, {"rounds": 1.5}, {"episodes_per_round": 0}, {"label_seed": -1}, {"duration_s": 0.0},
               {"duration_s": float("inf")}, {"decision_step_s": float("nan")}, {"l2": -1.0}, {"l2": float("inf")},
               {"critical_actions": ()}, {"critical_actions": (5,)}, {"critical_actions": "0"}):
        with pytest.raises(ConfigError):
            DaggerConfig(**kw)
    assert list(DaggerConfig(rounds=2, episodes_per_round=3, label_seed=10).label_seeds()) == list(range(10, 16))


def test_rounds_0_writes_the_logit_alone(tmp_path, capsys):
    table = tmp_path / "train.parquet"
    _accelerating_demos().to_parquet(table)
    (tmp_path / "o").mkdir()
    (tmp_path / "o" / "cf-dagger.json").write_text("{}")  # an earlier run's driver: it would not match
    assert main(["dagger", "--train", str(table), "--rounds", "0", "--no-progress", "--out", str(tmp_path / "o")]) == 0
    assert sorted(p.name for p in (tmp_path / "o").glob("*.json")) == ["cf-logit.json"]
    out = capsys.readouterr().out
    assert "round 0" in out and "--driver " + str(tmp_path / "o" / "cf-logit.json") in out


def test_cli_rejects_bad_input_in_one_line_before_sumo(tmp_path, capsys):
    table = tmp_path / "train.parquet"
    _accelerating_demos().drop(columns=["v_A"]).to_parquet(table)
    assert main(["dagger", "--train", str(table), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "v_A" in err[0]
    assert not (tmp_path / "o").exists()  # refused before the output folder is made
    assert not (tmp_path / "o" / "cf-dagger.json").exists()
    # a CSV pandas cannot parse: its error (which ends in a newline) on the same one line
    ragged = tmp_path / "ragged.csv"
    ragged.write_text("a,b\n1,2\n1,2,3,4\n")
    assert main(["dagger", "--train", str(ragged), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "ragged.csv" in err[0] and "Expected 2 fields" in err[0]
    with pytest.raises(SystemExit) as e:
        main(["dagger", "--train", str(table), "--critical", "hard_brake"])
    assert e.value.code == 2
    bad = tmp_path / "bad.json"
    bad.write_text('{"format": "merge-irl-model/1"}')
    assert main(["evaluate", "--driver", str(bad), "--baselines", "", "--out", str(tmp_path / "e")]) == 2
    # --driver reads through the driver-format registry: the file's own fault, named
    assert "bad.json: method: missing" in capsys.readouterr().err and not (tmp_path / "e").exists()
    # a driver file where an IRL model.json is expected says which command takes it
    good = CarFollowingLogit.fit(car_following_decisions(_accelerating_demos())).save(tmp_path / "cf.json")
    assert main(["score", "--model", str(good), "--demos", str(table)]) == 2
    assert "merge-irl evaluate --driver" in capsys.readouterr().err
    # held-out demonstrations without v_A fail before any episode runs
    assert main(["evaluate", "--driver", str(good), "--baselines", "", "--demos", str(table), "--episodes", "1",
                 "--no-progress", "--out", str(tmp_path / "e2")]) == 2
    assert "v_A" in capsys.readouterr().err and not (tmp_path / "e2").exists()  # nothing written
    # a label seed or duration the scenario rejects: before the round-0 fit and any SUMO run
    fine = tmp_path / "fine.parquet"
    _accelerating_demos().to_parquet(fine)
    assert main(["dagger", "--train", str(fine), "--duration", "30", "--out", str(tmp_path / "o2")]) == 2
    assert "duration" in capsys.readouterr().err
    assert not (tmp_path / "o2" / "cf-logit.json").exists()


def test_negative_or_missing_speeds_name_the_row():
    df = _accelerating_demos()
    df.loc[3, "v_A"] = -1.0
    with pytest.raises(DemonstrationError, match=r"t.parquet: row 3, column 'v_A'"):
        train_cf_driver(df, "synthetic", DaggerConfig(rounds=0), where="t.parquet", progress=False)


@pytest.mark.sumo
def test_cli_trains_and_evaluate_drives_the_result(tmp_path, capsys):
    table = tmp_path / "train.parquet"
    _accelerating_demos().to_parquet(table)
    out = tmp_path / "dg"
    assert main(["dagger", "--train", str(table), "--rounds", "1", "--episodes-per-round", "1", "--duration", "150",
                 "--label-seed", "11", "--critical", "high_brake,low_brake", "--out", str(out), "--no-progress"]) == 0
    m = CarFollowingLogit.load(out / "cf-dagger.json")
    assert m.info["dagger_round"] == 1 and m.info["critical_actions"] == [0, 1] and m.info["labels_per_round"][0] > 0
    assert CarFollowingLogit.load(out / "cf-logit.json").info["dagger_round"] == 0
    assert "cf-dagger.json" in capsys.readouterr().out
    ev = tmp_path / "ev"
    assert main(["evaluate", "--driver", str(out / "cf-dagger.json"), "--baselines", "", "--episodes", "1",
                 "--seed", "3", "--duration", "150", "--demos", str(table), "--no-rrd", "--no-progress",
                 "--out", str(ev)]) == 0
    metrics = json.loads((ev / "metrics.json").read_text())
    digest = metrics["provenance"]["models"]["cf-dagger"]  # the driver file is in the provenance
    assert digest["sha256"] == hashlib.sha256((out / "cf-dagger.json").read_bytes()).hexdigest()
    agg = metrics["policies"]["cf-dagger"]["aggregate"]
    assert agg["n_controls"] > 0 and agg["n_decisions"] > 0
    dec = car_following_decisions(_accelerating_demos())
    assert agg["heldout_loglik"] == pytest.approx(m.loglik_of(dec))


def test_labelling_runs_take_their_duration_from_the_scenario():
    """A fixed 240 s equalled i80's warm-up: the default comes from the scenario."""
    i80, synthetic = load_scenario("i80"), load_scenario("synthetic")
    d = labelling_duration_s(i80, DaggerConfig())
    assert i80.simulation.warmup_s < d <= i80.simulation.duration_s
    assert labelling_duration_s(synthetic, DaggerConfig()) == 240.0  # the synthetic scenario's, as before
    assert labelling_duration_s(i80, DaggerConfig(duration_s=300.0)) == 300.0
    with pytest.raises(SpecError, match=r"dagger --duration .* 240 s: .* i80's warm-up, simulation.warmup_s = 240 s"):
        labelling_duration_s(i80, DaggerConfig(duration_s=240.0))


def test_dagger_on_i80_with_its_own_defaults_and_errors_blaming_only_what_was_given(tmp_path, capsys, monkeypatch):
    """``merge-irl dagger --scenario i80`` passes its checks with its defaults (the labelling runs are
    stopped by the test, not run: an i80 run takes minutes); a --duration the scenario rejects is named."""
    table = tmp_path / "train.parquet"
    _accelerating_demos().to_parquet(table)
    seen = {}

    def stop(model, spec, seeds, config, executor, duration_s):
        seen.update(scenario=spec.name, seeds=seeds, duration_s=duration_s)
        raise SimError("labelling stopped by the test")

    monkeypatch.setattr(dagger_module, "label_runs", stop)
    args = ["dagger", "--scenario", "i80", "--train", str(table), "--rounds", "1", "--episodes-per-round", "1",
            "--no-progress", "--out", str(tmp_path / "o")]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "labelling stopped by the test" in err and "overrid" not in err and "--duration" not in err, err
    assert seen["scenario"] == "i80" and seen["duration_s"] > load_scenario("i80").simulation.warmup_s
    assert main([*args, "--duration", "200"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "dagger --duration (DaggerConfig.duration_s) 200 s" in err, err
    assert "stopped by the test" not in err
