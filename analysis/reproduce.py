"""Reproduce the paper's Tables 1-3 on the authors' data (the API behind ``merge-irl reproduce``).

Table 1: gridworld without noise; Table 2: gridworld with 10 % slip; Table 3: the 12 NGSIM merge
trajectories. Every method (MLIRL, Q-Avg, Q-SM, REIRL) runs over N random initialisations (the
same N trial seeds for every method, so trials pair up); the report gives mean +- std of each
weight and of the final log-likelihood, and what the paper lacks: the leave-one-trajectory-out
log-likelihood (sum over folds of the held-out trajectory's log-likelihood, one fit per fold
with the first trial seed), Wilcoxon signed-rank p-values of the paired held-out trajectories
(per-fold LOO log-likelihoods) against MLIRL's and the marginal's, and the baselines
``uniform``, ``marginal``, ``markov`` and ``bc`` (:mod:`irl.baselines`) as rows.

Example::

    from analysis.reproduce import reproduce, format_report
    report = reproduce(1, "/path/to/railusm", trials=5, executor="process:2")
    print(format_report(report))

Trials run through :func:`analysis.sweep.run_sweep` (``executor``: serial, process pool, Dask;
``store``: a directory that makes a re-run skip the trials already finished).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from collections.abc import Sequence

import numpy as np

from analysis.provenance import provenance, write_timings
from analysis.sweep import ResultStore, SweepReport, Task, TaskFailure, run_sweep
from analysis.trials import (TrialOutcome, TrialSpec, cached_table_problem, config_label, resolve_data_dir,
                             run_trial_spec, trial_seeds)
from irl.atomic import write_json_atomic
from irl.baselines import BASELINES, baseline_leave_one_out, fit_baseline, paired_test
from irl.config import IRLConfig
from irl.errors import ConfigError
from irl.problems import Problem
from irl.reirl import DEFAULT_EPSILON

#: Row order of the paper's tables.
METHOD_ORDER = ("mlirl", "qavg", "qsm", "reirl")
METHOD_LABELS = {"mlirl": "MLIRL", "qavg": "Q-Avg", "qsm": "Q-SM", "reirl": "REIRL", "uniform": "uniform",
                 "marginal": "marginal", "markov": "markov", "bc": "bc"}
DEFAULT_TRIALS = {1: 30, 2: 30, 3: 10}
TITLES = {
    1: "Table 1: gridworld, no transition noise",
    2: "Table 2: gridworld, 10% transition noise",
    3: "Table 3: NGSIM I-80 merge, 12 trajectories",
}
#: The paper's reported means (theta..., final LL) per table and method, for side-by-side reading.
PAPER: dict[int, dict[str, tuple[float, ...]]] = {
    1: {"mlirl": (43.04, 33.31, 54.23, 53.93, -49.09, -36.50), "qavg": (152.33, 92.06, 1526.06, 151.51, 0.03, -29.25),
        "qsm": (17.92, 11.96, 109.88, 17.87, 0.02, -40.39), "reirl": (0.87, 28.27, 40.43, 44.62, -3.10, -43.58)},
    2: {"mlirl": (94.00, 86.91, 93.26, 95.35, -71.57, -45.05), "qavg": (227.72, 89.83, 157.59, 3368.95, 151.43, -40.49),
        "qsm": (30.37, 10.98, 18.40, 225.20, 11.33, -57.35), "reirl": (0.58, 0.13, 1.96, 0.31, -0.50, -72.11)},
    3: {"mlirl": (0.28, 0.42, 0.45, -1927.09), "qavg": (2.01, 1.86, 0.15, -1891.34),
        "qsm": (0.41, 0.80, -0.12, -1914.56), "reirl": (0.08, 0.01, 15.89, -1920.48)},
}


def table_inputs(table: int, data_dir: str | os.PathLike) -> dict[str, Path]:
    """The folders ``table`` reads under ``data_dir`` (role -> path), for its provenance.

    Raises:
        ConfigError: ``table`` is not 1, 2 or 3.
        DemonstrationError: ``data_dir`` does not hold the authors' data layout.
    """
    d = resolve_data_dir(data_dir)
    if table in (1, 2):
        tag = f"noise_{0.0 if table == 1 else 0.1:.1f}"
        return {f"table{table}_demos": d / "gridworld" / f"{tag}_expert_trajs",
                f"table{table}_baseline": d / "gridworld" / f"{tag}_baseline_trajs"}
    if table == 3:
        return {"table3_demos": d / "merge_ngsim"}
    raise ConfigError(f"table must be 1, 2 or 3, got {table}")


@dataclass(frozen=True)
class MethodSummary:
    """One row of the table.

    Attributes:
        theta_mean, theta_std: ``[K]`` over trials (sample std, ddof 1).
        loglik_mean, loglik_std: final in-sample log-likelihood over trials.
        p_vs_mlirl: two-sided Wilcoxon signed-rank p-value of the paired held-out trajectories
            (per-fold LOO log-likelihoods) against MLIRL's (:func:`irl.baselines.paired_test`; NaN
            for MLIRL itself or without the LOO evaluation; 1.0 if all differences are 0).
        heldout_loglik: leave-one-trajectory-out log-likelihood (NaN if not run).
        heldout_folds: ``[n_trajectories]`` the per-fold values summed in ``heldout_loglik``.
        p_vs_marginal: as ``p_vs_mlirl``, against the ``marginal`` baseline.
        Baseline rows (``uniform``, ``marginal``, ``markov``, ``bc``) have no weights and one
        deterministic fit on all trajectories.
        n_converged, n_unbounded: trial counts.
        time_mean_s: mean wall time per trial.
    """

    method: str
    theta_mean: tuple[float, ...]
    theta_std: tuple[float, ...]
    loglik_mean: float
    loglik_std: float
    p_vs_mlirl: float
    heldout_loglik: float
    n_trials: int
    n_converged: int
    n_unbounded: int
    time_mean_s: float
    heldout_folds: tuple[float, ...] = ()
    p_vs_marginal: float = float("nan")


@dataclass(frozen=True)
class ReproductionReport:
    table: int
    title: str
    config: IRLConfig
    feature_names: tuple[str, ...]
    rows: tuple[MethodSummary, ...]
    trials: tuple[TrialOutcome, ...]
    holdout: tuple[TrialOutcome, ...]
    seed: int
    failures: tuple[TaskFailure, ...] = ()
    provenance: dict | None = None

    def to_json_dict(self) -> dict:
        """The report as JSON, with its provenance (versions, hashes of the data read) and
        without wall times (see :meth:`timings`), so identical runs give identical files."""
        def clean(x):
            if isinstance(x, float) and not math.isfinite(x):
                return None
            if isinstance(x, (list, tuple)):
                return [clean(v) for v in x]
            return x

        def untimed(t: TrialOutcome) -> dict:
            d = t.to_dict()
            d.pop("wall_time_s")
            return d

        return {
            "table": self.table, "title": self.title, "settings": self.config.to_dict(), "seed": self.seed,
            "feature_names": list(self.feature_names),
            "rows": [{k: clean(v) for k, v in r.__dict__.items() if k != "time_mean_s"} for r in self.rows],
            "trials": [untimed(t) for t in self.trials],
            "holdout": [untimed(t) for t in self.holdout],
            "paper": {m: list(v) for m, v in PAPER.get(self.table, {}).items()},
            "failures": [{"key": f.key, "error": f.error, "attempts": f.attempts} for f in self.failures],
            "provenance": self.provenance,
        }

    def timings(self) -> dict:
        """Wall time (s) of each trial and held-out fit, by method: ``{"trials": {method: [...]},
        "holdout": {...}}`` (kept out of :meth:`to_json_dict`)."""
        def by_method(outcomes) -> dict:
            out: dict[str, list[float]] = {}
            for t in outcomes:
                out.setdefault(t.method, []).append(t.wall_time_s)
            return out

        return {"table": self.table, "trials": by_method(self.trials), "holdout": by_method(self.holdout)}

    def save_json(self, path: str | os.PathLike) -> Path:
        """Write :meth:`to_json_dict` to ``path`` and :meth:`timings` beside it
        (``<stem>.timings.json``)."""
        write_timings(path, self.timings())
        return write_json_atomic(path, self.to_json_dict())


def save_reports_json(reports: Sequence[ReproductionReport], path: str | os.PathLike) -> Path:
    """Several tables' reports as ``{"tables": [report.to_json_dict(), ...]}``, atomically; their
    timings to ``<stem>.timings.json`` (``{"tables": [report.timings(), ...]}``)."""
    write_timings(path, {"tables": [r.timings() for r in reports]})
    return write_json_atomic(path, {"tables": [r.to_json_dict() for r in reports]})




#: Two-sided Wilcoxon signed-rank p-value of paired samples (one home: :mod:`irl.baselines`).
wilcoxon_p = paired_test


def _folds(holdout: list[TrialOutcome]) -> np.ndarray:
    """``[n]`` held-out log-likelihoods ordered by fold (held-out trajectory index)."""
    return np.array([o.heldout_loglik for o in sorted(holdout, key=lambda o: -1 if o.holdout is None else o.holdout)])


def _p_against(folds: np.ndarray, ref: np.ndarray | None) -> float:
    if ref is None or folds.size == 0 or folds.shape != ref.shape:
        return float("nan")
    return paired_test(folds, ref)


def summarize(method: str, outcomes: list[TrialOutcome], mlirl_folds: np.ndarray | None,
              holdout: list[TrialOutcome], marginal_folds: np.ndarray | None = None) -> MethodSummary:
    """One method's row; p-values pair its held-out folds with MLIRL's and the marginal's."""
    theta = np.array([o.theta for o in outcomes])
    ll = np.array([o.loglik for o in outcomes])
    ddof = 1 if len(outcomes) > 1 else 0
    folds = _folds(holdout)
    p = _p_against(folds, mlirl_folds) if method != "mlirl" else float("nan")
    held = float(np.sum(folds)) if holdout else float("nan")
    return MethodSummary(
        method=method, theta_mean=tuple(theta.mean(axis=0)), theta_std=tuple(theta.std(axis=0, ddof=ddof)),
        loglik_mean=float(ll.mean()), loglik_std=float(ll.std(ddof=ddof)), p_vs_mlirl=p, heldout_loglik=held,
        n_trials=len(outcomes), n_converged=sum(o.converged for o in outcomes),
        n_unbounded=sum(o.unbounded for o in outcomes),
        time_mean_s=float(np.mean([o.wall_time_s for o in outcomes])),
        heldout_folds=tuple(float(x) for x in folds), p_vs_marginal=_p_against(folds, marginal_folds),
    )


