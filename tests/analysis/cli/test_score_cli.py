"""``merge-irl score``: total log-likelihood and step count of any demonstrations under a model."""

import json
import subprocess
import sys

import numpy as np
import pytest
from irl_testdata import random_mdp

from analysis.cli.main import main
from irl.boltzmann import log_policy
from irl.io import save_npz
from irl.result import SavedModel


def _learn(tmp_path, demos_dir, extra=()):
    out = tmp_path / "model.json"
    assert main(["learn", "--method", "qavg", "--domain", "gridworld", "--demos", str(demos_dir), "--l2", "0.01",
                 "--out", str(out), "--no-progress", *extra]) == 0
    return out


def test_score_in_sample_equals_learned_loglik_and_held_out_is_recomputed(railusm, tmp_path, capsys):
    grid = railusm / "gridworld"
    model = _learn(tmp_path, grid / "noise_0.0_expert_trajs")
    capsys.readouterr()
    assert main(["score", "--model", str(model), "--demos", str(grid / "noise_0.0_expert_trajs"), "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    m = SavedModel.load(model)
    assert got["loglik"] == pytest.approx(m.loglik, rel=1e-9)
    # other demonstrations: the Eq. 5 sum recomputed by hand
    from irl.domains import gridworld

    d = gridworld.load(grid / "noise_0.1_expert_trajs")
    lp = log_policy(m.q, m.config.beta)
    assert main(["score", "--model", str(model), "--demos", str(grid / "noise_0.1_expert_trajs"), "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    assert got["n_steps"] == d.n_steps and got["n_trajectories"] == d.n_trajectories
    assert got["loglik"] == pytest.approx(sum(lp[s, a].sum() for s, a in zip(d.states, d.actions)), rel=1e-9)
    assert got["loglik_per_step"] == pytest.approx(got["loglik"] / got["n_steps"])
    assert main(["score", "--model", str(model), "--demos", str(grid / "noise_0.1_expert_trajs")]) == 0
    text = capsys.readouterr().out
    assert f"loglik {got['loglik']:.4f} over {d.n_steps} steps" in text


def test_score_npz_and_mismatched_demos_exit_2(tmp_path, capsys):
    _, d = random_mdp(1, n_states=6, n_actions=3)
    npz = save_npz(d, tmp_path / "d.npz")
    out = tmp_path / "m.json"
    assert main(["learn", "--method", "qavg", "--domain", "npz", "--demos", str(npz), "--l2", "0.1",
                 "--out", str(out), "--no-progress"]) == 0
    capsys.readouterr()
    assert main(["score", "--model", str(out), "--demos", str(npz), "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    assert got["n_steps"] == d.n_steps and got["loglik"] == pytest.approx(SavedModel.load(out).loglik, rel=1e-9)
    _, other = random_mdp(2, n_states=7, n_actions=3)
    bad = save_npz(other, tmp_path / "other.npz")
    r = subprocess.run([sys.executable, "-m", "analysis", "score", "--model", str(out), "--demos", str(bad)],
                       capture_output=True, text=True)
    assert r.returncode == 2
    assert r.stderr.count("\n") == 1 and "7 states x 3 actions" in r.stderr and "6 x 3" in r.stderr
    assert np.isfinite(got["loglik"])


def test_score_merge_table_uses_the_model_bins(tmp_path, capsys):
    import pandas as pd

    rng = np.random.default_rng(0)
    n, rows = 4, 30
    df = pd.DataFrame({
        "encounter_id": np.repeat(np.arange(n), rows), "frame": np.tile(np.arange(rows), n),
        "d_AC": rng.uniform(10, 150, n * rows), "d_AB": rng.uniform(0, 80, n * rows),
        "v_AC": rng.normal(0, 5, n * rows), "v_AB": rng.normal(0, 5, n * rows),
        "B_is_truck": np.repeat([0, 1, 0, 0], rows), "acc_A": rng.normal(0, 3, n * rows),
    })
    df.to_parquet(tmp_path / "all.parquet")
    df[df.encounter_id >= 2].to_parquet(tmp_path / "part.parquet")
    out = tmp_path / "m.json"
    assert main(["learn", "--method", "qavg", "--domain", "merge", "--demos", str(tmp_path / "all.parquet"),
                 "--settings", "reference", "--out", str(out), "--no-progress"]) == 0
    capsys.readouterr()
    assert main(["score", "--model", str(out), "--demos", str(tmp_path / "all.parquet"), "--json"]) == 0
    full = json.loads(capsys.readouterr().out)
    assert full["loglik"] == pytest.approx(SavedModel.load(out).loglik, rel=1e-9) and full["n_steps"] == n * (rows // 3 - 1)  # 0.3 s decisions, driver encoding from the 2nd
    assert main(["score", "--model", str(out), "--demos", str(tmp_path / "part.parquet"), "--json"]) == 0
    part = json.loads(capsys.readouterr().out)
    # discretized with the model's bins (not bins refitted on the part): the same per-trajectory values
    assert part["trajectory_logliks"] == pytest.approx(full["trajectory_logliks"][2:], rel=1e-12)


def test_score_reads_the_model_file_once(tmp_path, capsys, monkeypatch):
    """score checks the file's role and loads the model from one read of the file."""
    from pathlib import Path

    _, d = random_mdp(1, n_states=6, n_actions=3)
    npz = save_npz(d, tmp_path / "d.npz")
    out = tmp_path / "m.json"
    assert main(["learn", "--method", "qavg", "--domain", "npz", "--demos", str(npz), "--l2", "0.1",
                 "--out", str(out), "--no-progress"]) == 0
    capsys.readouterr()
    reads: list[Path] = []
    real = Path.read_text

    def counting(self: Path, *a, **kw) -> str:
        reads.append(self)
        return real(self, *a, **kw)

    monkeypatch.setattr(Path, "read_text", counting)
    assert main(["score", "--model", str(out), "--demos", str(npz), "--json"]) == 0
    assert reads.count(out) == 1
