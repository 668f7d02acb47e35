"""Train a car-following logit driver on demonstrations plus SUMO-expert labels in the
safety-critical states the learned driver reaches (DAgger restricted to critical labels).

Round 0 fits :class:`irl.domains.merge.cf_logit.CarFollowingLogit` on the training
encounters. Each round then lets the latest driver drive the lag cars A of
``episodes_per_round`` SUMO runs of the scenario (seeds disjoint from any evaluation), asks
SUMO's car-following model of A's type for its action at every decision
(:class:`sim.merges.expert_labels.ExpertLabels`) and keeps the labels whose expert action is in
``critical_actions`` (default High Brake only): the states the demonstrations never cover,
where the driver closes in on a stopping lead car. The logit is refitted on the
demonstrations plus every kept label so far. Keeping only critical labels leaves the
demonstrations in charge elsewhere, so the held-out likelihood stays near round 0's; keeping
every label (``critical_actions`` all five) swamps them with the expert's car following, which
does not yield to the merging car as the demonstrators do (docs/closed-loop.md).

DAgger: Ross, Gordon & Bagnell (2011), AISTATS. The expert must be queryable in the learner's
states: here SUMO's own driver model, the model the synthetic demonstrators drive with; real
(NGSIM) demonstrations have no such expert.
"""

from __future__ import annotations

import math
import sys
import time
import warnings
from dataclasses import dataclass

import numpy as np
import pandas as pd

from analysis.errors import AnalysisError
from analysis.sweep import Task, resolve_executor, run_sweep
from irl.domains.merge.actions import N_ACTIONS
from irl.domains.merge.car_following import OBS_COLUMNS, CFDecisions, car_following_decisions
from irl.domains.merge.cf_logit import CarFollowingLogit
from irl.domains.merge.mdp import DEFAULT_DECISION_STEP_S
from irl.errors import ConfigError
from scenarios.errors import SpecError
from scenarios.loader import load_scenario
from scenarios.spec.model import ScenarioSpec
from scenarios.spec.parse import with_overrides
from sim.closed_loop.config import ControllerConfig
from sim.closed_loop.controller import Controller
from sim.drivers.learned import CarFollowingLogitPolicy
from sim.merges.expert_labels import ExpertLabel, ExpertLabels
from sim.runtime.run import run_scenario


@dataclass(frozen=True)
class DaggerConfig:
    """Settings of :func:`train_cf_driver`.

    Attributes:
        rounds: DAgger rounds (0: the logit on the demonstrations alone).
        episodes_per_round: SUMO runs the driver drives per round.
        label_seed: SUMO seed of round ``r``'s episode ``e``: ``label_seed + r x episodes_per_round + e``.
        duration_s: seconds per labelling run, warm-up included (None: from the scenario,
            :func:`labelling_duration_s`).
        l2: L2 penalty of every fit.
        critical_actions: expert actions whose labels are kept (0 = High Brake ... 4 = High Accel).
        decision_step_s: seconds per decision (demonstrations resampled so; the controller decides so).
    """

    rounds: int = 4
    episodes_per_round: int = 15
    label_seed: int = 500
    duration_s: float | None = None
    l2: float = 0.1
    critical_actions: tuple[int, ...] = (0,)
    decision_step_s: float = DEFAULT_DECISION_STEP_S

    def __post_init__(self) -> None:
        def whole(name: str, lowest: int) -> None:
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < lowest:
                raise ConfigError(f"DaggerConfig.{name} must be a whole number >= {lowest}, got {v!r}")

        whole("rounds", 0)
        whole("episodes_per_round", 1)
        whole("label_seed", 0)
        for name in ("duration_s", "decision_step_s"):
            v = getattr(self, name)
            if name == "duration_s" and v is None:
                continue
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
                raise ConfigError(f"DaggerConfig.{name} must be a positive finite number of seconds, got {v!r}")
        if isinstance(self.l2, bool) or not isinstance(self.l2, (int, float)) or not (math.isfinite(self.l2) and self.l2 >= 0):
            raise ConfigError(f"DaggerConfig.l2 must be a finite number >= 0, got {self.l2!r}")
        acts = self.critical_actions
        if not isinstance(acts, tuple) or not acts or any(
                isinstance(a, bool) or not isinstance(a, int) or not 0 <= a < N_ACTIONS for a in acts):
            raise ConfigError(f"DaggerConfig.critical_actions must be a non-empty tuple of actions 0..{N_ACTIONS - 1}, "
                              f"got {acts!r}")

    def label_seeds(self) -> range:
        """Every labelling run's seed (to keep them apart from evaluation seeds)."""
        return range(self.label_seed, self.label_seed + self.rounds * self.episodes_per_round)


