"""``merge-irl reproduce``: the paper's table layout, Wilcoxon p-values, held-out likelihood."""

import json
from pathlib import Path

import numpy as np
import pytest

from analysis.cli import main
from analysis.reproduce import reproduce, table_problem, wilcoxon_p
from analysis.trials import TrialTask, run_trial, run_trials, trial_seeds
from irl.config import IRLConfig

from shared_data import DATA as SHARED_DATA

DATA = SHARED_DATA / "railusm"
needs_data = pytest.mark.skipif(not DATA.is_dir(), reason="the authors' data is not on this machine")


def test_wilcoxon_handles_degenerate_inputs():
    assert wilcoxon_p(np.ones(5), np.ones(5)) == 1.0
    assert np.isnan(wilcoxon_p(np.ones(1), np.zeros(1)))
    p = wilcoxon_p(np.arange(10.0) + 1.0, np.zeros(10))
    assert 0 < p < 0.01


def test_trial_seeds_are_deterministic_and_distinct():
    a, b = trial_seeds(4, 6), trial_seeds(4, 6)
    assert a == b and len(set(a)) == 6 and trial_seeds(5, 6) != a


@needs_data
def test_cli_table_1_two_trials(tmp_path, capsys):
    out = tmp_path / "t1.json"
    rc = main(["reproduce", "--table", "1", "--data", str(DATA), "--trials", "2", "--no-holdout",
               "--json", str(out), "--no-progress"])
    assert rc == 0
    text = capsys.readouterr().out
    for label in ("MLIRL", "Q-Avg", "Q-SM", "REIRL", "θ_5 (blue)", "Final log-likelihood", "p vs MLIRL",
                  "paper Q-Avg"):
        assert label in text
    data = json.loads(out.read_text())
    assert data["table"] == 1 and len(data["trials"]) == 8 and data["holdout"] == []
    rows = {r["method"]: r for r in data["rows"]}
    assert set(rows) == {"mlirl", "qavg", "qsm", "reirl"}
    for r in rows.values():
        assert len(r["theta_mean"]) == 5 and r["n_trials"] == 2
    qavg = [t for t in data["trials"] if t["method"] == "qavg"]
    assert rows["qavg"]["loglik_mean"] == pytest.approx(np.mean([t["loglik"] for t in qavg]))
    assert rows["mlirl"]["p_vs_mlirl"] is None


@needs_data
def test_holdout_is_the_held_out_trajectory_likelihood():
    problem = table_problem(1, DATA)
    config = IRLConfig.paper(l2=0.01)
    task = TrialTask("qavg", problem, config, seed=1, holdout=3)
    out = run_trial(task)
    (again,) = run_trials([task], map_fn=lambda f, ts: [f(t) for t in ts])  # pure: same result again
    assert (again.theta, again.loglik, again.heldout_loglik) == (out.theta, out.loglik, out.heldout_loglik)
    # independently: fit on the other trajectories, score trajectory 3
    from analysis.learn import fit_problem
    from irl.boltzmann import log_policy

    fit = fit_problem(problem.subset([i for i in range(12) if i != 3]), "qavg", config, 1)
    lp = log_policy(fit.q, config.beta)
    s, a = problem.demos.states[3], problem.demos.actions[3]
    assert out.heldout_loglik == pytest.approx(lp[s, a].sum())
    assert out.heldout_loglik < 0


@needs_data
def test_reproduce_api_is_deterministic_and_uses_map_fn():
    calls = []

    def recording_map(fn, tasks):
        tasks = list(tasks)
        calls.append(len(tasks))
        return [fn(t) for t in tasks]

    kw = dict(trials=2, methods=("qavg", "reirl"), holdout=True, config=IRLConfig.paper(l2=0.01))
    r1 = reproduce(2, DATA, map_fn=recording_map, **kw)
    r2 = reproduce(2, DATA, **kw)
    assert calls == [2 * 2 + 2 * 14]  # 2 methods x (2 trials + 14 folds), one batch
    assert [t.theta for t in r1.trials] == [t.theta for t in r2.trials]
    assert [row.loglik_mean for row in r1.rows] == [row.loglik_mean for row in r2.rows]
    assert all(np.isfinite(row.heldout_loglik) for row in r1.rows)
    # the two trials start from different random thetas
    qavg = [t for t in r1.trials if t.method == "qavg"]
    assert qavg[0].seed != qavg[1].seed


@needs_data
def test_table_3_problem_is_the_authors_merge_data():
    p = table_problem(3, DATA)
    assert p.demos.n_steps == 1197 and p.transitions.shape == (1250, 5, 1250)
    assert p.bins is not None and p.pad_step() is not None
    sub = p.subset(range(11))
    assert sub.demos.n_trajectories == 11 and not np.array_equal(sub.transitions, p.transitions)
