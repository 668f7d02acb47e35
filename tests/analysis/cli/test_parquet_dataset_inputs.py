"""A Parquet dataset folder (pandas ``partition_cols``, or numbered part files) is read wherever a
table is: ``export-transitions``, ``learn`` and ``encounters`` give from it what they give from the
single file."""

import numpy as np
import pandas as pd
from ngsim_testdata import synthetic_table

from analysis.cli.main import main
from irl.result import SavedModel
from sim.merges.transitions import load
from sim.ngsim.io import read_trajectories


def _encounters() -> pd.DataFrame:
    rng = np.random.default_rng(0)
    n, rows = 11, 30  # 11 encounters: encounter_id=10 and 11 come after 9 in the folder too
    return pd.DataFrame({
        "encounter_id": np.repeat(np.arange(1, n + 1), rows), "Frame_ID": np.tile(np.arange(rows) + 100, n),
        "d_AC": rng.uniform(10, 150, n * rows), "d_AB": rng.uniform(0, 80, n * rows),
        "v_AC": rng.normal(0, 5, n * rows), "v_AB": rng.normal(0, 5, n * rows), "v_A": rng.uniform(20, 60, n * rows),
        "B_is_truck": np.repeat(np.arange(n) % 3 == 0, rows), "acc_A": rng.normal(0, 3, n * rows),
        "len_C": 15.0, "len_B": 16.0,
    })


def _partitioned(tmp_path):
    df = _encounters()
    df.to_parquet(tmp_path / "enc.parquet")
    df.to_parquet(tmp_path / "enc_ds", partition_cols=["encounter_id"])
    return tmp_path / "enc.parquet", tmp_path / "enc_ds"


def test_export_transitions_reads_a_partitioned_folder_as_the_file(tmp_path, capsys):
    one, folder = _partitioned(tmp_path)
    for src, out in ((one, tmp_path / "a.npz"), (folder, tmp_path / "b.npz")):
        assert main(["export-transitions", "--demos", str(src), "--out", str(out)]) == 0, capsys.readouterr().err
    a, b = load(tmp_path / "a.npz"), load(tmp_path / "b.npz")
    assert a.n > 0 and a.n_episodes == 11
    for name in ("obs", "next_obs", "acts", "dones", "episode"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))


def test_learn_reads_a_partitioned_folder_as_the_file(tmp_path, capsys):
    one, folder = _partitioned(tmp_path)
    for src, out in ((one, tmp_path / "a.json"), (folder, tmp_path / "b.json")):
        rc = main(["learn", "--method", "qavg", "--domain", "merge", "--demos", str(src), "--settings", "reference",
                   "--out", str(out), "--no-progress"])
        assert rc == 0, capsys.readouterr().err
    a, b = SavedModel.load(tmp_path / "a.json"), SavedModel.load(tmp_path / "b.json")
    assert a.feature_set == b.feature_set == "driver"  # an encounter table, not the authors' text folder
    np.testing.assert_array_equal(a.theta, b.theta)
    assert a.bin_edges == b.bin_edges


def test_encounters_reads_part_files_as_the_file(tmp_path, capsys):
    table = synthetic_table(n_vehicles=12)
    table.to_parquet(tmp_path / "traj.parquet")
    (tmp_path / "traj_ds").mkdir()
    for i, v0 in enumerate(range(1, 13, 4)):  # three part files of four vehicles each
        part = table[(table["Vehicle_ID"] >= v0) & (table["Vehicle_ID"] < v0 + 4)]
        part.to_parquet(tmp_path / "traj_ds" / f"part.{i}.parquet")
    pd.testing.assert_frame_equal(read_trajectories(tmp_path / "traj_ds"), table)
    outs = []
    for src, out in ((tmp_path / "traj.parquet", tmp_path / "a" / "e.parquet"),
                     (tmp_path / "traj_ds", tmp_path / "b" / "e.parquet")):
        assert main(["encounters", str(src), "--out", str(out)]) == 0
        outs.append((pd.read_parquet(out), pd.read_parquet(out.with_name("e.merges.parquet"))))
        assert "merges" in capsys.readouterr().err
    pd.testing.assert_frame_equal(outs[0][0], outs[1][0])
    pd.testing.assert_frame_equal(outs[0][1], outs[1][1])


def test_a_folder_of_different_tables_is_refused_in_one_line(tmp_path, capsys):
    run = tmp_path / "run"
    run.mkdir()
    _encounters().to_parquet(run / "encounters.parquet")
    synthetic_table(n_vehicles=2).to_parquet(run / "trajectories.parquet")  # another table: not one dataset
    out = tmp_path / "m.json"
    assert main(["learn", "--method", "qavg", "--domain", "merge", "--demos", str(run), "--out", str(out),
                 "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "its Parquet files are not the part files of one table" in err[0], err
    assert main(["export-transitions", "--demos", str(run), "--out", str(tmp_path / "t.npz")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "a folder, not a file or a Parquet dataset folder" in err[0], err
    assert not out.exists() and not (tmp_path / "t.npz").exists()