def baseline_summary(name: str, problem: Problem, holdout: bool, mlirl_folds: np.ndarray | None,
                     marginal_folds: np.ndarray | None) -> MethodSummary:
    """The row of baseline ``name``: in-sample log-likelihood of its fit on every trajectory and,
    with ``holdout``, its per-fold LOO values (:func:`irl.baselines.baseline_leave_one_out`)."""
    demos = problem.demos
    folds = baseline_leave_one_out(name, demos) if holdout else np.empty(0)
    return MethodSummary(
        method=name, theta_mean=(), theta_std=(), loglik_mean=fit_baseline(name, demos).loglik(demos),
        loglik_std=0.0, p_vs_mlirl=_p_against(folds, mlirl_folds),
        heldout_loglik=float(folds.sum()) if holdout else float("nan"), n_trials=1, n_converged=1,
        n_unbounded=0, time_mean_s=0.0, heldout_folds=tuple(float(x) for x in folds),
        p_vs_marginal=_p_against(folds, marginal_folds) if name != "marginal" else float("nan"),
    )


def _trial_specs(table: int, data_dir: str, config: IRLConfig, n: int, seed: int,
                 methods: tuple[str, ...], holdout: bool, epsilon: float | None) -> list[TrialSpec]:
    seeds = trial_seeds(seed, n)
    specs = [TrialSpec(table, data_dir, m, config, j, s, epsilon=epsilon)
             for m in methods for j, s in enumerate(seeds)]
    if holdout:
        n_traj = cached_table_problem(table, data_dir).demos.n_trajectories
        specs += [TrialSpec(table, data_dir, m, config, 0, seeds[0], holdout=i, epsilon=epsilon)
                  for m in methods for i in range(n_traj)]
    return specs


