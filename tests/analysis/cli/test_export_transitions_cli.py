"""``merge-irl export-transitions``: encounter tables, NGSIM files and decision logs of one real
SUMO run into one .npz, read back by sim.merges.transitions.load; bad inputs exit 2 with one line."""

from __future__ import annotations

import numpy as np
import pytest
from extras import require_extra
from sim_testutil import short_run

from analysis.cli.main import main
from sim.closed_loop.config import ControllerConfig
from sim.closed_loop.controller import Controller
from sim.drivers.policy import SumoPolicy
from sim.merges.encounters import extract
from sim.merges.transitions import from_decisions, from_encounters, from_trajectories, load
from sim.ngsim.write import write_ngsim_csv


@pytest.mark.sumo
def test_export_transitions_of_every_source(tmp_path, capsys) -> None:
    ctl = Controller(SumoPolicy(), ControllerConfig())
    res = short_run(tmp_path, seed=11, duration_s=180.0, hooks=[ctl])
    enc = extract(res.table).frames  # the merge-frame rule, as `merge-irl encounters`
    enc.to_parquet(tmp_path / "enc.parquet")
    ngsim = write_ngsim_csv(res.table, tmp_path / "run.csv", precision="exact")
    ctl.decision_table().to_csv(tmp_path / "decisions.csv", index=False)
    out = tmp_path / "t" / "demos.npz"
    assert main(["export-transitions", "--demos", str(tmp_path / "enc.parquet"), str(ngsim),
                 str(tmp_path / "decisions.csv"), "--out", str(out)]) == 0
    assert capsys.readouterr().out.strip() == str(out)
    t = load(out)
    parts = [from_encounters(enc), from_trajectories(res.table), from_decisions(ctl.decision_table())]
    assert t.n == sum(p.n for p in parts) and t.n_episodes == sum(p.n_episodes for p in parts)
    assert all(p.n_episodes > 0 for p in parts)
    n0, n1 = parts[0].n, parts[0].n + parts[1].n
    np.testing.assert_array_equal(t.obs[:n0], parts[0].obs)
    np.testing.assert_allclose(t.obs[n0:n1], parts[1].obs, rtol=1e-12)  # the NGSIM file: the same merges
    np.testing.assert_array_equal(t.acts[n1:], parts[2].acts)
    assert t.episode[n0] == parts[0].n_episodes and t.dones.sum() == t.n_episodes
    (tmp_path / "other.csv").write_text("x,y\n1,2\n")
    # a decision log decided at another step than asked for is refused, as is what is no demonstration
    for argv, said in ((["--demos", str(tmp_path / "decisions.csv"), "--decision-step-s", "0.5"], "decided every 0.3 s"),
                       (["--demos", str(tmp_path / "none.parquet")], "no such file"),
                       (["--demos", str(out)], "expected a .parquet, .csv or .txt file"),
                       (["--demos", str(tmp_path / "other.csv")], "neither an encounter table"),
                       (["--demos", str(tmp_path / "enc.parquet"), "--decision-step-s", "0.25"], "multiple of 0.1"),
                       (["--demos", str(tmp_path / "enc.parquet"), "--smooth"], "NGSIM .csv/.txt files only")):
        assert main(["export-transitions", *argv, "--out", str(tmp_path / "bad.npz")]) == 2
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1 and said in err, (argv, err)
        assert not (tmp_path / "bad.npz").exists()
    assert main(["export-transitions", "--demos", str(tmp_path / "enc.parquet"), "--out", str(tmp_path / "x.txt")]) == 2
    assert ".npz" in capsys.readouterr().err


def test_a_run_folder_is_named_as_a_folder_not_as_missing(tmp_path, capsys) -> None:
    """``--demos runs/gen`` (a generate run's folder) said 'no such file' of a folder that exists."""
    run = tmp_path / "gen"
    run.mkdir()
    (run / "encounters.parquet").write_bytes(b"")
    assert main(["export-transitions", "--demos", str(run), "--out", str(tmp_path / "t.npz")]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "a folder, not a file" in err, err
    assert str(run / "encounters.parquet") in err and not (tmp_path / "t.npz").exists()


@pytest.mark.sumo
def test_export_transitions_to_minari_of_a_real_run(tmp_path, capsys, monkeypatch) -> None:
    """``--format minari``: a real run's encounters as a Minari dataset that minari.load_dataset
    reads back (episodes, rewards, terminations, the input's provenance); an existing id refused
    in one line (exit 2) until ``--overwrite``; ``--help`` names the format."""
    minari = require_extra("minari", "rl")
    from merge_irl.provenance import file_sha256

    res = short_run(tmp_path, seed=11, duration_s=180.0)
    enc = extract(res.table).frames
    enc.to_parquet(tmp_path / "enc.parquet")
    expected = from_encounters(enc)
    argv = ["export-transitions", "--demos", str(tmp_path / "enc.parquet"), "--format", "minari",
            "--dataset-id", "merge-irl/run11-v0", "--out", str(tmp_path / "minari")]
    assert main(argv) == 0
    assert capsys.readouterr().out.strip() == str(tmp_path / "minari" / "merge-irl" / "run11-v0")
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "minari"))
    ds = minari.load_dataset("merge-irl/run11-v0")
    assert ds.total_episodes == expected.n_episodes > 0 and ds.total_steps == expected.n
    episodes = list(ds.iterate_episodes())
    assert all(e.terminations[-1] and not e.terminations[:-1].any() and not e.rewards.any() for e in episodes)
    np.testing.assert_array_equal(np.concatenate([e.actions for e in episodes]), expected.acts)
    prov = ds.storage.metadata["merge_irl"]["provenance"]
    assert prov["inputs"]["demos"]["sha256"] == file_sha256(tmp_path / "enc.parquet")
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "exists already" in err and "--overwrite" in err
    assert main([*argv, "--overwrite"]) == 0
    capsys.readouterr()
    for bad, said in ((["--dataset-id", "nover"], "not a Minari dataset id"), ([], "needs --dataset-id")):
        args = ["export-transitions", "--demos", str(tmp_path / "enc.parquet"), "--format", "minari", *bad,
                "--out", str(tmp_path / "minari")]
        assert main(args) == 2 and said in capsys.readouterr().err
    assert sorted(p.name for p in (tmp_path / "minari").iterdir()) == ["merge-irl"]  # nothing else left
    with pytest.raises(SystemExit):
        main(["export-transitions", "--help"])
    assert "--format {npz,minari}" in capsys.readouterr().out
