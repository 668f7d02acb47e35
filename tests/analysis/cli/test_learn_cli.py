"""``merge-irl learn`` writes a model.json that SavedModel.load reads back."""

import subprocess
import sys

import numpy as np
import pytest
from irl_testdata import encounter_table, gridworld_demos

from analysis.cli.main import main
from irl.boltzmann import log_policy
from irl.domains import gridworld
from irl.domains.merge.bins import MergeBins, fit_quantile_bins
from irl.io import save_npz, save_text_trajectories
from irl.result import SavedModel


def test_learn_gridworld_qavg_round_trip(tmp_path, capsys):
    out = tmp_path / "model.json"
    demos_dir = tmp_path / "noise_0.1_expert_trajs"
    save_text_trajectories(gridworld_demos("0.1"), demos_dir)  # the authors' text format
    rc = main(["learn", "--method", "qavg", "--domain", "gridworld", "--noise", "0.1",
               "--demos", str(demos_dir), "--l2", "0.01",
               "--seed", "3", "--out", str(out), "--no-progress"])
    assert rc == 0
    assert "wrote" in capsys.readouterr().out
    m = SavedModel.load(out)
    assert m.method == "qavg" and m.domain == "gridworld" and m.theta.shape == (5,)
    assert m.config.l2 == 0.01 and m.config.gamma == 0.99 and m.info["seed"] == 3
    assert m.feature_names == ("yellow", "green", "red", "pink", "blue")
    assert m.q.shape == (25, 4) and m.bin_edges == {}
    # loglik is the Eq. 5 sum under the saved Q, recomputed independently here
    d = gridworld.load(demos_dir)
    assert d.n_steps == gridworld_demos("0.1").n_steps
    lp = log_policy(m.q, m.config.beta)
    assert m.loglik == pytest.approx(sum(lp[s, a].sum() for s, a in zip(d.states, d.actions)), rel=1e-9)