_METHOD_COST = {"qsm": 3, "mlirl": 2, "reirl": 1, "qavg": 0}


def _expected_cost(spec: TrialSpec) -> tuple[int, int, int]:
    return (spec.table == 3, _METHOD_COST.get(spec.method, 0), spec.holdout is None)


@dataclass(frozen=True)
class ReproductionRun:
    """Result of :func:`reproduce_tables`: one report per table and the sweep that ran them.

    Attributes:
        reports: one :class:`ReproductionReport` per requested table, in order.
        sweep: the :class:`analysis.sweep.SweepReport` (timings, cached/run counts, failures).
    """

    reports: tuple[ReproductionReport, ...]
    sweep: SweepReport

    @property
    def ok(self) -> bool:
        return self.sweep.ok


def reproduce_tables(
    tables: Sequence[int],
    data_dir: str | os.PathLike,
    *,
    trials: int | None = None,
    settings: str = "paper",
    config: IRLConfig | None = None,
    seed: int = 0,
    methods: tuple[str, ...] = METHOD_ORDER,
    holdout: bool = True,
    epsilon: float | None = DEFAULT_EPSILON,
    executor: str = "process",
    store: ResultStore | str | os.PathLike | None = None,
    retries: int = 1,
    progress: bool = False,
) -> ReproductionRun:
    """Run every method of each table over ``trials`` initialisations (default 30, 30, 10), as
    one sweep (:func:`analysis.sweep.run_sweep`), so slow and fast trials of all tables share
    the workers.

    Args:
        settings: ``paper`` or ``reference`` base settings (ignored if ``config`` is given).
        seed: master seed; trial ``j`` uses ``trial_seeds(seed, n)[j]`` for every method (the
            same seeds as before the sweep runner: results are unchanged for a given seed).
        holdout: also run the leave-one-trajectory-out evaluation (first trial seed).
        epsilon: REIRL's L1 weight.
        executor: ``serial``, ``process[:N]`` (default: every core), ``dask-local[:N]`` or
            ``dask://HOST:PORT``. Results do not depend on it.
        store: a result directory: finished trials are stored there and skipped when re-run.
        retries: re-runs of a failing trial before it is reported in ``sweep.failures``; the
            tables are summarised from the trials that succeeded.

    Raises:
        ConfigError: no table, a table other than 1, 2 or 3, unknown ``settings`` or ``methods``, or
            ``trials`` < 1.
        DemonstrationError: ``data_dir`` does not hold the authors' data layout.
    """
    tables = tuple(int(t) for t in tables)
    for table in tables:
        if table not in DEFAULT_TRIALS:
            raise ConfigError(f"table must be 1, 2 or 3, got {table}")
    if not tables:
        raise ConfigError("no table to reproduce")
    if settings not in ("paper", "reference"):
        raise ConfigError(f"settings must be 'paper' or 'reference', got {settings!r}")
    bad = [m for m in methods if m not in METHOD_ORDER]
    if bad:
        raise ConfigError(f"methods: unknown {bad}; expected some of {list(METHOD_ORDER)}")
    if config is None:
        config = IRLConfig.reference() if settings == "reference" else IRLConfig.paper()
    if trials is not None and int(trials) < 1:
        raise ConfigError(f"trials must be >= 1, got {trials}")
    d = str(resolve_data_dir(data_dir).resolve())
    provenances = {table: provenance(table_inputs(table, d)) for table in tables}  # the data as read, before the work
    specs: dict[int, list[TrialSpec]] = {}
    for table in tables:
        n = DEFAULT_TRIALS[table] if trials is None else int(trials)
        specs[table] = _trial_specs(table, d, config, n, seed, tuple(methods), holdout, epsilon)
    # submit the slow trials first (NGSIM before gridworld; Q-SM and MLIRL before Q-Avg and
    # REIRL) so no long trial starts last and leaves the other workers idle; results are
    # keyed, so the order changes nothing else
    ordered = sorted((s for table in tables for s in specs[table]), key=_expected_cost, reverse=True)
    tasks = [Task(s.key, run_trial_spec, s) for s in ordered]
    label = "tables " + ",".join(map(str, tables)) if len(tables) > 1 else f"table {tables[0]}"
    sweep = run_sweep(tasks, seed=seed, executor=executor, store=store, retries=retries,
                      progress=progress, desc=label)
    reports = []
    for table in tables:
        outcomes = [TrialOutcome.from_dict(sweep.results[s.key]) for s in specs[table] if s.key in sweep.results]
        prefix = f"table{table}/"
        failed = tuple(f for f in sweep.failures if f.key.startswith(prefix))
        reports.append(_table_report(table, d, config, methods, outcomes, failed, seed, provenances[table]))
    return ReproductionRun(tuple(reports), sweep)


