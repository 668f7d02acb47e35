"""The report of a run evaluation: aggregates, files, and :class:`EvaluationReport`.

:func:`write_report` takes a plan (:mod:`analysis.evaluation.plan`) and its episodes
(:mod:`analysis.evaluation.run`) and writes ``report.md``, ``metrics.json``, the PNG plots
(:func:`analysis.evaluation.report.write_outputs`) and ``timings.json``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd

from analysis.evaluation.aggregate import AggregateMetrics, aggregate
from analysis.evaluation.distances import w1_to_demos
from analysis.evaluation.episode import EpisodeResult
from analysis.evaluation.human_likeness import DemoCloseness, demo_close_to_c, w1_acc_jerk
from analysis.evaluation.plan import EvaluationPlan
from analysis.evaluation.recorded import RecordedComparison, compare_to_recorded
from analysis.evaluation.report import write_outputs
from analysis.evaluation.run import EvaluationRun
from irl.domains.merge.actions import N_ACTIONS
from merge_irl.provenance import write_timings
from merge_irl.units import FT_PER_M
from sim.drivers.baselines import left_out_baselines


@dataclass(frozen=True)
class EvaluationReport:
    """Result of :func:`analysis.evaluation.evaluate.evaluate` (and :func:`write_report`).

    Attributes:
        out_dir: where the files are.
        aggregates: policy name -> aggregated metrics.
        episodes: policy name -> per-episode results (metrics, controls, decisions, profiles).
        report_md, metrics_json: paths of the written report and metrics.
        plots: paths of the PNG plots.
        rrd: policy name -> rerun recording (first episode), if written.
        demo_closeness: the share of held-out encounters whose A came within the metrics'
            ``close_gap_m`` of C (None without ``demos``).
        recorded: every driver beside the recorded drivers of ``pairs`` (None without ``pairs``).
    """

    out_dir: Path
    aggregates: dict[str, AggregateMetrics]
    episodes: dict[str, list[EpisodeResult]] = field(repr=False)
    report_md: Path
    metrics_json: Path
    plots: tuple[Path, ...] = ()
    rrd: dict[str, Path] = field(default_factory=dict)
    demo_closeness: DemoCloseness | None = None
    recorded: RecordedComparison | None = None


def write_report(plan: EvaluationPlan, run: EvaluationRun) -> EvaluationReport:
    """Aggregate ``run``'s episodes per policy and write the report files into ``plan.out_dir``;
    any ``.rrd`` under ``rerun/`` that this run did not write (an earlier evaluation's) is removed.

    Raises:
        OSError: a file cannot be written.
    """
    cfg, held, out = plan.config, plan.heldout, plan.out_dir
    by_policy = {name: list(rs) for name, rs in run.by_policy.items()}
    counts = held.action_counts if held is not None else None
    aggs = {}
    for p in plan.policies:
        ho = plan.scores[p.name]
        rs = by_policy[p.name]
        w1 = {**w1_to_demos(pd.concat([r.decisions for r in rs], ignore_index=True), held.encounters),
              **w1_acc_jerk([r.speed_profiles for r in rs], held.encounters)} if held is not None and rs else None
        aggs[p.name] = aggregate([r.metrics for r in rs], demo_action_counts=counts, heldout=ho, w1=w1,
                                 flags=tuple(p.flags) + heldout_flags(ho))
    recorded = compare_to_recorded(plan.recorded, by_policy) if plan.recorded is not None else None
    closeness = demo_close_to_c(held.encounters, cfg.metrics.close_gap_m) if held is not None else None
    scen_name = cfg.scenario if isinstance(cfg.scenario, (str, Path)) else plan.spec.name
    report_md, metrics_json, plots = write_outputs(
        out, aggs, by_policy, held, scenario=str(scen_name), seed=cfg.seed, episodes=cfg.episodes,
        duration_s=cfg.duration_s, controller=plan.controller, metrics=cfg.metrics,
        provenance=dict(plan.provenance), speed_limit_ft_s=plan.spec.road.speed_limit_mps * FT_PER_M,
        left_out=left_out_baselines(plan.baselines, cfg.train_demos), demo_closeness=closeness,
        recorded=recorded,
    )
    write_timings(out, {"episode_wall_time_s": {name: [float(r.wall_time_s) for r in rs]
                                                for name, rs in by_policy.items()}})
    rrds = {name: Path(rs[0].rrd) for name, rs in by_policy.items() if rs and rs[0].rrd}
    for old in (out / "rerun").glob("*.rrd"):  # every other recording there: an earlier evaluation's
        if old not in rrds.values():
            old.unlink(missing_ok=True)
    return EvaluationReport(out, aggs, by_policy, report_md, metrics_json, plots, rrds, closeness, recorded)


#: Held-out log-likelihood per step of uniform actions over the merge actions (log 1/5 = -1.609):
#: a driver scoring below it predicts the held-out demonstrations worse than chance.
UNIFORM_LL_PER_STEP = -math.log(N_ACTIONS)


def heldout_flags(heldout: tuple[float, float] | None) -> tuple[str, ...]:
    """``("heldout_worse_than_uniform",)`` when a held-out score ``(sum, per step)`` is below
    :data:`UNIFORM_LL_PER_STEP` per step (beyond rounding), else ``()``."""
    if heldout is None or not math.isfinite(heldout[1]):
        return ()
    return ("heldout_worse_than_uniform",) if heldout[1] < UNIFORM_LL_PER_STEP - 1e-9 else ()
