"""Evaluate driving policies in closed loop: learned IRL models against SUMO and random.

Example::

    from analysis.evaluate import evaluate

    report = evaluate(["runs/demo/models/qavg.json"], "synthetic", episodes=4, seed=1,
                      out_dir="runs/eval", demos="runs/demo/heldout_encounters.parquet")
    print(report.report_md)          # report.md: one row per policy
    print(report.aggregates["qavg"].b_ahead_rate)

Every policy runs the same episodes (seeds ``seed .. seed + episodes - 1``: the same traffic
for every policy). Episodes run through :func:`analysis.sweep.run_sweep` (``executor``: a
process pool by default, one libsumo simulation per process at a time; or Dask). Outputs in ``out_dir``: ``report.md``, ``metrics.json``, ``action_histograms.png``,
``gap_acceptance.png``, ``speed_profiles.png``, ``timings.json`` (wall time of each episode,
kept out of the results so reruns can be compared by hash) and, with ``rrd=True``, one rerun
recording of the first episode of each policy under ``rerun/``. ``metrics.json`` and
``report.md`` record their provenance (:mod:`analysis.provenance`).
"""

from __future__ import annotations

import math
import os
import sys
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, is_dataclass, replace
from pathlib import Path

import numpy as np
import pandas as pd

from analysis.episode import EpisodeResult, EpisodeSpec, run_episode_task
from analysis.evaluate_report import write_outputs
from analysis.metrics import MetricsConfig
from analysis.metrics_aggregate import AggregateMetrics, aggregate
from analysis.metrics_demos import heldout_loglik, w1_to_demos
from analysis.provenance import provenance, text_digest, write_timings
from analysis.sweep import Task, parse_executor, run_sweep
from irl.baselines import fit_baseline
from irl.domains.merge_actions import ACTION_ACC_FT_S2, N_ACTIONS, actions_of
from irl.domains.merge_bins import MergeBins, fit_quantile_bins
from irl.domains.merge_car_following import CFDecisions, car_following_decisions
from irl.domains.merge_cf_logit import CarFollowingLogit
from irl.domains.merge_encounters import REQUIRED_COLUMNS
from irl.errors import ConfigError, DemonstrationError
from irl.merge_mdp import action_mean_acc, discretize, frames_per_step, read_encounters
from irl.result import SavedModel
from irl.run_folder import check_writable
from irl.units import FRAME_S, FT_PER_M
from scenarios.loader import load_scenario
from sim.controller_config import ControllerConfig
from sim.errors import SimError
from sim.idm_policy import IdmPolicy
from sim.observe import MergeObservation
from sim.policy import (BaselineTabularPolicy, CarFollowingLogitPolicy, LearnedPolicy, Policy, PolicyError,
                        SumoPolicy, UniformPolicy)

#: Baselines of every evaluation (issue 11): SUMO's own driver, uniform random, and the
#: tabular baselines fitted on the training demonstrations (:mod:`irl.baselines`).
BASELINES = ("sumo", "uniform", "marginal", "markov", "bc")
#: Every baseline an evaluation can run: :data:`BASELINES` and, on request, ``idm``, the
#: Intelligent Driver Model with the scenario's car parameters through the controller
#: (:class:`sim.idm_policy.IdmPolicy`), and ``sumo-in-lane``, SUMO's driver with A's lane
#: changes switched off while observed (:class:`sim.policy.SumoPolicy` ``keep_lane``).
KNOWN_BASELINES = (*BASELINES, "idm", "sumo-in-lane")
#: The baselines that need training demonstrations.
FITTED_BASELINES = ("marginal", "markov", "bc")


@dataclass(frozen=True)
class HeldOut:
    """Demonstrations used for the divergence and the held-out log-likelihood.

    Attributes:
        encounters: encounter frames (``irl.domains.merge_encounters.ENCOUNTER_SCHEMA``; NaN d_AC and
            v_AC = no lead car, encoded by the domain's no-lead-car rule).
        action_counts: ``[5]`` counts of the binned ``acc_A``.
        source: where they came from.
    """

    encounters: pd.DataFrame
    action_counts: np.ndarray
    source: str = ""


