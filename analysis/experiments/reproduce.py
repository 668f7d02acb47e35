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

    from analysis.experiments.reproduce import ReproduceConfig, reproduce
    from analysis.experiments.reproduce_report import format_report
    report = reproduce(1, ReproduceConfig("/path/to/railusm", trials=5, executor="process:2"))
    print(format_report(report))

Trials run through :func:`analysis.sweep.run_sweep` (``executor``: serial, process pool, Dask;
``store``: a directory that makes a re-run skip the trials already finished).

The report (one row per method and baseline, its JSON file and the text table) is
:mod:`analysis.experiments.reproduce_report`.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from analysis.experiments.reproduce_report import ReproductionReport, _table_report
from analysis.experiments.trials import (
    TrialOutcome,
    TrialSpec,
    cached_table_problem,
    resolve_data_dir,
    run_trial_spec,
    trial_seeds,
)
from analysis.sweep import ResultStore, SweepReport, Task, run_sweep
from irl.config import IRLConfig
from irl.errors import ConfigError
from irl.methods.registry import REGISTRY, method_names
from irl.methods.reirl import DEFAULT_EPSILON
from merge_irl.provenance import provenance

DEFAULT_TRIALS = {1: 30, 2: 30, 3: 10}


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


def _expected_cost(spec: TrialSpec) -> tuple[int, int, int]:
    return (spec.table == 3, REGISTRY[spec.method].cost if spec.method in REGISTRY else 0, spec.holdout is None)


@dataclass(frozen=True)
class ReproductionRun:
    """Result of :func:`reproduce_tables`: one report per table and the sweep that ran them.

    Attributes:
        reports: one :class:`~analysis.experiments.reproduce_report.ReproductionReport` per requested table, in order.
        sweep: the :class:`analysis.sweep.SweepReport` (timings, cached/run counts, failures).
    """

    reports: tuple[ReproductionReport, ...]
    sweep: SweepReport

    @property
    def ok(self) -> bool:
        return self.sweep.ok


@dataclass(frozen=True)
class ReproduceConfig:
    """How to reproduce the paper's tables: everything :func:`reproduce_tables` and
    :func:`reproduce` take but the tables.

    Attributes:
        data_dir: the authors' data (``railusm`` or ``Model-free-IRL/data``).
        trials: initialisations per method (None: 30, 30, 10 for tables 1, 2, 3).
        settings: ``paper`` or ``reference`` base settings (ignored if ``irl_config`` is given).
        irl_config: the IRL settings of every trial (None: those of ``settings``).
        seed: master seed; trial ``j`` uses ``trial_seeds(seed, n)[j]`` for every method (the
            same seeds as before the sweep runner: results are unchanged for a given seed).
        methods: the methods to run (None: every registered method, ``irl.fit.method_names()``).
        holdout: also run the leave-one-trajectory-out evaluation (first trial seed).
        epsilon: REIRL's L1 weight.
        executor: ``serial``, ``process[:N]`` (default: every core), ``dask-local[:N]`` or
            ``dask://HOST:PORT``. Results do not depend on it.
        store: a result directory: finished trials are stored there and skipped when re-run.
        retries: re-runs of a failing trial before it is reported in ``sweep.failures``; the
            tables are summarised from the trials that succeeded.
        progress: show a progress bar.
    """

    data_dir: str | os.PathLike
    trials: int | None = None
    settings: str = "paper"
    irl_config: IRLConfig | None = None
    seed: int = 0
    methods: tuple[str, ...] | None = None
    holdout: bool = True
    epsilon: float | None = DEFAULT_EPSILON
    executor: str = "process"
    store: ResultStore | str | os.PathLike | None = None
    retries: int = 1
    progress: bool = False


def reproduce_tables(tables: Sequence[int], config: ReproduceConfig) -> ReproductionRun:
    """Run every method of each table over ``config.trials`` initialisations (default 30, 30, 10), as
    one sweep (:func:`analysis.sweep.run_sweep`), so slow and fast trials of all tables share
    the workers; ``config``: see :class:`ReproduceConfig`.

    Raises:
        ConfigError: no table, a table other than 1, 2 or 3, unknown ``settings`` or ``methods``, or
            ``trials`` < 1.
        DemonstrationError: ``data_dir`` does not hold the authors' data layout.
    """
    trials, seed = config.trials, config.seed
    tables = tuple(int(t) for t in tables)
    for table in tables:
        if table not in DEFAULT_TRIALS:
            raise ConfigError(f"table must be 1, 2 or 3, got {table}")
    if not tables:
        raise ConfigError("no table to reproduce")
    if config.settings not in ("paper", "reference"):
        raise ConfigError(f"settings must be 'paper' or 'reference', got {config.settings!r}")
    methods = method_names() if config.methods is None else tuple(config.methods)
    bad = [m for m in methods if m not in REGISTRY]
    if bad:
        raise ConfigError(f"methods: unknown {bad}; expected some of {list(method_names())}")
    irl_config = config.irl_config
    if irl_config is None:
        irl_config = IRLConfig.reference() if config.settings == "reference" else IRLConfig.paper()
    if trials is not None and int(trials) < 1:
        raise ConfigError(f"trials must be >= 1, got {trials}")
    d = str(resolve_data_dir(config.data_dir).resolve())
    provenances = {table: provenance(table_inputs(table, d)) for table in tables}  # the data as read, before the work
    specs: dict[int, list[TrialSpec]] = {}
    for table in tables:
        n = DEFAULT_TRIALS[table] if trials is None else int(trials)
        specs[table] = _trial_specs(table, d, irl_config, n, seed, tuple(methods), config.holdout, config.epsilon)
    # submit the slow trials first (NGSIM before gridworld; Q-SM and MLIRL before Q-Avg and
    # REIRL) so no long trial starts last and leaves the other workers idle; results are
    # keyed, so the order changes nothing else
    ordered = sorted((s for table in tables for s in specs[table]), key=_expected_cost, reverse=True)
    tasks = [Task(s.key, run_trial_spec, s) for s in ordered]
    label = "tables " + ",".join(map(str, tables)) if len(tables) > 1 else f"table {tables[0]}"
    sweep = run_sweep(tasks, seed=seed, executor=config.executor, store=config.store, retries=config.retries,
                      progress=config.progress, desc=label)
    reports = []
    for table in tables:
        outcomes = [TrialOutcome.from_dict(sweep.results[s.key]) for s in specs[table] if s.key in sweep.results]
        prefix = f"table{table}/"
        failed = tuple(f for f in sweep.failures if f.key.startswith(prefix))
        reports.append(_table_report(table, d, irl_config, methods, outcomes, failed, seed, provenances[table]))
    return ReproductionRun(tuple(reports), sweep)


def reproduce(table: int, config: ReproduceConfig) -> ReproductionReport:
    """One table: :func:`reproduce_tables` ``([table], config)``; trials that failed after their
    retry are listed in ``report.failures``."""
    return reproduce_tables([table], config).reports[0]