def _table_report(table: int, data_dir: str, config: IRLConfig, methods: Sequence[str], outcomes: list[TrialOutcome],
                  failures: tuple[TaskFailure, ...], seed: int, prov: dict | None = None) -> ReproductionReport:
    main = [o for o in outcomes if o.holdout is None]
    folds = [o for o in outcomes if o.holdout is not None]
    by_method = {m: [o for o in main if o.method == m] for m in methods}
    # a method with a failed fold gets no held-out sum (NaN) rather than a partial one
    fold_failed = {f.key.split("/")[1] for f in failures if "/holdout" in f.key}
    held = {m: [] if m in fold_failed else [o for o in folds if o.method == m] for m in methods}
    problem = cached_table_problem(table, data_dir)
    with_holdout = bool(folds)
    marginal = baseline_leave_one_out("marginal", problem.demos) if with_holdout else None
    mlirl = _folds(held["mlirl"]) if held.get("mlirl") else None
    rows = tuple(summarize(m, by_method[m], mlirl, held[m], marginal) for m in methods if by_method[m])
    rows += tuple(baseline_summary(b, problem, with_holdout, mlirl, marginal) for b in BASELINES)
    names = tuple(problem.feature_names)
    return ReproductionReport(table, TITLES[table], config, names, rows, tuple(main), tuple(folds), int(seed),
                              failures, provenance=prov)


