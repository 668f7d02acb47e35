"""``benchmarks/imitation_bench.py`` without torch: its observation statistics, its reading of
GAIL's CSV log, that it (and ``benchmarks/gail_diagnosis.py``) imports and answers ``--help``
without torch, imitation or Stable-Baselines3, and that its extra stays out of the default
install and the ``test`` extra. The training and the table need the
``imitation-bench`` extra and run as the benchmark only (docs/imitation.md)."""

from __future__ import annotations

import os
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np

import math

import pytest

from benchmarks.gail_diagnosis import parse_config
from benchmarks.imitation_bench import GAIL_LOG_COLUMNS, GailConfig, ObsScaler, gail_log_summary
from sim.drivers.observe import NO_LEAD_GAP_FT, policy_rows

ROOT = Path(__file__).resolve().parents[2]
HEAVY = ("torch", "imitation", "stable_baselines3", "benchmarks.imitation_nets")


def test_scaler_fills_the_missing_lead_car_and_standardises_on_the_training_rows() -> None:
    rng = np.random.default_rng(0)
    obs = np.column_stack([rng.uniform(20, 200, 40), rng.normal(0, 5, 40), rng.uniform(-60, 60, 40),
                           rng.normal(0, 5, 40), rng.uniform(40, 90, 40), np.full(40, 15.0), np.full(40, 16.0)])
    obs[:5, [0, 1, 5]] = np.nan  # no lead car C in the first five decisions
    obs[5, 6] = np.nan  # B's length unknown once
    sc = ObsScaler.fit(obs)
    x = sc(obs)
    assert x.dtype == np.float32 and x.shape == (40, 7) and np.isfinite(x).all()
    np.testing.assert_allclose(x.mean(axis=0), 0.0, atol=1e-5)
    varying = np.asarray(sc.std) != 1.0
    np.testing.assert_allclose(x[:, varying].std(axis=0), 1.0, atol=1e-5)
    # the no-lead rows read as a car NO_LEAD_GAP_FT ahead at A's speed, as the environment's observation
    np.testing.assert_allclose(policy_rows(obs)[:5, :2], np.tile([NO_LEAD_GAP_FT, 0.0], (5, 1)))
    np.testing.assert_allclose(x[:5, 0], (NO_LEAD_GAP_FT - sc.mean[0]) / sc.std[0], rtol=1e-6)
    # one observation (the callable's [7]) scales like its row; a policy observation (already
    # filled) scales like the continuous row it came from
    np.testing.assert_array_equal(sc(obs[7]), x[7:8])
    np.testing.assert_array_equal(sc(policy_rows(obs)), x)


def test_the_bench_imports_and_answers_help_without_torch() -> None:
    code = ("import sys, runpy\n"
            "import benchmarks.imitation_bench\n"
            f"heavy = [m for m in {HEAVY!r} if m in sys.modules]\n"
            "assert not heavy, heavy\n"
            "sys.argv = ['imitation_bench', '--help']\n"
            "runpy.run_module('benchmarks.imitation_bench', run_name='__main__')\n")
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    r = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr[-2000:]
    assert "--gail-steps" in r.stdout and "--bc-epochs" in r.stdout


def test_the_imitation_bench_extra_stays_out_of_the_default_install_and_the_tests() -> None:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    extra = project["optional-dependencies"]["imitation-bench"]
    assert "torch==2.13.0" in extra and "imitation==1.0.1" in extra

    def names(reqs: list[str]) -> set[str]:
        return {r.split("[")[0].split("=")[0].split(">")[0].split("<")[0].strip().lower() for r in reqs}

    for where, reqs in (("dependencies", project["dependencies"]),
                        ("test", project["optional-dependencies"]["test"])):
        assert not names(reqs) & {"torch", "imitation", "stable-baselines3"}, where


def test_gail_log_summary_reads_first_and_last_round_and_negates_the_entropy_loss(tmp_path: Path) -> None:
    cols = list(GAIL_LOG_COLUMNS.values())
    rows = [{"mean/gen/time/total_timesteps": "512", "mean/gen/train/entropy_loss": "-1.609",
             "mean/gen/train/approx_kl": "0.0001", "mean/disc/disc_loss": "0.70", "mean/disc/disc_acc": "0.5",
             "mean/gen/rollout/ep_len_mean": ""},
            {"mean/gen/time/total_timesteps": "1024", "mean/gen/train/entropy_loss": "-1.2",
             "mean/gen/train/approx_kl": "0.01", "mean/disc/disc_loss": "0.55", "mean/disc/disc_acc": "0.7",
             "mean/gen/rollout/ep_len_mean": "24.5"}]
    log = tmp_path / "progress.csv"
    log.write_text(",".join(["other", *cols]) + "\n"
                   + "\n".join(",".join(["9", *(r[c] for c in cols)]) for r in rows) + "\n", encoding="utf-8")
    s = gail_log_summary(log)
    assert set(s) == set(GAIL_LOG_COLUMNS)
    assert s["steps"] == (512.0, 1024.0)
    assert s["entropy"] == (1.609, 1.2)
    assert s["disc_loss"] == (0.70, 0.55)
    assert math.isnan(s["ep_len"][0]) and s["ep_len"][1] == 24.5
    (tmp_path / "empty.csv").write_text(",".join(cols) + "\n", encoding="utf-8")
    with pytest.raises(ValueError, match="no rounds"):
        gail_log_summary(tmp_path / "empty.csv")


def test_the_gail_diagnosis_answers_help_and_refuses_a_missing_demo_without_torch(tmp_path: Path) -> None:
    code = ("import sys, runpy\n"
            "import benchmarks.gail_diagnosis\n"
            f"heavy = [m for m in {HEAVY!r} if m in sys.modules]\n"
            "assert not heavy, heavy\n"
            "sys.argv = ['gail_diagnosis', *sys.argv[1:]]\n"
            "runpy.run_module('benchmarks.gail_diagnosis', run_name='__main__')\n")
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    r = subprocess.run([sys.executable, "-c", code, "--help"], cwd=ROOT, env=env, capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0, r.stderr[-2000:]
    assert "--config" in r.stdout and "--demo" in r.stdout
    r = subprocess.run([sys.executable, "-c", code, "--demo", str(tmp_path), "--config", "{}"], cwd=ROOT, env=env,
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "no data/train_encounters.parquet" in r.stderr


def test_gail_config_refuses_what_imitation_would_fail_on_late() -> None:
    assert GailConfig().steps == 32768 and GailConfig().steps % GailConfig().n_steps == 0
    for bad in ({"steps": 100}, {"n_steps": 0}, {"disc_updates": 0}, {"learning_rate": 0.0}, {"gamma": 1.5},
                {"ent_coef": -0.1}):
        with pytest.raises(ValueError, match="GAIL's"):
            GailConfig(**bad)
    assert parse_config('{"steps": 1024, "disc_updates": 16}') == GailConfig(steps=1024, disc_updates=16)
    for bad_text in ("{steps: 1}", "[1]", '{"stepz": 1}', '{"steps": 0}'):
        with pytest.raises(ValueError):
            parse_config(bad_text)


def test_the_bench_refuses_a_gail_budget_below_one_round_in_one_line() -> None:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    r = subprocess.run([sys.executable, "-m", "benchmarks.imitation_bench", "--gail-steps", "100"], cwd=ROOT, env=env,
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "at least one round" in r.stderr, r.stderr[-2000:]