def test_learn_shows_progress_lines_when_stderr_is_a_log_file(tmp_path):
    """A fit run from a batch job (stderr a file, not a terminal) says how far it is,
    and --no-progress silences it."""
    demos_dir = tmp_path / "noise_0.1_expert_trajs"
    save_text_trajectories(gridworld_demos("0.1"), demos_dir)
    cmd = [sys.executable, "-m", "analysis", "learn", "--method", "qavg", "--domain", "gridworld", "--noise", "0.1",
           "--demos", str(demos_dir), "--seed", "3"]
    log = tmp_path / "stderr.log"
    with open(log, "w") as err:
        r = subprocess.run([*cmd, "--out", str(tmp_path / "a.json")], stderr=err, stdout=subprocess.PIPE,
                           text=True, timeout=300)
    assert r.returncode == 0, log.read_text()
    lines = [ln for ln in log.read_text().splitlines() if "qavg exact" in ln]
    assert lines and "\r" not in log.read_text(), log.read_text()
    r = subprocess.run([*cmd, "--out", str(tmp_path / "b.json"), "--no-progress"], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0 and "qavg exact" not in r.stderr, r.stderr


def test_learn_merge_encounter_table_saves_fitted_bins(tmp_path):
    rng = np.random.default_rng(0)
    import pandas as pd

    n, rows = 4, 30
    df = pd.DataFrame({
        "encounter_id": np.repeat(np.arange(n), rows), "frame": np.tile(np.arange(rows), n),
        "d_AC": rng.uniform(10, 150, n * rows), "d_AB": rng.uniform(0, 80, n * rows),
        "v_AC": rng.normal(0, 5, n * rows), "v_AB": rng.normal(0, 5, n * rows),
        "B_is_truck": np.repeat([0, 1, 0, 0], rows), "acc_A": rng.normal(0, 3, n * rows),
    })
    table = tmp_path / "enc.parquet"
    df.to_parquet(table)
    out = tmp_path / "m.json"
    rc = main(["learn", "--method", "qavg", "--domain", "merge", "--demos", str(table), "--settings", "reference",
               "--out", str(out), "--no-progress"])
    assert rc == 0
    m = SavedModel.load(out)
    bins = MergeBins.from_dict({k: list(v) for k, v in m.bin_edges.items()})
    assert bins == fit_quantile_bins(df)
    assert m.config.gamma == 0.9 and m.q.shape == (6250, 5)  # encounter tables: driver features by default
    assert (m.state_encoding, m.feature_set, m.decision_step_s, m.config.beta) == ("driver", "driver", 0.3, 1.0)
    assert m.action_acc_ft_s2 != (-8.0, -2.7, 0.0, 2.7, 8.0)  # the data's per-action means


def test_learn_npz_reirl(tmp_path):
    p = save_npz(gridworld_demos("0.0"), tmp_path / "d.npz", feature_names=gridworld.FEATURE_NAMES)
    base = save_npz(gridworld_demos("0.0", "baseline"), tmp_path / "b.npz")
    out = tmp_path / "m.json"
    assert main(["learn", "--method", "reirl", "--domain", "npz", "--demos", str(p), "--baseline", str(base),
                 "--epsilon", "0.05", "--out", str(out), "--no-progress"]) == 0
    m = SavedModel.load(out)
    assert m.method == "reirl" and m.feature_names == gridworld.FEATURE_NAMES and m.info["extra"]["epsilon"] == 0.05


def test_learn_bad_input_is_one_line_exit_2(tmp_path):
    bad = tmp_path / "trajs"
    bad.mkdir()
    (bad / "t_0.txt").write_text("3\t1\t\n99\t0\t\n")
    r = subprocess.run([sys.executable, "-m", "analysis", "learn", "--method", "qavg", "--domain", "gridworld",
                        "--demos", str(bad), "--out", str(tmp_path / "m.json")], capture_output=True, text=True)
    assert r.returncode == 2
    assert "t_0.txt:2: state 99 out of range [0, 25)" in r.stderr
    assert not (tmp_path / "m.json").exists()


def test_merge_defaults_have_one_home(tmp_path):
    """``merge-irl learn`` and ``merge-irl demo`` take the merge settings from analysis.experiments.learn."""
    from analysis.experiments.learn import merge_config, merge_encoding, merge_features
    from irl.problems import DOMAINS
    d = DOMAINS["merge"].defaults
    from irl.config import IRLConfig

    cfg = merge_config()
    assert (cfg.beta, cfg.l2, cfg.gamma) == (d.beta, d.l2, IRLConfig.paper().gamma) == (1.0, 0.0, 0.99)
    ref = merge_config(IRLConfig.reference(), l2=0.5, gamma=0.0)
    assert (ref.beta, ref.l2, ref.gamma, ref.alpha) == (1.0, 0.5, 0.0, IRLConfig.reference().alpha)
    assert merge_config(beta=5.0).beta == 5.0
    folder = tmp_path / "merge_ngsim"
    folder.mkdir()
    assert merge_features(folder) == "paper" and merge_features(tmp_path / "a.txt") == "paper"
    assert merge_features(tmp_path / "enc.parquet") == "driver"
    assert merge_features([tmp_path / "enc.parquet", tmp_path / "b.csv"]) == "driver"
    assert merge_features(tmp_path / "enc.parquet", "paper") == "paper"
    assert (merge_encoding("driver"), merge_encoding("paper"), merge_encoding(("safe",))) == ("driver", "paper", "paper")


def test_learn_says_where_an_encounter_table_has_missing_frames(tmp_path):
    """The split at a recording's gap is counted in learn's one-line report."""
    df = encounter_table(n=3, rows=60)
    df = df[~((df.encounter_id == 2) & df.Frame_ID.between(1020, 1033))]
    path = tmp_path / "enc.parquet"
    df.to_parquet(path)
    r = subprocess.run([sys.executable, "-m", "analysis", "learn", "--method", "qavg", "--domain", "merge",
                        "--demos", str(path), "--l2", "0.1", "--no-progress", "--out", str(tmp_path / "model.json")],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    said = [ln for ln in r.stderr.splitlines() if "missing frames" in ln]
    assert len(said) == 1 and said[0].startswith("merge-irl learn: warning: ")
    assert "1 encounter(s) have missing frames (1 gap(s), 14 frames): each is split at its gaps" in said[0]
