"""The report of a reproduction of the paper's Tables 1-3 (:mod:`analysis.experiments.reproduce`).

One row per method (:class:`MethodSummary`: mean +- std of each weight and of the final
log-likelihood over the trials, the leave-one-trajectory-out log-likelihood, Wilcoxon
signed-rank p-values of the paired held-out trajectories against MLIRL's and the marginal's)
and one per baseline (``uniform``, ``marginal``, ``markov``, ``bc``, :mod:`irl.baselines`); the
paper's reported means beside them (:data:`PAPER`); the report as JSON
(:meth:`ReproductionReport.to_json_dict`, :func:`save_reports_json`) and as the paper's table
layout in text (:func:`format_report`).
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from analysis.experiments.trials import TrialOutcome, cached_table_problem, config_label
from analysis.sweep import TaskFailure
from irl.baselines import TABULAR_BASELINES, baseline_leave_one_out, fit_baseline, paired_test
from irl.config import IRLConfig
from irl.methods.registry import REGISTRY
from irl.problems import Problem
from merge_irl.atomic import write_json_atomic
from merge_irl.provenance import write_timings


def row_label(name: str) -> str:
    """A table row's label: the registered method's (``"Q-Avg"``, ...), else the name itself (the
    baselines ``uniform``, ``marginal``, ``markov``, ``bc``)."""
    m = REGISTRY.get(name)
    return m.label if m is not None else name

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
        n_uninformative, n_infeasible: trials REIRL judged uninformative (every weight 0) or
            infeasible (its dual unbounded); see :attr:`verdict`.
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
    n_uninformative: int = 0
    n_infeasible: int = 0

    @property
    def verdict(self) -> str:
        """REIRL's verdicts over the trials, as printed: ``"uninformative 10/10"`` (every weight 0:
        the experts cannot be told from the baseline at this confidence), ``"infeasible 4/10"``
        (the dual is unbounded: no reweighting matches the experts); "" when none."""
        parts = [f"{name} {n}/{self.n_trials}" for name, n in (("uninformative", self.n_uninformative),
                                                               ("infeasible", self.n_infeasible)) if n]
        return ", ".join(parts)


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
        n_uninformative=sum("uninformative" in o.flags for o in outcomes),
        n_infeasible=sum("infeasible" in o.flags for o in outcomes),
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
    rows += tuple(baseline_summary(b, problem, with_holdout, mlirl, marginal) for b in TABULAR_BASELINES)
    names = tuple(problem.feature_names)
    return ReproductionReport(table, TITLES[table], config, names, rows, tuple(main), tuple(folds), int(seed),
                              failures, provenance=prov)


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
        ["Final log-likelihood", "LOO held-out LL", "p vs MLIRL", "p vs marginal", "conv/unb", "verdict", "s/trial"]
    lines = [[row_label(r.method)] + ([_pm(m, s) for m, s in zip(r.theta_mean, r.theta_std)] or ["-"] * k)
             + [_pm(r.loglik_mean, r.loglik_std),
                f"{r.heldout_loglik:.2f}" if math.isfinite(r.heldout_loglik) else "-",
                _p(r.p_vs_mlirl), _p(r.p_vs_marginal),
                f"{r.n_converged}/{r.n_unbounded}", r.verdict or "-", f"{r.time_mean_s:.3f}"] for r in report.rows]
    paper = PAPER.get(report.table, {})
    paper_lines = [[f"paper {row_label(m)}"] + [f"{v:.2f}" for v in paper[m][:k]] + [f"{paper[m][k]:.2f}", "", "",
                                                                                        "", "", "", ""]
                   for m in REGISTRY if m in paper and len(paper[m]) == k + 1]
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
               "marginal); bc = tabular behaviour cloning. conv/unb: trials converged / with unbounded weights. "
               "verdict (REIRL): uninformative = every weight 0, the experts cannot be told from the baseline "
               "trajectories at this confidence (the weights are no result); infeasible = its dual is unbounded "
               "(the weights sit at their cap). The policy depends on the weights only through beta x theta: "
               "compare beta x theta with the paper's beta x theta, not theta alone.")
    for f in report.failures:
        out.append(f"FAILED {f.key} after {f.attempts} attempt(s): {f.error}")
    return "\n".join(out)
