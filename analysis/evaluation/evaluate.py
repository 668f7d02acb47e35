"""Evaluate driving policies in closed loop: learned IRL models against SUMO and random.

Example::

    from analysis.evaluation.evaluate import evaluate

    report = evaluate(["runs/demo/models/qavg.json"], "synthetic", episodes=4, seed=1,
                      out_dir="runs/eval", demos="runs/demo/heldout_encounters.parquet")
    print(report.report_md)          # report.md: one row per policy
    print(report.aggregates["qavg"].b_ahead_rate)

The steps are public, for callers that want to inspect or reuse one: an
:class:`~analysis.evaluation.config.EvaluationConfig`, :func:`~analysis.evaluation.plan.plan_evaluation`
(every input read and checked; nothing written), :func:`~analysis.evaluation.run.run_plan` and
:func:`~analysis.evaluation.outcome.write_report`. :func:`evaluate` is the four in a row.

Every policy runs the same episodes (seeds ``seed .. seed + episodes - 1``: the same traffic
for every policy). Episodes run through :func:`analysis.sweep.run_sweep` (``executor``: a
process pool by default, one libsumo simulation per process at a time; or Dask). Outputs in ``out_dir``: ``report.md``, ``metrics.json``, ``action_histograms.png``,
``gap_acceptance.png``, ``speed_profiles.png``, ``timings.json`` (wall time of each episode,
kept out of the results so reruns can be compared by hash) and, with ``rrd=True``, one rerun
recording of the first episode of each policy under ``rerun/`` (any other ``.rrd`` there, an
earlier evaluation's, is removed once this one has finished). ``metrics.json`` and
``report.md`` record their provenance (:mod:`merge_irl.provenance`).
"""

from __future__ import annotations

import os
from collections.abc import Sequence

import pandas as pd

from analysis.evaluation.config import EvaluationConfig
from analysis.evaluation.metrics import MetricsConfig
from analysis.evaluation.outcome import EvaluationReport, write_report
from analysis.evaluation.plan import plan_evaluation
from analysis.evaluation.run import run_plan
from irl.result import SavedModel
from sim.closed_loop.config import ControllerConfig
from sim.drivers.policy import Policy

#: The names this facade answers for (their homes: config, plan, run and outcome).


def evaluate(
    models: Sequence[SavedModel | str | os.PathLike],
    scenario,
    episodes: int,
    seed: int,
    out_dir: str | os.PathLike,
    *,
    duration_s: float | None = None,
    demos: str | os.PathLike | pd.DataFrame | None = None,
    baselines: Sequence[str] | None = None,
    train_demos: str | os.PathLike | pd.DataFrame | None = None,
    policies: Sequence[Policy] = (),
    controller: ControllerConfig = ControllerConfig(),
    metrics: MetricsConfig = MetricsConfig(),
    workers: int | None = None,
    executor: str | None = None,
    rrd: bool = True,
    progress: bool = True,
    allow_implausible: bool = False,
) -> EvaluationReport:
    """Closed-loop evaluation of each model, policy and baseline over ``episodes`` seeds.

    ``models`` and ``policies`` are driver specs (:mod:`analysis.evaluation.driver_specs`: learned
    files of any registered format, ``SavedModel`` objects, baseline names, policies, callables),
    evaluated in that order; every other argument is the
    :class:`~analysis.evaluation.config.EvaluationConfig` field of its name (``workers`` None:
    every core, as ``merge-irl evaluate``). Every input is read and checked, and the held-out
    scores taken, before the output folder is made and any episode runs.

    Raises:
        SpecError, AnalysisError, SimError, PolicyError, ModelFileError, DemonstrationError: a bad
            input, before any output (:func:`~analysis.evaluation.plan.plan_evaluation`).
        SimulationError: SUMO fails to start or to step.
    """
    config = EvaluationConfig(
        scenario, episodes, seed, out_dir, drivers=(*models, *policies),
        baselines=None if baselines is None else tuple(baselines), duration_s=duration_s, demos=demos,
        train_demos=train_demos, controller=controller, metrics=metrics, workers=workers, executor=executor,
        rrd=rrd, progress=progress, allow_implausible=allow_implausible)
    plan = plan_evaluation(config)
    return write_report(plan, run_plan(plan))