def prepare_encounters(frames: pd.DataFrame, where: str = "encounters") -> pd.DataFrame:
    """Encounter frames ready to discretize: rows with A, B and an action only (frames without
    car C stay, with d_AC and v_AC NaN: the domain's no-lead-car rule encodes them).

    Raises:
        DemonstrationError: a column of :data:`irl.domains.merge_encounters.REQUIRED_COLUMNS` is
            missing (``where`` names the table).
    """
    missing = [c for c in REQUIRED_COLUMNS if c not in frames.columns]
    if missing:
        raise DemonstrationError(f"{where}: encounter table lacks column(s) {missing}; expected {list(REQUIRED_COLUMNS)} "
                                 "(an encounters.parquet of 'merge-irl generate' or 'merge-irl encounters')")
    df = frames.copy()
    df = df[np.isfinite(df["d_AB"]) & np.isfinite(df["v_AB"]) & np.isfinite(df["acc_A"])]
    return df.reset_index(drop=True)


def load_heldout(demos: str | os.PathLike | pd.DataFrame) -> HeldOut:
    """Held-out demonstrations from an encounter table (Parquet/CSV path or DataFrame)."""
    if isinstance(demos, pd.DataFrame):
        df, src = demos, "encounters"
    else:
        df, src = read_encounters(demos), str(demos)
    df = prepare_encounters(df, src)
    counts = np.bincount(actions_of(df["acc_A"].to_numpy(float)), minlength=N_ACTIONS)
    return HeldOut(df, counts.astype(np.int64), src)


def policy_heldout_loglik(policy: Policy, heldout: HeldOut, decision_step_s: float = 0.1, *,
                          cf_decisions: CFDecisions | None = None) -> tuple[float, float]:
    """``(sum, per step)`` state-conditional log-likelihood of the held-out demonstrations under
    ``policy`` (NaN for SUMO), scored as learning sees them: resampled at the decision step
    (:func:`irl.merge_mdp.discretize`; a learned policy at its model's ``decision_step_s`` and
    state encoding, every other policy at ``decision_step_s``), so an action is the forward
    difference of A's speed over one decision. ``markov`` scores a trajectory's first step by
    its marginal. ``cf_decisions``: the held-out decisions of a car-following driver when
    already taken (:func:`~irl.domains.merge_car_following.car_following_decisions` at its step).
    NaN for the deterministic IDM reference driver as well (no likelihood to speak of)."""
    if not policy.controls or isinstance(policy, IdmPolicy):
        return float("nan"), float("nan")
    df = heldout.encounters
    if isinstance(policy, CarFollowingLogitPolicy):
        dec = cf_decisions if cf_decisions is not None else car_following_decisions(
            df, decision_step_s=policy.decision_step_s, where=heldout.source)
        total = policy.model.loglik_of(dec)
        return total, total / dec.n
    if isinstance(policy, LearnedPolicy):
        d = discretize(df, policy.encoder, where=heldout.source, encoding=policy.state_encoding,
                       decision_step_s=policy.decision_step_s)
        s, a, _ = d.flat()
        return heldout_loglik(policy.log_pi, s, a)
    bins = policy.encoder if isinstance(policy, BaselineTabularPolicy) else MergeBins.assumed_authors()
    d = discretize(df, bins, where=heldout.source, decision_step_s=decision_step_s)
    n = sum(len(x) for x in d.actions)
    if isinstance(policy, BaselineTabularPolicy):
        total = float(policy.baseline.loglik(d))
        return total, total / n if n else float("nan")
    # state-independent policies (uniform, constant): log p(a)
    _, actions, _ = d.flat()
    p = np.asarray(policy.probs(MergeObservation(0, 0, 0, 0, False, 0)), dtype=float)
    with np.errstate(divide="ignore"):
        lp = np.log(p)[actions]
    return float(lp.sum()), float(lp.mean()) if lp.size else float("nan")


def baseline_policies(names: Sequence[str], train_demos: str | os.PathLike | pd.DataFrame,
                      bins: MergeBins | None = None, decision_step_s: float = 0.3) -> list[BaselineTabularPolicy]:
    """The fitted baselines ``names`` (of ``FITTED_BASELINES``) from training encounters, in
    the paper state bins ``bins`` (None: quantile bins fitted on the training encounters).

    Raises:
        DemonstrationError: the training encounters cannot be read or discretized.
    """
    df = _training_table(train_demos)
    where = "training encounters" if isinstance(train_demos, pd.DataFrame) else str(train_demos)
    bins = bins if bins is not None else fit_quantile_bins(df, where=where)
    demos = discretize(df, bins, where=where, decision_step_s=decision_step_s)
    means = training_action_acc(df)
    return [BaselineTabularPolicy(fit_baseline(n, demos), bins, n, action_acc_ft_s2=means) for n in names]


