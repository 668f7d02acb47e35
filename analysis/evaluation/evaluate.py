"""Evaluate driving policies in closed loop: learned IRL models against SUMO and random.

Example::

    from analysis.evaluation.evaluate import evaluate

    report = evaluate(["runs/demo/models/qavg.json"], "synthetic", episodes=4, seed=1,
                      out_dir="runs/eval", demos="runs/demo/heldout_encounters.parquet")
    print(report.report_md)          # report.md: one row per policy
    print(report.aggregates["qavg"].b_ahead_rate)

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

import math
import os
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import pandas as pd

from analysis.errors import AnalysisError
from analysis.evaluation.aggregate import AggregateMetrics, aggregate
from analysis.evaluation.distances import w1_to_demos
from analysis.evaluation.episode import EpisodeResult, EpisodeSpec, run_episode_task
from analysis.evaluation.heldout_scoring import load_heldout, policy_heldout_loglik
from analysis.evaluation.human_likeness import DemoCloseness, demo_close_to_c, w1_acc_jerk
from analysis.evaluation.metrics import MetricsConfig
from analysis.evaluation.policies import check_picklable, check_unambiguous, learned_policy, with_distinct_names
from analysis.evaluation.report import write_outputs
from analysis.sweep import Task, resolve_executor, run_sweep
from irl.domains.merge.actions import N_ACTIONS
from irl.domains.merge.mdp import DEFAULT_DECISION_STEP_S, frames_per_step
from irl.errors import ConfigError
from irl.result import SavedModel
from merge_irl.provenance import provenance, text_digest, write_timings
from merge_irl.run_folder import check_writable
from merge_irl.units import FRAME_S, FT_PER_M
from scenarios.loader import load_scenario
from scenarios.spec.parse import with_overrides
from sim.closed_loop.config import ControllerConfig
from sim.drivers.baselines import baseline_drivers, check_baselines, default_baselines, left_out_baselines
from sim.drivers.learned import LearnedPolicy
from sim.drivers.policy import Policy, check_policy


class DecisionStepWarning(UserWarning):
    """A policy is driven at another decision step than the one it was trained at."""


@dataclass(frozen=True)
class EvaluationReport:
    """Result of :func:`evaluate`.

    Attributes:
        out_dir: where the files are.
        aggregates: policy name -> aggregated metrics.
        episodes: policy name -> per-episode results (metrics, controls, decisions, profiles).
        report_md, metrics_json: paths of the written report and metrics.
        plots: paths of the PNG plots.
        rrd: policy name -> rerun recording (first episode), if written.
        demo_closeness: the share of held-out encounters whose A came within the metrics'
            ``close_gap_m`` of C (None without ``demos``).
    """

    out_dir: Path
    aggregates: dict[str, AggregateMetrics]
    episodes: dict[str, list[EpisodeResult]] = field(repr=False)
    report_md: Path
    metrics_json: Path
    plots: tuple[Path, ...] = ()
    rrd: dict[str, Path] = field(default_factory=dict)
    demo_closeness: DemoCloseness | None = None


def run_episodes(tasks: Sequence[tuple], *, workers: int | None = None, executor: str | None = None,
                 store=None, progress: bool = True) -> list[EpisodeResult]:
    """Run ``(scenario, policy, seed, kwargs)`` tasks through :func:`analysis.sweep.run_sweep`, in order.

    Args:
        executor: ``serial``, ``process[:N]``, ``dask-local[:N]`` or ``dask://HOST:PORT``
            (default: ``process:<workers>``, or every core if ``workers`` is None too). Process
            workers are fresh ``spawn`` processes running one task (one libsumo simulation) at
            a time; the Dask executors start single-threaded workers.
        workers: shorthand for ``executor="process:<workers>"``.
        store: optional result directory (finished episodes are skipped on a re-run).

    Raises:
        AnalysisError: if an episode failed twice (every failure listed).
    """
    executor = resolve_executor(executor, workers)
    sweep_tasks = []
    for i, (scenario, policy, seed, kw) in enumerate(tasks):
        kw = dict(kw)
        counts = kw.pop("demo_action_counts", None)
        spec = EpisodeSpec(scenario, policy, int(seed), **kw,
                           demo_action_counts=None if counts is None else tuple(int(c) for c in counts))
        sweep_tasks.append(Task(f"{i:04d}/{policy.name}/seed{int(seed)}", run_episode_task, spec))
    report = run_sweep(sweep_tasks, seed=0, executor=executor, store=store, progress=progress,
                       desc="episodes")
    if not report.ok:
        stopped = " (the evaluation stopped there)" if report.aborted else ""
        raise AnalysisError("episodes failed: " + "; ".join(f"{f.key}: {f.error}" for f in report.failures) + stopped)
    return [EpisodeResult.from_dict(report.results[t.key]) for t in sweep_tasks]


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
    workers: int | None = 2,
    executor: str | None = None,
    rrd: bool = True,
    progress: bool = True,
    allow_implausible: bool = False,
) -> EvaluationReport:
    """Closed-loop evaluation of each model (and the baselines) over ``episodes`` seeds.

    Args:
        models: saved models (``model.json`` paths or objects) of the merge domain.
        scenario: preset name, TOML path or ScenarioSpec.
        episodes: episodes per policy; seeds ``seed + i``.
        out_dir: output folder (created).
        duration_s: override the scenario's duration.
        demos: held-out encounters (Parquet/CSV/DataFrame) for the action divergence and the
            held-out log-likelihood; None: both are NaN.
        baselines: names of :data:`sim.drivers.baselines.BASELINES` (None: its default
            set, :func:`~sim.drivers.baselines.default_baselines`): ``"sumo"`` (not taken over),
            ``"uniform"`` (random actions), ``"marginal"``, ``"markov"``, ``"bc"`` (fitted on
            ``train_demos`` in the first model's state bins; left out, and said so in report.md,
            without them), ``"idm"`` (:class:`sim.drivers.idm.IdmPolicy` of the scenario's car type;
            its actions applied at ``train_demos``' mean acceleration per action bin, as the fitted
            baselines', else at the bin midpoints), ``"sumo-in-lane"`` (SUMO's driver, A's lane
            changes off while observed), and any registered by
            :func:`~sim.drivers.baselines.register_baseline`.
        train_demos: training encounters (Parquet/CSV/DataFrame) of the fitted baselines.
        policies: further policies to evaluate (e.g. ``ConstantPolicy(0)``, a car-following
            logit driver of :func:`~analysis.evaluation.policies.cf_policy`, or any callable
            ``obs -> action`` as a :class:`sim.drivers.callables.CallablePolicy`).
        workers: processes (shorthand for ``executor="process:<workers>"``).
        executor: where episodes run (see :func:`run_episodes`); overrides ``workers``.
        rrd: write a rerun recording of each policy's first episode.
        allow_implausible: run a scenario (and ``duration_s``) outside the plausibility bounds
            (:mod:`scenarios.spec.bounds`).
        controller: ``decision_step_s`` None: the first model's ``decision_step_s`` (else the first
            of ``policies`` whose ``decision_step_s`` is not None, else
            :data:`~irl.domains.merge.mdp.DEFAULT_DECISION_STEP_S`) for every policy, so all decide
            on the same step.

    Every input is read and checked, and the held-out scores taken, before the output folder is
    made and any episode runs.

    Raises:
        SpecError: the scenario cannot be loaded, or ``duration_s`` is invalid or implausible for it.
        AnalysisError: ``episodes`` < 1, or a decision step that is not a positive multiple of
            the 0.1 s simulation step.
        SimError: an unknown baseline name.
        PolicyError: a model is not a merge model, a policy lacks a member of
            :class:`sim.drivers.policy.Policy`, two policies share a name and one of them is not a
            dataclass that can be renamed, or a policy cannot be pickled for the executor's worker
            processes (:func:`~analysis.evaluation.policies.check_picklable`).
        ModelFileError: a model file is missing or malformed.
        DemonstrationError: the held-out or training encounters cannot be read, lack columns, or
            cannot be scored.
        SimulationError: SUMO fails to start or to step.
    """
    if episodes < 1:
        raise AnalysisError(f"evaluate: episodes must be >= 1, got {episodes}")
    spec = (load_scenario(scenario, allow_implausible=allow_implausible) if isinstance(scenario, (str, Path))
            else replace(scenario, allow_implausible=True) if allow_implausible else scenario)  # validate before SUMO
    if duration_s is not None:
        with_overrides(spec, duration_s=duration_s)  # a duration the scenario rejects: now, not in every episode
    baselines = default_baselines() if baselines is None else tuple(baselines)
    check_baselines(baselines)
    for p in policies:
        check_policy(p, scoring=demos is not None, where="evaluate")
    learned: list[LearnedPolicy] = [learned_policy(m) for m in models]
    pols: list[Policy] = list(learned)
    step = controller.decision_step_s
    steps = [(p.name, float(s)) for p in (*learned, *policies) if (s := p.decision_step_s) is not None]
    if step is None:
        step = steps[0][1] if steps else DEFAULT_DECISION_STEP_S
        controller = replace(controller, decision_step_s=step)
    try:
        frames_per_step(step)
    except ConfigError:
        raise AnalysisError(f"evaluate: the decision step must be a positive multiple of the {FRAME_S} s simulation "
                       f"step, got {step}") from None
    other = [(name, s) for name, s in steps if not math.isclose(s, step)]
    if other:
        warnings.warn(f"evaluate: every policy decides every {step} s, but " + ", ".join(
            f"{name} was trained at {s} s" for name, s in other), DecisionStepWarning, stacklevel=2)
    pols += baseline_drivers(baselines, spec, train_demos, learned[0].encoder if learned else None, step)
    check_unambiguous(policies, pols)  # a --policy named 'sumo' beside the baseline: refused, not 'sumo-2'
    pols.extend(policies)
    pols = with_distinct_names(pols)
    check_picklable(pols, resolve_executor(executor, workers))  # a lambda: now, named, not as a raw pickling error
    held = load_heldout(demos) if demos is not None else None
    # the held-out scores do not depend on the episodes: taken first, so a held-out table that a
    # policy's scoring rejects fails before any SUMO run
    scores: dict[str, tuple[float, float] | None] = {}
    shared: dict = {}  # what several policies' held-out scoring shares (Policy.heldout_inputs)
    for p in pols:
        scores[p.name] = policy_heldout_loglik(p, held, step, cache=shared) if held is not None else None
    out = Path(out_dir)  # made once every input has been read and checked, so a bad input leaves no folder
    created = not out.exists()
    out.mkdir(parents=True, exist_ok=True)
    check_writable(out / "report.md")  # before the episodes, not after
    prov = evaluation_provenance(models, pols, scenario, spec, demos, train_demos)  # the files as read, before the work
    counts = held.action_counts if held is not None else None
    tasks = []
    for p in pols:
        for i in range(episodes):
            kw = dict(duration_s=duration_s, controller=controller, metrics=metrics, demo_action_counts=counts,
                      rrd_path=str(out / "rerun" / f"{p.name}.rrd") if (rrd and i == 0) else None)
            tasks.append((spec, p, seed + i, kw))
    try:
        results = run_episodes(tasks, workers=workers, executor=executor, progress=progress)
    except BaseException:  # a failed or interrupted evaluation leaves no partial recording behind
        discard_unfinished(out, [p.name for p in pols], created=created)
        raise
    by_policy: dict[str, list[EpisodeResult]] = {p.name: [] for p in pols}
    for (_, p, _, _), r in zip(tasks, results):
        by_policy[p.name].append(r)
    aggs = {}
    for p in pols:
        ho = scores[p.name]
        rs = by_policy[p.name]
        w1 = {**w1_to_demos(pd.concat([r.decisions for r in rs], ignore_index=True), held.encounters),
              **w1_acc_jerk([r.speed_profiles for r in rs], held.encounters)} if held is not None and rs else None
        aggs[p.name] = aggregate([r.metrics for r in rs], demo_action_counts=counts, heldout=ho, w1=w1,
                                 flags=tuple(p.flags) + heldout_flags(ho))
    closeness = demo_close_to_c(held.encounters, metrics.close_gap_m) if held is not None else None
    scen_name = scenario if isinstance(scenario, (str, Path)) else spec.name
    report_md, metrics_json, plots = write_outputs(
        out, aggs, by_policy, held, scenario=str(scen_name), seed=seed, episodes=episodes,
        duration_s=duration_s, controller=controller, metrics=metrics,
        provenance=prov, speed_limit_ft_s=spec.road.speed_limit_mps * FT_PER_M,
        left_out=left_out_baselines(baselines, train_demos), demo_closeness=closeness,
    )
    write_timings(out, {"episode_wall_time_s": {name: [float(r.wall_time_s) for r in rs]
                                                for name, rs in by_policy.items()}})
    rrds = {name: Path(rs[0].rrd) for name, rs in by_policy.items() if rs and rs[0].rrd}
    for old in (out / "rerun").glob("*.rrd"):  # every other recording there: an earlier evaluation's
        if old not in rrds.values():
            old.unlink(missing_ok=True)
    return EvaluationReport(out, aggs, by_policy, report_md, metrics_json, plots, rrds, closeness)


#: Held-out log-likelihood per step of uniform actions over the merge actions (log 1/5 = -1.609):
#: a driver scoring below it predicts the held-out demonstrations worse than chance.
UNIFORM_LL_PER_STEP = -math.log(N_ACTIONS)


def heldout_flags(heldout: tuple[float, float] | None) -> tuple[str, ...]:
    """``("heldout_worse_than_uniform",)`` when a held-out score ``(sum, per step)`` is below
    :data:`UNIFORM_LL_PER_STEP` per step (beyond rounding), else ``()``."""
    if heldout is None or not math.isfinite(heldout[1]):
        return ()
    return ("heldout_worse_than_uniform",) if heldout[1] < UNIFORM_LL_PER_STEP - 1e-9 else ()


def discard_unfinished(out: Path, names: Sequence[str], *, created: bool) -> None:
    """After a failed or interrupted evaluation: remove the recordings its episodes left half
    written (``rerun/.<name>.rrd.*.tmp.partial``, their workers having been stopped) and, when this
    evaluation made ``out``, the recordings it finished and the folders it made, if left empty.
    A folder that was there before keeps everything else (an earlier evaluation's files)."""
    rerun = out / "rerun"
    for name in names:
        for f in rerun.glob(f".{name}.rrd.*.tmp.partial"):
            f.unlink(missing_ok=True)
        if created:
            (rerun / f"{name}.rrd").unlink(missing_ok=True)
    if created:
        for folder in (rerun, out):
            try:
                folder.rmdir()
            except OSError:  # not empty, or gone
                pass


def evaluation_provenance(models: Sequence, pols: Sequence[Policy], scenario, spec, demos, train_demos=None) -> dict:
    """:func:`merge_irl.provenance.provenance` of an evaluation: the model file of each policy
    (``pols`` starts with one policy per entry of ``models``; a further policy's ``source``
    file when it has one, as :func:`~analysis.evaluation.policies.cf_policy`'s; None for baselines and models given as
    objects), the held-out and training demonstrations and scenario files read, and the SHA-256
    of the scenario actually simulated (its TOML)."""
    files = {p.name: None if isinstance(m, SavedModel) else m for p, m in zip(pols, models)}
    files.update({p.name: p.source or None for p in pols[len(models):]})
    scenario_file = scenario if isinstance(scenario, (str, Path)) and Path(scenario).is_file() else None
    demos_file = None if isinstance(demos, pd.DataFrame) else demos
    train_file = None if isinstance(train_demos, pd.DataFrame) else train_demos
    return provenance({"demos": demos_file, "train_demos": train_file, "scenario": scenario_file}, files,
                      extra={"scenario_sha256": text_digest(spec.to_toml())})



