"""The whole pipeline (generate -> discretize -> learn -> re-inject -> evaluate -> .rrd), small."""

from __future__ import annotations

import json

import pytest

from analysis.demo.config import DemoConfig
from analysis.demo.pipeline import run_demo
from analysis.recording.read import read_entities
from irl.result import SavedModel

pytestmark = pytest.mark.sumo


def test_run_demo_small(tmp_path):
    cfg = DemoConfig(train_seeds=(11,), heldout_seed=12, data_duration_s=240.0, eval_episodes=1,
                     eval_duration_s=110.0, methods=("qavg",), dagger_rounds=0)
    # an earlier demo's models in the folder: those this run does not write are removed, other files kept
    (tmp_path / "demo" / "models").mkdir(parents=True)
    for name in ("cf-dagger.json", "cf-logit.json", "qsm.json", "mine.json"):
        (tmp_path / "demo" / "models" / name).write_text("{}")
    res = run_demo(tmp_path / "demo", cfg, quiet=True, progress=False)
    out = tmp_path / "demo"
    assert sorted(p.name for p in (out / "models").iterdir()) == ["mine.json", "planner.json", "qavg.json"]
    model = SavedModel.load(res.models["qavg"])
    assert set(model.bin_edges) == {"d_AC", "d_AB", "v_AC", "v_AB"}
    # learned as `merge-irl learn` learns on encounter tables (driver features and encoding, beta 1),
    # at the demo's gamma and L2
    assert (model.feature_set, model.state_encoding, model.q.shape) == ("driver", "driver", (6250, 5))
    assert (model.config.beta, model.config.gamma, model.config.l2) == (1.0, cfg.gamma, cfg.l2)
    assert res.n_train_steps > 100
    data = json.loads(res.evaluation.metrics_json.read_text())
    # the planning driver, learned from the demonstrations alone, is evaluated beside them
    assert set(data["policies"]) == {"qavg", "planner", "sumo", "uniform", "marginal", "markov", "bc"}
    assert data["policies"]["planner"]["aggregate"]["heldout_loglik_per_step"] < 0
    assert data["policies"]["planner"]["aggregate"]["need_brakes"] == 0  # the physical actuation
    # the held-out frames carry A's speed: every policy has the Wasserstein distances (TTC only
    # when A closed in on C at some decision of this short run)
    for p in data["policies"].values():
        agg = p["aggregate"]
        assert all(agg[k] is not None and agg[k] >= 0 for k in ("w1_speed_A_ft_s", "w1_acc_A_ft_s2", "w1_d_AC_ft"))
        assert agg["w1_ttc_s"] is None or agg["w1_ttc_s"] >= 0
        assert "a_collision_ci95" in agg
        # human likeness: real held-out frames, so both W1 distances are measured
        assert 0 < agg["w1_acc_A_m_s2"] < 5 and 0 < agg["w1_jerk_A_m_s3"] < 100
        assert 0 <= agg["close_to_c_rate"] <= 1 and agg["emergency_braking_rate"] >= 0
    assert data["demos"]["n_steps"] > 0
    assert data["demos"]["close_to_c"]["n_encounters"] == res.n_heldout_encounters
    assert "| demonstrations | " in res.format() and "| demonstrations | " in res.evaluation.report_md.read_text()
    ents = read_entities(res.demo_rrd)
    assert "/train/qavg/loglik" in ents and "/train/qavg/theta/safe" in ents
    assert "/world/vehicles" in ents and any(k.startswith("/policy/A_") for k in ents)
    for name in ("summary.md", "data/train_encounters.parquet", "data/heldout_encounters.parquet", "data/bins.json",
                 "evaluation/report.md", "evaluation/speed_profiles.png"):
        assert (out / name).exists(), name
    assert str(out) in res.format()
    # provenance: the models were learned from the training table; the summary lists their files
    import hashlib

    train = out / "data" / "train_encounters.parquet"
    assert model.info["provenance"]["inputs"]["demos"]["sha256"] == hashlib.sha256(train.read_bytes()).hexdigest()
    summary = (out / "summary.md").read_text()
    assert "## Provenance" in summary
    assert "(in-lane demonstrations)" in summary  # the rule the data runs were cut by
    assert hashlib.sha256(res.models["qavg"].read_bytes()).hexdigest() in summary
    # no wall time in the results: it is in timings.json
    assert "wall_time" not in res.models["qavg"].read_text()
    assert f"({res.wall_time_s:.0f} s)" not in summary
    assert set(json.loads((out / "timings.json").read_text())["fit_wall_time_s"]) == {"qavg", "planner"}


def test_run_demo_with_the_dagger_driver(tmp_path):
    """``dagger_rounds``: the car-following logit driver is trained after the IRL methods, saved
    beside them, evaluated on the same episodes and scored on the held-out demonstrations."""
    import hashlib

    from analysis.demo.config import CF_DRIVER
    from irl.domains.merge.car_following import car_following_decisions
    from irl.domains.merge.cf_logit import CarFollowingLogit
    from irl.domains.merge.mdp import read_encounters

    cfg = DemoConfig(train_seeds=(11,), heldout_seed=12, heldout_runs=2, data_duration_s=240.0, eval_episodes=1,
                     eval_duration_s=110.0, methods=("qavg",), dagger_rounds=1)
    res = run_demo(tmp_path / "demo", cfg, quiet=True, progress=False)
    # two held-out runs (seeds 12 and 13) in one held-out table, named in the summary
    heldout = read_encounters(tmp_path / "demo" / "data" / "heldout_encounters.parquet")
    assert set(heldout["encounter_id"] // 1_000_000) == {12, 13}
    assert res.n_heldout_encounters == heldout["encounter_id"].nunique()
    assert f"held-out data: {res.n_heldout_encounters} encounters from 2 runs" in res.format()
    cf = CarFollowingLogit.load(res.models[CF_DRIVER])
    assert res.models[CF_DRIVER].name == "cf-dagger.json" and cf.info["dagger_round"] == 1
    data = json.loads(res.evaluation.metrics_json.read_text())
    assert set(data["policies"]) == {"qavg", CF_DRIVER, "cf-logit", "planner", "sumo", "uniform", "marginal", "markov",
                                     "bc"}
    # the driver file is in the evaluation's provenance, as for evaluate --cf-model
    assert data["provenance"]["models"][CF_DRIVER]["sha256"] == hashlib.sha256(
        res.models[CF_DRIVER].read_bytes()).hexdigest()
    agg = data["policies"][CF_DRIVER]["aggregate"]
    assert agg["n_controls"] > 0
    held = car_following_decisions(read_encounters(tmp_path / "demo" / "data" / "heldout_encounters.parquet"))
    assert agg["heldout_loglik"] == pytest.approx(cf.loglik_of(held))
    assert CF_DRIVER in json.loads((tmp_path / "demo" / "timings.json").read_text())["fit_wall_time_s"]