#: Seconds recorded past the scenario's warm-up in a labelling run by default: the synthetic
#: scenario's 240 s (60 s warm-up) as before, for any scenario.
LABEL_RECORDED_S = 180.0


def labelling_duration_s(spec: ScenarioSpec, config: DaggerConfig) -> float:
    """Seconds per labelling run: ``config.duration_s`` when given, else the scenario's warm-up
    plus :data:`LABEL_RECORDED_S`, at most the scenario's own duration (synthetic: 240 s; i80,
    240 s of warm-up: 420 s).

    Raises:
        SpecError: a given ``duration_s`` not longer than the scenario's warm-up (naming it as the
            user gave it, ``--duration`` / ``DaggerConfig.duration_s``).
    """
    sim = spec.simulation
    default = min(sim.duration_s, sim.warmup_s + LABEL_RECORDED_S)
    if config.duration_s is None:
        return default
    if config.duration_s <= sim.warmup_s:
        raise SpecError(f"dagger --duration (DaggerConfig.duration_s) {config.duration_s:g} s: the labelling runs must "
                        f"be longer than scenario {spec.name}'s warm-up, simulation.warmup_s = {sim.warmup_s:g} s "
                        f"(leave it out for the scenario's: {default:g} s)")
    return float(config.duration_s)


@dataclass(frozen=True)
class LabelRun:
    """One labelling run as a sweep task config (:func:`label_run_task`): the driver ``model``
    drives the As of ``scenario`` (a ScenarioSpec) with SUMO seed ``seed``."""

    scenario: ScenarioSpec
    model: CarFollowingLogit
    seed: int
    duration_s: float
    decision_step_s: float


def label_run_task(run: LabelRun, seed: int) -> dict:
    """Sweep task: one SUMO run of :class:`LabelRun` with :class:`~sim.merges.expert_labels.ExpertLabels`;
    returns ``{"records": [[state, d_AC, v_AC, d_AB, v_AB, v_A, len_C, len_B, prev, action], ...]}``."""
    del seed  # the run's own SUMO seed, as every evaluation episode
    ctl = Controller(CarFollowingLogitPolicy(run.model), ControllerConfig(decision_step_s=run.decision_step_s))
    hook = ExpertLabels(ctl)
    run_scenario(run.scenario, seed=run.seed, duration_s=run.duration_s, hooks=[ctl, hook])
    return {"records": [list(r) for r in hook.records]}


def label_runs(model: CarFollowingLogit, spec: ScenarioSpec, seeds: list[int], config: DaggerConfig,
               executor: str, duration_s: float) -> pd.DataFrame:
    """The expert records (columns of :class:`~sim.merges.expert_labels.ExpertLabel`) of one labelling
    run per seed of ``duration_s`` seconds, in seed order, run by ``executor`` (``analysis.sweep``).

    Raises:
        AnalysisError: a run failed twice.
    """
    tasks = [Task(f"label/seed{s}", label_run_task, LabelRun(spec, model, int(s), duration_s,
                                                              config.decision_step_s)) for s in seeds]
    report = run_sweep(tasks, seed=0, executor=executor, progress=False, desc="labelling runs")
    if not report.ok:
        raise AnalysisError("labelling runs failed: " + "; ".join(f"{f.key}: {f.error}" for f in report.failures))
    rows = [r for t in tasks for r in report.results[t.key]["records"]]
    return pd.DataFrame(rows, columns=list(ExpertLabel._fields))


