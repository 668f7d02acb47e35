"""``merge-irl reproduce``: the paper's table layout, Wilcoxon p-values, held-out likelihood."""

import json
from dataclasses import replace

import numpy as np
import pytest

from analysis.cli.main import main
from analysis.experiments.reproduce import ReproduceConfig, reproduce, reproduce_tables
from analysis.experiments.reproduce_report import wilcoxon_p
from analysis.experiments.trials import TrialOutcome, TrialTask, run_trial, run_trials, table_problem, trial_seeds
from irl.config import IRLConfig


def test_wilcoxon_handles_degenerate_inputs():
    assert wilcoxon_p(np.ones(5), np.ones(5)) == 1.0
    assert np.isnan(wilcoxon_p(np.ones(1), np.zeros(1)))
    p = wilcoxon_p(np.arange(10.0) + 1.0, np.zeros(10))
    assert 0 < p < 0.01


def test_without_data_says_where_the_authors_data_come_from(capsys):
    assert main(["reproduce", "--table", "1", "--no-progress"]) == 2
    captured = capsys.readouterr()
    err = captured.err.strip().splitlines()
    assert len(err) == 1 and captured.out == ""
    assert err[0].startswith("merge-irl reproduce: error: --data DIR is required")
    assert "github.com/RAILUSM/Model-free-IRL" in err[0] and "folder data/" in err[0]


def test_trial_seeds_are_deterministic_and_distinct():
    a, b = trial_seeds(4, 6), trial_seeds(4, 6)
    assert a == b and len(set(a)) == 6 and trial_seeds(5, 6) != a


def test_cli_table_1_two_trials(railusm, tmp_path, capsys):
    out = tmp_path / "t1.json"
    rc = main(["reproduce", "--table", "1", "--data", str(railusm), "--trials", "2", "--no-holdout",
               "--json-out", str(out), "--no-progress", "--executor", "serial"])
    assert rc == 0
    text = capsys.readouterr().out
    for label in ("MLIRL", "Q-Avg", "Q-SM", "REIRL", "θ_5 (blue)", "Final log-likelihood", "p vs MLIRL",
                  "paper Q-Avg"):
        assert label in text
    data = json.loads(out.read_text())
    assert data["table"] == 1 and len(data["trials"]) == 8 and data["holdout"] == []
    rows = {r["method"]: r for r in data["rows"]}
    assert set(rows) == {"mlirl", "qavg", "qsm", "reirl", "uniform", "marginal", "markov", "bc"}
    for m in ("mlirl", "qavg", "qsm", "reirl"):
        assert len(rows[m]["theta_mean"]) == 5 and rows[m]["n_trials"] == 2
    assert rows["bc"]["theta_mean"] == [] and rows["bc"]["heldout_loglik"] is None
    qavg = [t for t in data["trials"] if t["method"] == "qavg"]
    assert rows["qavg"]["loglik_mean"] == pytest.approx(np.mean([t["loglik"] for t in qavg]))
    assert rows["mlirl"]["p_vs_mlirl"] is None
    # provenance: the folders table 1 read; wall times beside the file, not in it
    from merge_irl.provenance import path_digest

    inputs = data["provenance"]["inputs"]
    assert inputs["table1_demos"]["sha256"] == path_digest(railusm / "gridworld" / "noise_0.0_expert_trajs")["sha256"]
    assert set(inputs) == {"table1_demos", "table1_baseline"}
    assert "wall_time" not in out.read_text() and "time_mean_s" not in out.read_text()
    timings = json.loads((tmp_path / "t1.timings.json").read_text())
    assert {m: len(v) for m, v in timings["trials"].items()} == {"mlirl": 2, "qavg": 2, "qsm": 2, "reirl": 2}


def test_holdout_is_the_held_out_trajectory_likelihood(railusm):
    problem = table_problem(1, railusm)
    config = IRLConfig.paper(l2=0.01)
    task = TrialTask("qavg", problem, config, seed=1, holdout=3)
    out = run_trial(task)
    (again,) = run_trials([task], map_fn=lambda f, ts: [f(t) for t in ts])  # pure: same result again
    assert (again.theta, again.loglik, again.heldout_loglik) == (out.theta, out.loglik, out.heldout_loglik)
    # independently: fit on the other trajectories, score trajectory 3
    from analysis.experiments.learn import fit_problem
    from irl.boltzmann import log_policy

    fit = fit_problem(problem.subset([i for i in range(12) if i != 3]), "qavg", config, 1)
    lp = log_policy(fit.q, config.beta)
    s, a = problem.demos.states[3], problem.demos.actions[3]
    assert out.heldout_loglik == pytest.approx(lp[s, a].sum())
    assert out.heldout_loglik < 0