def reproduce(
    table: int,
    data_dir: str | os.PathLike,
    *,
    trials: int | None = None,
    settings: str = "paper",
    config: IRLConfig | None = None,
    seed: int = 0,
    methods: tuple[str, ...] = METHOD_ORDER,
    holdout: bool = True,
    epsilon: float | None = DEFAULT_EPSILON,
    executor: str = "process",
    store: ResultStore | str | os.PathLike | None = None,
    retries: int = 1,
    progress: bool = False,
) -> ReproductionReport:
    """One table: :func:`reproduce_tables` ``([table], ...)`` (same arguments); trials that
    failed after their retry are listed in ``report.failures``."""
    run = reproduce_tables([table], data_dir, trials=trials, settings=settings, config=config, seed=seed,
                           methods=methods, holdout=holdout, epsilon=epsilon, executor=executor, store=store,
                           retries=retries, progress=progress)
    return run.reports[0]


def _pm(mean: float, std: float) -> str:
    return f"{mean:.2f} ± {std:.2f}"


def _p(p: float) -> str:
    if not math.isfinite(p):
        return "-"
    return f"{p:.3g}"


def format_report(report: ReproductionReport) -> str:
    """The paper's table layout plus p-values and held-out log-likelihood, and the paper's means."""
    k = len(report.feature_names)
    head = ["Method"] + [f"θ_{i + 1} ({n})" for i, n in enumerate(report.feature_names)] + \
        ["Final log-likelihood", "LOO held-out LL", "p vs MLIRL", "p vs marginal", "conv/unb", "s/trial"]
    lines = [[METHOD_LABELS[r.method]] + ([_pm(m, s) for m, s in zip(r.theta_mean, r.theta_std)] or ["-"] * k)
             + [_pm(r.loglik_mean, r.loglik_std),
                f"{r.heldout_loglik:.2f}" if math.isfinite(r.heldout_loglik) else "-",
                _p(r.p_vs_mlirl), _p(r.p_vs_marginal),
                f"{r.n_converged}/{r.n_unbounded}", f"{r.time_mean_s:.3f}"] for r in report.rows]
    paper = PAPER.get(report.table, {})
    paper_lines = [[f"paper {METHOD_LABELS[m]}"] + [f"{v:.2f}" for v in paper[m][:k]] + [f"{paper[m][k]:.2f}", "", "",
                                                                                        "", "", ""]
                   for m in METHOD_ORDER if m in paper and len(paper[m]) == k + 1]
    table = [head] + lines + paper_lines
    widths = [max(len(row[c]) for row in table) for c in range(len(head))]
    n_trials = report.rows[0].n_trials if report.rows else 0
    out = [f"{report.title} ({n_trials} trials per method; {config_label(report.config)}; seed {report.seed})"]
    for i, row in enumerate(table):
        out.append("  ".join(cell.ljust(w) for cell, w in zip(row, widths)).rstrip())
        if i == 0 or (paper_lines and i == len(lines)):
            out.append("  ".join("-" * w for w in widths))
    out.append("Final log-likelihood: Eq. 5 sum of log pi(a|s) over the training steps, without log Pr(s_1). "
               "LOO held-out LL: sum over trajectories of its log-likelihood under the policy fitted on the "
               "others (first trial seed). p: two-sided Wilcoxon signed-rank test of the paired held-out "
               "trajectories (per-fold LOO LL) vs MLIRL / the marginal. Baselines (add-one smoothed): uniform; "
               "marginal = action frequencies; markov = next action given the previous one (first step: "
               "marginal); bc = tabular behaviour cloning. conv/unb: trials converged / with unbounded weights.")
    for f in report.failures:
        out.append(f"FAILED {f.key} after {f.attempts} attempt(s): {f.error}")
    return "\n".join(out)