def _training_table(train_demos: str | os.PathLike | pd.DataFrame) -> pd.DataFrame:
    df = train_demos if isinstance(train_demos, pd.DataFrame) else read_encounters(train_demos)
    return prepare_encounters(df, "training encounters" if isinstance(train_demos, pd.DataFrame) else str(train_demos))


def training_action_acc(train_demos: str | os.PathLike | pd.DataFrame) -> tuple[float, ...]:
    """``[5]`` the mean acceleration (ft/s^2) of each action bin over the frames of the training
    encounters (a bin without frames: its midpoint), as the baselines apply their actions.

    Raises:
        DemonstrationError: the training encounters cannot be read.
    """
    acc = _training_table(train_demos)["acc_A"].to_numpy(float)
    return action_mean_acc(acc, actions_of(acc))


def learned_policy(model: SavedModel | str | os.PathLike, name: str = "") -> LearnedPolicy:
    """A :class:`LearnedPolicy` from a saved model (path or object) with its bin edges.

    Raises:
        ModelFileError: ``model`` is a path to a missing, unreadable or malformed ``model.json``.
        PolicyError: the model is not a merge model (message prefixed with the file).
    """
    where = "model"
    if not isinstance(model, SavedModel):
        path = Path(model)
        model = SavedModel.load(path)
        name = name or path.stem
        where = str(path)
    try:
        return LearnedPolicy.from_model(model, name=name or model.method)
    except PolicyError as e:
        raise type(e)(f"{where}: {e}") from None


def cf_policy(path: str | os.PathLike, name: str = "") -> CarFollowingLogitPolicy:
    """A :class:`~sim.policy.CarFollowingLogitPolicy` from a car-following logit file
    (``cf-dagger.json`` or ``cf-logit.json`` of ``merge-irl dagger``), named ``name`` or the
    file's stem (as :func:`learned_policy` names a model file; the demo's ``cf-dagger`` is
    ``models/cf-dagger.json``). A fit that did not converge is flagged (``not_converged``).

    Raises:
        ModelFileError: a missing, unreadable or malformed file.
    """
    return CarFollowingLogitPolicy(CarFollowingLogit.load(path), name=name or Path(path).stem, source=str(path))


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
    """

    out_dir: Path
    aggregates: dict[str, AggregateMetrics]
    episodes: dict[str, list[EpisodeResult]] = field(repr=False)
    report_md: Path
    metrics_json: Path
    plots: tuple[Path, ...] = ()
    rrd: dict[str, Path] = field(default_factory=dict)


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
        SimError: if an episode failed twice (every failure listed).
    """
    executor = resolve_executor(executor, workers)
    sweep_tasks = []
    for i, (scenario, policy, seed, kw) in enumerate(tasks):
        kw = dict(kw)
        counts = kw.pop("demo_action_counts", None)
        spec = EpisodeSpec(scenario, policy, int(seed), **kw,
                           demo_action_counts=None if counts is None else tuple(int(c) for c in counts))
        sweep_tasks.append(Task(f"{i:04d}/{policy.name}/seed{int(seed)}", run_episode_task, spec))
    report = run_sweep(sweep_tasks, seed=0, executor=executor, store=store, progress=progress and sys.stderr.isatty(),
                       desc="episodes")
    if not report.ok:
        raise SimError("episodes failed: " + "; ".join(f"{f.key}: {f.error}" for f in report.failures))
    return [EpisodeResult.from_dict(report.results[t.key]) for t in sweep_tasks]


def resolve_executor(executor: str | None, workers: int | None) -> str:
    """``executor`` if given, else ``process:<workers>``, else ``process`` (every core);
    raises SimError on a malformed value.

    Raises:
        SimError: both ``executor`` and ``workers`` given, or an executor spec that does not parse.
    """
    if executor is None:
        executor = "process" if workers is None else f"process:{max(1, int(workers))}"
    try:
        parse_executor(executor)
    except ValueError as e:
        raise SimError(str(e)) from None
    return executor