def test_reproduce_api_is_deterministic_and_pairs_trials(railusm):
    config = ReproduceConfig(railusm, trials=2, methods=("qavg", "reirl"), holdout=True,
                             irl_config=IRLConfig.paper(l2=0.01), executor="serial")
    r1 = reproduce(2, config)
    r2 = reproduce(2, config)
    assert len(r1.trials) == 2 * 2 and len(r1.holdout) == 2 * 14 and r1.failures == ()
    assert [t.theta for t in r1.trials] == [t.theta for t in r2.trials]
    assert [row.loglik_mean for row in r1.rows] == [row.loglik_mean for row in r2.rows]
    assert all(np.isfinite(row.heldout_loglik) for row in r1.rows)
    # the two trials start from different random thetas; trial j has the same seed for every method
    qavg = [t for t in r1.trials if t.method == "qavg"]
    reirl = [t for t in r1.trials if t.method == "reirl"]
    assert qavg[0].seed != qavg[1].seed and [t.seed for t in qavg] == [t.seed for t in reirl]
    assert [t.seed for t in qavg] == trial_seeds(0, 2)  # the seeds used before the sweep runner


def _trial_key(o: TrialOutcome):
    return (o.method, o.seed, o.holdout, o.theta, o.loglik, o.converged, o.n_iterations, o.message,
            None if np.isnan(o.heldout_loglik) else o.heldout_loglik)


def test_serial_and_process_executors_give_identical_tables(railusm):
    config = ReproduceConfig(railusm, trials=2, methods=("qavg", "reirl"), holdout=False)
    serial = reproduce_tables([1, 3], replace(config, executor="serial"))
    pooled = reproduce_tables([1, 3], replace(config, executor="process:2"))
    assert serial.ok and pooled.ok and pooled.sweep.n_run == serial.sweep.n_run == 2 * 2 * 2
    for a, b in zip(serial.reports, pooled.reports):
        assert [_trial_key(o) for o in a.trials] == [_trial_key(o) for o in b.trials]
        strip = lambda r: {k: v for k, v in r.__dict__.items() if k != "time_mean_s"}  # noqa: E731
        assert [repr(strip(r)) for r in a.rows] == [repr(strip(r)) for r in b.rows]  # repr: NaN == NaN


def test_resumed_reproduce_skips_finished_trials(railusm, tmp_path):
    store = tmp_path / "store"
    config = ReproduceConfig(railusm, trials=2, methods=("qavg", "reirl"), holdout=False, executor="serial", store=store)
    first = reproduce_tables([1], config)
    assert first.sweep.n_run == 4 and first.sweep.n_cached == 0
    files = sorted(store.glob("*.json"))
    assert len(files) == 4
    files[0].unlink()  # as if the run had been killed before this trial finished
    again = reproduce_tables([1], config)
    assert again.sweep.n_cached == 3 and again.sweep.n_run == 1
    assert [_trial_key(o) for o in again.reports[0].trials] == [_trial_key(o) for o in first.reports[0].trials]
    # another master seed is another set of trials: nothing reused
    other = reproduce_tables([1], replace(config, trials=1, seed=1))
    assert other.sweep.n_cached == 0


def test_cli_reports_failed_trials_and_exits_nonzero(railusm, tmp_path, capsys):
    store = tmp_path / "s"
    args = ["reproduce", "--table", "1", "--data", str(railusm), "--trials", "1", "--no-holdout", "--no-progress",
            "--executor", "serial", "--store", str(store), "--epsilon", "-1"]
    rc = main(args)  # a negative REIRL weight fails REIRL's trial (twice: one retry); the others finish
    captured = capsys.readouterr()
    assert rc == 1
    assert "FAILED table1/reirl/trial00 after 2 attempt(s)" in captured.out
    assert "Q-Avg" in captured.out and "1 failed" in captured.err
    assert len(list(store.glob("*.json"))) == 3
    assert main(args) == 1  # resumed: only REIRL runs again
    assert "3 from the store, 1 run" in capsys.readouterr().err


def test_table_3_problem_is_the_authors_merge_data(railusm):
    p = table_problem(3, railusm)
    assert p.demos.n_steps == 1197 and p.transitions.to_dense().shape == (1250, 5, 1250)
    assert p.bins is not None and p.pad_step() is not None
    sub = p.subset(range(11))
    assert sub.demos.n_trajectories == 11 and (sub.transitions.p != p.transitions.p).nnz > 0


