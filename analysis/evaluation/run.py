"""Run a planned evaluation: every driver over the same seeds, through the sweep runner.

:func:`run_plan` makes the output folder, runs the episodes of an
:class:`~analysis.evaluation.plan.EvaluationPlan` (:func:`run_episodes`) and returns them per
policy; a failed or interrupted run leaves no partial recording behind (:func:`discard_unfinished`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from analysis.errors import AnalysisError
from analysis.evaluation.episode import EpisodeResult, EpisodeSpec, run_episode_task
from analysis.evaluation.plan import EvaluationPlan
from analysis.sweep import Task, resolve_executor, run_sweep
from merge_irl.run_folder import check_writable


@dataclass(frozen=True)
class EvaluationRun:
    """The episodes of a run plan (:func:`run_plan`).

    Attributes:
        by_policy: policy name -> its episodes' results, in seed order (every policy of the plan).
    """

    by_policy: Mapping[str, list[EpisodeResult]] = field(repr=False)


def run_plan(plan: EvaluationPlan) -> EvaluationRun:
    """Make ``plan.out_dir`` and run every episode of the plan on ``plan.executor``.

    Raises:
        PermissionError: the output folder cannot be written.
        AnalysisError: an episode failed twice (every failure listed).
        SimulationError: SUMO fails to start or to step (in a serial run).
    """
    cfg = plan.config
    out = plan.out_dir
    created = not out.exists()
    out.mkdir(parents=True, exist_ok=True)
    check_writable(out / "report.md")  # before the episodes, not after
    counts = plan.heldout.action_counts if plan.heldout is not None else None
    tasks = []
    for p in plan.policies:
        for i in range(cfg.episodes):
            kw = dict(duration_s=cfg.duration_s, controller=plan.controller, metrics=cfg.metrics,
                      demo_action_counts=counts,
                      rrd_path=str(out / "rerun" / f"{p.name}.rrd") if (cfg.rrd and i == 0) else None)
            tasks.append((plan.spec, p, cfg.seed + i, kw))
    try:
        results = sweep_episodes(tasks, plan.executor, progress=cfg.progress)  # the plan's executor, as resolved
    except BaseException:  # a failed or interrupted evaluation leaves no partial recording behind
        discard_unfinished(out, [p.name for p in plan.policies], created=created)
        raise
    by_policy: dict[str, list[EpisodeResult]] = {p.name: [] for p in plan.policies}
    for (_, p, _, _), r in zip(tasks, results):
        by_policy[p.name].append(r)
    return EvaluationRun(by_policy)


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
    return sweep_episodes(tasks, resolve_executor(executor, workers), store=store, progress=progress)


def sweep_episodes(tasks: Sequence[tuple], executor: str, *, store=None, progress: bool = True) -> list[EpisodeResult]:
    """:func:`run_episodes` on a resolved ``executor`` spec (:func:`analysis.sweep.resolve_executor`).

    Raises:
        AnalysisError: if an episode failed twice (every failure listed).
    """
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