def evaluate(
    models: Sequence[SavedModel | str | os.PathLike],
    scenario,
    episodes: int,
    seed: int,
    out_dir: str | os.PathLike,
    *,
    duration_s: float | None = None,
    demos: str | os.PathLike | pd.DataFrame | None = None,
    baselines: Sequence[str] = BASELINES,
    train_demos: str | os.PathLike | pd.DataFrame | None = None,
    policies: Sequence[Policy] = (),
    controller: ControllerConfig = ControllerConfig(),
    metrics: MetricsConfig = MetricsConfig(),
    workers: int | None = 2,
    executor: str | None = None,
    rrd: bool = True,
    progress: bool = True,
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
        baselines: any of ``KNOWN_BASELINES`` (default ``BASELINES``): ``"sumo"`` (not taken over),
            ``"uniform"`` (random actions), ``"marginal"``, ``"markov"``, ``"bc"`` (fitted on
            ``train_demos`` in the first model's state bins; left out, and said so in report.md,
            without them), ``"idm"`` (:class:`sim.idm_policy.IdmPolicy` of the scenario's car type;
            its actions applied at ``train_demos``' mean acceleration per action bin, as the fitted
            baselines', else at the bin midpoints), ``"sumo-in-lane"`` (SUMO's driver, A's lane
            changes off while observed).
        train_demos: training encounters (Parquet/CSV/DataFrame) of the fitted baselines.
        policies: further policies to evaluate (e.g. ``ConstantPolicy(0)``, or a car-following
            logit driver of :func:`cf_policy`).
        workers: processes (shorthand for ``executor="process:<workers>"``).
        executor: where episodes run (see :func:`run_episodes`); overrides ``workers``.
        rrd: write a rerun recording of each policy's first episode.
        controller: ``decision_s`` None: the first model's ``decision_step_s`` (else the first
            of ``policies`` that has one, else 0.3 s) for every policy, so all decide on the same step.

    Every input is read and checked, and the held-out scores taken, before the output folder is
    made and any episode runs.

    Raises:
        SimError: ``episodes`` < 1, an unknown baseline name, or a decision step that is not a
            positive multiple of the 0.1 s simulation step.
        PolicyError: a model is not a merge model, or two policies share a name and one of them is not a
            dataclass that can be renamed.
        ModelFileError: a model file is missing or malformed.
        DemonstrationError: the held-out or training encounters cannot be read, lack columns, or
            cannot be scored.
        SimulationError: SUMO fails to start or to step.
    """
    if episodes < 1:
        raise SimError(f"evaluate: episodes must be >= 1, got {episodes}")
    spec = load_scenario(scenario) if isinstance(scenario, (str, Path)) else scenario  # validate before SUMO
    bad = [b for b in baselines if b not in KNOWN_BASELINES]
    if bad:
        raise SimError(f"evaluate: unknown baseline(s) {bad}; expected some of {', '.join(KNOWN_BASELINES)}")
    learned: list[LearnedPolicy] = [learned_policy(m) for m in models]
    pols: list[Policy] = list(learned)
    step = controller.decision_s
    steps = [(p.name, p.decision_step_s) for p in (*learned, *policies) if hasattr(p, "decision_step_s")]
    if step is None:
        step = steps[0][1] if steps else 0.3
        controller = replace(controller, decision_s=step)
    try:
        frames_per_step(step)
    except ConfigError:
        raise SimError(f"evaluate: the decision step must be a positive multiple of the {FRAME_S} s simulation "
                       f"step, got {step}") from None
    other = [(name, s) for name, s in steps if not math.isclose(s, step)]
    if other:
        warnings.warn(f"evaluate: every policy decides every {step} s, but " + ", ".join(
            f"{name} was trained at {s} s" for name, s in other), DecisionStepWarning, stacklevel=2)
    fitted = [b for b in baselines if b in FITTED_BASELINES]
    fitted_pols = baseline_policies(fitted, train_demos, learned[0].encoder if learned else None,
                                    step) \
        if fitted and train_demos is not None else []
    by_name = {p.name: p for p in fitted_pols}
    for b in baselines:
        if b in FITTED_BASELINES:
            if b in by_name:
                pols.append(by_name[b])
        elif b == "idm":  # applies its actions as the fitted baselines do, when there are training encounters
            if train_demos is None:
                warnings.warn("evaluate: idm without training encounters applies the action bins' midpoints "
                              f"{tuple(ACTION_ACC_FT_S2)} ft/s^2 (High Brake too weak to stop behind a braking car; "
                              "give train_demos / --train-demos)", UserWarning, stacklevel=2)
            acc = fitted_pols[0].action_acc_ft_s2 if fitted_pols else training_action_acc(train_demos) \
                if train_demos is not None else tuple(float(x) for x in ACTION_ACC_FT_S2)
            pols.append(IdmPolicy.from_scenario(spec, action_acc_ft_s2=acc))
        else:
            pols.append(_BASELINES[b]())
    pols.extend(policies)
    names = [p.name for p in pols]
    dup = {n for n in names if names.count(n) > 1}
    if dup:
        seen: dict[str, int] = {}
        renamed = []
        for p in pols:
            k = seen.get(p.name, 0)
            seen[p.name] = k + 1
            renamed.append(_renamed(p, f"{p.name}-{k + 1}") if p.name in dup else p)
        pols = renamed
    held = load_heldout(demos) if demos is not None else None
    # the held-out scores do not depend on the episodes: taken first, so a held-out table that a
    # policy's scoring rejects fails before any SUMO run
    scores: dict[str, tuple[float, float] | None] = {}
    cf_decisions: dict[float, CFDecisions] = {}  # by decision step
    for p in pols:
        cf_dec = None
        if held is not None and isinstance(p, CarFollowingLogitPolicy):
            if p.decision_step_s not in cf_decisions:
                cf_decisions[p.decision_step_s] = car_following_decisions(
                    held.encounters, decision_step_s=p.decision_step_s, where=held.source)
            cf_dec = cf_decisions[p.decision_step_s]
        scores[p.name] = policy_heldout_loglik(p, held, step, cf_decisions=cf_dec) if held is not None else None
    out = Path(out_dir)  # made once every input has been read and checked, so a bad input leaves no folder
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
    results = run_episodes(tasks, workers=workers, executor=executor, progress=progress)
    by_policy: dict[str, list[EpisodeResult]] = {p.name: [] for p in pols}
    for (_, p, _, _), r in zip(tasks, results):
        by_policy[p.name].append(r)
    aggs = {}
    for p in pols:
        ho = scores[p.name]
        rs = by_policy[p.name]
        w1 = w1_to_demos(pd.concat([r.decisions for r in rs], ignore_index=True), held.encounters) \
            if held is not None and rs else None
        aggs[p.name] = aggregate([r.metrics for r in rs], demo_action_counts=counts, heldout=ho, w1=w1,
                                 flags=tuple(getattr(p, "flags", ())))
    scen_name = scenario if isinstance(scenario, (str, Path)) else spec.name
    report_md, metrics_json, plots = write_outputs(
        out, aggs, by_policy, held, scenario=str(scen_name), seed=seed, episodes=episodes,
        duration_s=duration_s, controller=controller, metrics=metrics,
        provenance=prov, speed_limit_ft_s=spec.road.speed_limit_mps * FT_PER_M,
        left_out=[b for b in fitted if b not in by_name],
    )
    write_timings(out, {"episode_wall_time_s": {name: [float(r.wall_time_s) for r in rs]
                                                for name, rs in by_policy.items()}})
    rrds = {name: Path(rs[0].rrd) for name, rs in by_policy.items() if rs and rs[0].rrd}
    return EvaluationReport(out, aggs, by_policy, report_md, metrics_json, plots, rrds)


def evaluation_provenance(models: Sequence, pols: Sequence[Policy], scenario, spec, demos, train_demos=None) -> dict:
    """:func:`analysis.provenance.provenance` of an evaluation: the model file of each policy
    (``pols`` starts with one policy per entry of ``models``; a further policy's ``source``
    file when it has one, as :func:`cf_policy`'s; None for baselines and models given as
    objects), the held-out and training demonstrations and scenario files read, and the SHA-256
    of the scenario actually simulated (its TOML)."""
    files = {p.name: None if isinstance(m, SavedModel) else m for p, m in zip(pols, models)}
    files.update({p.name: getattr(p, "source", "") or None for p in pols[len(models):]})
    scenario_file = scenario if isinstance(scenario, (str, Path)) and Path(scenario).is_file() else None
    demos_file = None if isinstance(demos, pd.DataFrame) else demos
    train_file = None if isinstance(train_demos, pd.DataFrame) else train_demos
    return provenance({"demos": demos_file, "train_demos": train_file, "scenario": scenario_file}, files,
                      extra={"scenario_sha256": text_digest(spec.to_toml())})


_BASELINES: dict[str, Callable[[], Policy]] = {"sumo": SumoPolicy, "uniform": UniformPolicy,
                                               "sumo-in-lane": lambda: SumoPolicy("sumo-in-lane", keep_lane=True)}


def _renamed(p: Policy, name: str) -> Policy:
    if not is_dataclass(p) or isinstance(p, type):
        raise PolicyError(f"evaluate: two policies are named {p.name!r} and {type(p).__name__} is not a "
                          "dataclass that could be renamed; give each policy a distinct name")
    return replace(p, name=name)