def test_baseline_rows_and_paired_held_out_tests(railusm, capsys):
    from irl.baselines import baseline_leave_one_out, fit_baseline, paired_test

    report = reproduce(1, ReproduceConfig(railusm, trials=1, methods=("mlirl", "qavg"),
                                          irl_config=IRLConfig.paper(l2=0.01), executor="serial"))
    rows = {r.method: r for r in report.rows}
    demos = table_problem(1, railusm).demos
    for name in ("uniform", "marginal", "markov", "bc"):
        assert rows[name].loglik_mean == pytest.approx(fit_baseline(name, demos).loglik(demos))
        folds = baseline_leave_one_out(name, demos)
        assert rows[name].heldout_folds == pytest.approx(tuple(folds))
        assert rows[name].heldout_loglik == pytest.approx(folds.sum())
    # the IRL rows' folds are the sweep's held-out trials, in fold order; p pairs them by trajectory
    qavg_folds = [o.heldout_loglik for o in sorted(report.holdout, key=lambda o: o.holdout) if o.method == "qavg"]
    mlirl_folds = [o.heldout_loglik for o in sorted(report.holdout, key=lambda o: o.holdout) if o.method == "mlirl"]
    assert rows["qavg"].heldout_folds == pytest.approx(qavg_folds)
    assert rows["qavg"].p_vs_mlirl == pytest.approx(paired_test(np.array(qavg_folds), np.array(mlirl_folds)))
    assert rows["qavg"].p_vs_marginal == pytest.approx(
        paired_test(np.array(qavg_folds), baseline_leave_one_out("marginal", demos)))
    assert np.isnan(rows["mlirl"].p_vs_mlirl) and np.isnan(rows["marginal"].p_vs_marginal)
    from analysis.experiments.reproduce_report import format_report

    text = format_report(report)
    for label in ("uniform", "marginal", "markov", "bc", "p vs marginal"):
        assert label in text


def test_heldout_module_uses_the_same_folds_as_reproduce(railusm):
    from analysis.experiments.leave_one_out import method_leave_one_out

    problem = table_problem(1, railusm)
    config = IRLConfig.paper(l2=0.01)
    folds = method_leave_one_out(problem, "qavg", config, seed=1)
    out = run_trial(TrialTask("qavg", problem, config, seed=1, holdout=3))
    assert folds[3] == pytest.approx(out.heldout_loglik)
    assert folds.shape == (problem.demos.n_trajectories,)


def test_heldout_script_prints_the_baseline_table(railusm, capsys):
    from analysis.experiments.leave_one_out import main as heldout_main

    assert heldout_main([str(railusm), "--table", "1", "--methods", "uniform,marginal,markov,bc"]) == 0
    text = capsys.readouterr().out
    demos = table_problem(1, railusm).demos
    from irl.baselines import baseline_leave_one_out

    for name in ("uniform", "marginal", "markov", "bc"):
        assert f"{name:10s} {baseline_leave_one_out(name, demos).sum():10.1f}" in text


def _outcome(method: str, seed: int, flags: tuple[str, ...], message: str = "ok") -> TrialOutcome:
    return TrialOutcome(method=method, seed=seed, holdout=None, theta=(0.0, 0.0), loglik=-10.0, heldout_loglik=float("nan"),
                        wall_time_s=0.1, converged=not flags, unbounded="infeasible" in flags, n_iterations=3,
                        message=message, flags=flags)


def test_reirl_verdict_is_in_the_printed_table():
    """REIRL's "uninformative" (every weight 0) and "infeasible" verdicts are a column of the
    printed table, not only in the JSON, and the footnote says what they and beta x theta mean."""
    from dataclasses import replace

    from analysis.experiments.reproduce_report import ReproductionReport, format_report, summarize

    reirl = summarize("reirl", [_outcome("reirl", s, ("not_converged", "uninformative")) for s in range(3)]
                      + [_outcome("reirl", 3, ())], None, [])
    qavg = summarize("qavg", [_outcome("qavg", s, ()) for s in range(4)], None, [])
    assert (reirl.n_uninformative, reirl.verdict, qavg.verdict) == (3, "uninformative 3/4", "")
    report = ReproductionReport(table=3, title="Table 3: toy", config=IRLConfig.paper(), feature_names=("a", "b"),
                                rows=(qavg, reirl), trials=(), holdout=(), seed=0)
    text = format_report(report)
    header = next(line for line in text.splitlines() if line.startswith("Method"))
    reirl_line = next(line for line in text.splitlines() if line.startswith("REIRL"))
    assert "verdict" in header and "uninformative 3/4" in reirl_line
    assert "beta x theta" in text and "uninformative = every weight 0" in text
    inf = replace(reirl, n_uninformative=0, n_infeasible=2)
    assert inf.verdict == "infeasible 2/4"


def test_outcomes_stored_before_flags_get_their_verdict_from_the_message():
    """A result store written before outcomes had flags still prints REIRL's verdict."""
    old = _outcome("reirl", 0, ("not_converged", "uninformative"),
                   message="dual solved; UNINFORMATIVE: every weight is 0").to_dict()
    del old["flags"]
    assert TrialOutcome.from_dict(old).flags == ("not_converged", "uninformative")
    new = _outcome("reirl", 0, ("not_converged", "uninformative")).to_dict()
    assert TrialOutcome.from_dict(new).flags == ("not_converged", "uninformative")