def labels_as_decisions(table: pd.DataFrame, demos: CFDecisions) -> CFDecisions:
    """Expert label records (:meth:`sim.merges.expert_labels.ExpertLabels.table`) as decisions with
    the demonstrations' action accelerations and step."""
    obs = table[list(OBS_COLUMNS)].to_numpy(dtype=np.float64).reshape(-1, len(OBS_COLUMNS))
    return CFDecisions(obs, table["prev"].to_numpy(dtype=np.int64), table["action"].to_numpy(dtype=np.int64),
                       demos.action_acc_ft_s2, demos.decision_step_s)


class NotConvergedWarning(UserWarning):
    """A car-following logit fit did not converge (its ``converged`` is False)."""


def train_cf_driver(train_encounters: pd.DataFrame, scenario, config: DaggerConfig = DaggerConfig(), *,
                    workers: int | None = None, executor: str | None = None, where: str = "training encounters",
                    progress: bool = True) -> list[CarFollowingLogit]:
    """The driver of every round, round 0 first (module docstring); the last is the result.

    Args:
        train_encounters: encounter table with a ``v_A`` column (the demonstrations).
        scenario: preset name, TOML path or ScenarioSpec of the labelling runs (the one the
            demonstrations came from).
        config: :class:`DaggerConfig`.
        workers, executor: where the labelling runs run (:func:`analysis.evaluation.run.run_episodes`'
            meaning: default every core, one SUMO per worker process); the results do not
            depend on it (each run has its own seed).
        where: how errors name the encounters (e.g. their file).
        progress: print one line per round to stderr.

    A fit that does not converge is kept (``converged`` False in its file) and warned about
    with a :class:`NotConvergedWarning`.

    Raises:
        DemonstrationError: the encounters cannot be resampled or lack ``v_A``.
        ScenarioError / AnalysisError: the scenario cannot be loaded, a labelling run's seed or
            duration is invalid for it (checked before any work), or a run fails.
    """
    spec = scenario if isinstance(scenario, ScenarioSpec) else load_scenario(scenario)
    executor = resolve_executor(executor, workers)
    seeds = config.label_seeds()
    duration_s = labelling_duration_s(spec, config)
    for seed in {seeds[0], seeds[-1]} if len(seeds) else ():  # the labelling runs' overrides, before any work
        with_overrides(spec, seed=seed, duration_s=duration_s)
    demos = car_following_decisions(train_encounters, decision_step_s=config.decision_step_s, where=where)
    models = [CarFollowingLogit.fit(demos, l2=config.l2, info={"dagger_round": 0, "labels_per_round": []})]
    if not models[0].converged:
        warnings.warn("DAgger round 0: the logit fit on the demonstrations did not converge", NotConvergedWarning,
                      stacklevel=2)
    kept: list[pd.DataFrame] = []
    per_round: list[int] = []
    k = config.episodes_per_round
    for r in range(config.rounds):
        t0 = time.perf_counter()
        table = label_runs(models[-1], spec, list(seeds[r * k:(r + 1) * k]), config, executor, duration_s)
        critical = table[table["action"].isin(config.critical_actions)]
        kept.append(critical)
        per_round.append(len(critical))
        labels = labels_as_decisions(pd.concat(kept, ignore_index=True), demos)
        models.append(CarFollowingLogit.fit(
            demos, l2=config.l2, labels=labels,
            info={"dagger_round": r + 1, "labels_per_round": list(per_round),
                  "critical_actions": list(config.critical_actions), "label_seed": config.label_seed,
                  "episodes_per_round": config.episodes_per_round}))
        if not models[-1].converged:
            warnings.warn(f"DAgger round {r + 1}: the logit fit did not converge", NotConvergedWarning, stacklevel=2)
        if progress:
            print(f"DAgger round {r + 1}/{config.rounds}: {len(table)} decisions, {len(critical)} critical labels "
                  f"kept, training LL/step {models[-1].loglik / demos.n:.3f}, {time.perf_counter() - t0:.0f} s",
                  file=sys.stderr, flush=True)
    return models
