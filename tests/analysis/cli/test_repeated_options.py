"""One meaning of a repeated option everywhere: every --demos is read whether repeated or listed
(export-transitions before: the last of three, 186 of 690 transitions), kept apart as sources or
merged (score: one set); an option that takes one value refuses a second instead of keeping only
the last."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
from irl_testdata import planning_encounters

from sim.merges.transitions import load


def _cli(*args, cwd=None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "analysis", *args], capture_output=True, text=True, timeout=180,
                          cwd=cwd)


def test_export_transitions_reads_every_repeated_demos(tmp_path) -> None:
    files = []
    for i in range(3):
        f = tmp_path / f"enc{i}.parquet"
        planning_encounters(n=2 + i, seed=i).to_parquet(f)
        files.append(str(f))
    r = _cli("export-transitions", "--demos", files[0], "--demos", files[1], "--demos", files[2],
             "--out", str(tmp_path / "rep.npz"))
    assert r.returncode == 0, r.stderr
    r = _cli("export-transitions", "--demos", *files, "--out", str(tmp_path / "list.npz"))
    assert r.returncode == 0, r.stderr
    each = []
    for i, f in enumerate(files):
        assert _cli("export-transitions", "--demos", f, "--out", str(tmp_path / f"one{i}.npz")).returncode == 0
        each.append(len(load(tmp_path / f"one{i}.npz").acts))
    rep, lst = load(tmp_path / "rep.npz"), load(tmp_path / "list.npz")
    assert len(rep.acts) == len(lst.acts) == sum(each) and len(set(each)) == 3
    assert (rep.acts == lst.acts).all() and int(rep.episode.max()) + 1 == 2 + 3 + 4


def test_score_reads_every_demos_as_one_set(tmp_path) -> None:
    from analysis.cli.main import main

    files = []
    for i in range(2):
        f = tmp_path / f"enc{i}.parquet"
        planning_encounters(n=2 + i, seed=i).to_parquet(f)
        files.append(str(f))
    model = tmp_path / "m.json"
    assert main(["learn", "--method", "qavg", "--domain", "merge", "--demos", *files, "--out", str(model),
                 "--no-progress"]) == 0
    rep = _cli("score", "--model", str(model), "--demos", files[0], "--demos", files[1], "--json")
    lst = _cli("score", "--model", str(model), "--demos", *files, "--json")
    one = [_cli("score", "--model", str(model), "--demos", f, "--json") for f in files]
    assert rep.returncode == lst.returncode == 0, rep.stderr
    both, each = json.loads(rep.stdout), [json.loads(r.stdout) for r in one]
    assert json.loads(lst.stdout) == both
    assert both["n_steps"] == sum(e["n_steps"] for e in each) and len(set(e["n_steps"] for e in each)) == 2
    assert both["loglik"] == pytest.approx(sum(e["loglik"] for e in each))
    assert both["trajectory_logliks"] == each[0]["trajectory_logliks"] + each[1]["trajectory_logliks"]


@pytest.mark.parametrize("args, option", [
    (["evaluate", "--train-demos", "a.parquet", "--train-demos", "b.parquet"], "--train-demos"),
    (["calibrate", "fit", "--pairs", "x", "--pairs", "y", "--out", "p.toml"], "--pairs"),
    (["calibrate", "check", "--params", "p.toml", "--pairs", "x", "--pairs", "y"], "--pairs"),
])
def test_a_one_value_option_given_twice_is_refused(tmp_path, args, option) -> None:
    r = _cli(*args, cwd=tmp_path)
    assert r.returncode == 2
    last = r.stderr.strip().splitlines()[-1]
    assert f"{option} given twice" in last and "would keep only the last" in last, r.stderr


def test_evaluate_reads_every_demos_as_one_held_out_set(tmp_path) -> None:
    """evaluate --demos a --demos b (or --demos a b): both tables, their encounters kept apart."""
    from analysis.cli.commands.evaluate import _demos
    from analysis.evaluation.heldout_scoring import load_heldout

    files = []
    for i in range(2):
        f = tmp_path / f"enc{i}.parquet"
        planning_encounters(n=2 + i, seed=i).to_parquet(f)
        files.append(str(f))
    assert _demos([files[0]]) == files[0] and _demos(files) == tuple(files) and _demos(None) is None
    each = [load_heldout(f) for f in files]
    both = load_heldout(_demos(files))
    assert len(both.encounters) == sum(len(h.encounters) for h in each)
    assert both.encounters["encounter_id"].nunique() == sum(h.encounters["encounter_id"].nunique() for h in each)
    assert (both.action_counts == sum(h.action_counts for h in each)).all()
