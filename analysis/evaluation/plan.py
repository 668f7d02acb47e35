"""Plan a closed-loop evaluation: every input read and checked before anything is written.

:func:`plan_evaluation` turns an :class:`~analysis.evaluation.config.EvaluationConfig` into an
:class:`EvaluationPlan`: the scenario loaded, the drivers resolved, named and checked, the decision
step fixed, the held-out scores taken and the executor resolved, once. Nothing is written and
no episode runs; :func:`analysis.evaluation.run.run_plan` runs the plan and
:func:`analysis.evaluation.outcome.write_report` writes its report. Example::

    plan = plan_evaluation(EvaluationConfig("synthetic", 2, 0, "runs/eval", drivers=("model.json",)))
    print([p.name for p in plan.policies], plan.controller.decision_step_s, plan.executor)
"""

from __future__ import annotations

import math
import os
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import pandas as pd

from analysis.calibration.pairs import load_pairs
from analysis.errors import AnalysisError
from analysis.evaluation.config import EvaluationConfig
from analysis.evaluation.driver_specs import resolve_driver_specs
from analysis.evaluation.heldout_scoring import HeldOut, load_heldout, policy_heldout_loglik
from analysis.evaluation.policies import check_picklable, check_unambiguous, with_distinct_names
from analysis.evaluation.recorded import RecordedDrivers, recorded_drivers
from analysis.sweep import resolve_executor
from irl.domains.merge.mdp import DEFAULT_DECISION_STEP_S, frames_per_step
from irl.errors import ConfigError
from merge_irl.provenance import provenance, text_digest
from merge_irl.units import FRAME_S
from scenarios.errors import SpecError
from scenarios.loader import load_scenario
from scenarios.spec.parse import with_overrides
from sim.closed_loop.config import ControllerConfig
from sim.drivers.baselines import baseline_drivers, check_baselines, default_baselines
from sim.drivers.policy import Policy, check_policy


class DecisionStepWarning(UserWarning):
    """A policy is driven at another decision step than the one it was trained at."""


@dataclass(frozen=True)
class EvaluationPlan:
    """A checked evaluation, ready to run (:func:`plan_evaluation`).

    Attributes:
        config: the config it was planned from.
        spec: the scenario simulated (``ScenarioSpec``).
        policies: every driver in report order (models, baselines, then the others), names distinct.
        baselines: the baseline names asked for (some may be left out without training encounters).
        controller: ``config.controller`` with the decision step fixed.
        executor: the resolved executor spec (``process:2``, ``serial``, ...).
        heldout: the held-out encounters, or None without ``demos``.
        scores: policy name -> held-out log-likelihood ``(sum, per step)``, or None without ``demos``.
        provenance: the provenance record of the inputs (:func:`evaluation_provenance`).
        recorded: the recorded drivers' distributions of ``config.pairs``, at the decision step
            (:func:`analysis.evaluation.recorded.recorded_drivers`), or None without ``pairs``.
    """

    config: EvaluationConfig
    spec: Any
    policies: tuple[Policy, ...]
    baselines: tuple[str, ...]
    controller: ControllerConfig
    executor: str
    heldout: HeldOut | None = field(repr=False)
    scores: Mapping[str, tuple[float, float] | None] = field(repr=False)
    provenance: Mapping[str, Any] = field(repr=False)
    recorded: RecordedDrivers | None = field(default=None, repr=False)

    @property
    def out_dir(self) -> Path:
        """The output folder (not made by planning)."""
        return Path(self.config.out_dir)


def plan_evaluation(config: EvaluationConfig) -> EvaluationPlan:
    """Read and check every input of ``config``; nothing is written, no episode runs.

    Warns:
        DecisionStepWarning: a driver is driven at another decision step than its own.

    Raises:
        SpecError: the scenario cannot be loaded, or ``duration_s`` is invalid or implausible for it.
        AnalysisError: ``episodes`` < 1, a decision step that is not a positive multiple of the
            0.1 s simulation step, or an executor spec that does not parse.
        SimError: an unknown baseline name.
        PolicyError: a model is not a merge model, a policy lacks a member of
            :class:`sim.drivers.policy.Policy`, two policies share a name and one of them is not a
            dataclass that can be renamed, a driver is named as another of different origin, or a
            policy cannot be pickled for the executor's workers.
        ModelFileError: a driver file is missing, malformed or of no registered format.
        DemonstrationError: the held-out or training encounters cannot be read, lack columns, or
            cannot be scored.
        SpecError: ``pairs`` is not a folder of valid pair CSVs (the folder or file named).
    """
    if config.episodes < 1:
        raise AnalysisError(f"evaluate: episodes must be >= 1, got {config.episodes}")
    spec = _scenario(config)
    baselines = tuple(default_baselines() if config.baselines is None else config.baselines)
    check_baselines(baselines)
    resolved = resolve_driver_specs(config.drivers)
    baselines += tuple(b for b in resolved.baselines if b not in baselines)
    others = [d.policy for d in resolved.others]
    for p in others:
        check_policy(p, scoring=config.demos is not None, where="evaluate")
    models = [d.policy for d in resolved.models]
    controller = _fixed_step(config.controller, models + others)
    step = float(controller.decision_step_s)  # type: ignore[arg-type]
    recorded = _recorded(config.pairs, step, config.metrics.close_gap_m) if config.pairs is not None else None
    base = baseline_drivers(baselines, spec, config.train_demos, models[0].encoder if models else None, step)
    check_unambiguous(others, models + base)  # a --policy named 'sumo' beside the baseline: refused, not 'sumo-2'
    files = [d.file for d in resolved.models] + [None] * len(base) + [d.file for d in resolved.others]
    pols = with_distinct_names(models + base + others)
    executor = resolve_executor(config.executor, config.workers)
    check_picklable(pols, executor)  # a lambda: now, named, not as a raw pickling error
    held = load_heldout(config.demos) if config.demos is not None else None
    # the held-out scores do not depend on the episodes: taken first, so a held-out table that a
    # policy's scoring rejects fails before any SUMO run
    shared: dict = {}  # what several policies' held-out scoring shares (Policy.heldout_inputs)
    scores = {p.name: policy_heldout_loglik(p, held, step, cache=shared) if held is not None else None for p in pols}
    # the files as read, before the work: a driver's file, else its source (a callable's module), else None
    prov = evaluation_provenance({p.name: f or p.source or None for p, f in zip(pols, files)}, config, spec,
                                 policy_files=policy_files(pols, config.policy_weights))
    return EvaluationPlan(config, spec, tuple(pols), baselines, controller, executor, held, scores, prov, recorded)


def _recorded(pairs, step: float, close_gap_m: float) -> RecordedDrivers:
    """The recorded drivers of the ``pairs`` folder at ``step`` s.

    Raises:
        SpecError: the folder is missing, a file, empty of pair CSVs, or holds an invalid pair.
    """
    try:
        loaded = load_pairs(pairs)
    except FileNotFoundError:
        raise SpecError(f"evaluate: --pairs {pairs}: no such folder (a folder of recorded pair CSVs)") from None
    return recorded_drivers(loaded, step, source=str(pairs), gap_m=close_gap_m)


def _scenario(config: EvaluationConfig):
    scenario = config.scenario
    if isinstance(scenario, (str, Path)):
        spec = load_scenario(scenario, allow_implausible=config.allow_implausible)
    else:
        spec = replace(scenario, allow_implausible=True) if config.allow_implausible else scenario
    if config.duration_s is not None:
        with_overrides(spec, duration_s=config.duration_s)  # a duration the scenario rejects: now, not per episode
    return spec


def _fixed_step(controller: ControllerConfig, pols: list[Policy]) -> ControllerConfig:
    """``controller`` with ``decision_step_s`` fixed: its own, else the first of ``pols`` with a
    step of its own, else the default; warns for every driver trained at another step."""
    steps = [(p.name, float(s)) for p in pols if (s := p.decision_step_s) is not None]
    step = controller.decision_step_s
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
            f"{name} was trained at {s} s" for name, s in other), DecisionStepWarning, stacklevel=4)
    return controller


def policy_files(pols: Sequence[Any], weights: Sequence[str | os.PathLike]) -> dict[str, dict[str, Any]]:
    """Policy name -> role -> file, of the files each callable policy (one with ``obs_stats``,
    :class:`sim.drivers.callables.DriverFromCallable`) loads: ``weights`` (``weights1``,
    ``weights2``, ... when several) and its ``vecnormalize`` statistics; other policies: none."""
    roles = {"weights": weights[0]} if len(weights) == 1 else {f"weights{i}": w for i, w in enumerate(weights, 1)}
    out: dict[str, dict[str, Any]] = {}
    for p in pols:
        if not hasattr(p, "obs_stats"):
            continue
        files = {**roles, **({"vecnormalize": p.obs_stats} if p.obs_stats else {})}
        if files:
            out[p.name] = files
    return out


def evaluation_provenance(files: Mapping[str, Any], config: EvaluationConfig, spec, *,
                          policy_files: Mapping[str, Mapping[str, Any]] | None = None) -> dict:
    """:func:`merge_irl.provenance.provenance` of an evaluation: each policy's file (``files``),
    the files a callable policy loads (``policy_files``: :func:`policy_files`), the held-out and
    training demonstrations, pairs folder and scenario files read, and the SHA-256 of the
    scenario actually simulated (its TOML)."""
    scenario = config.scenario
    scenario_file = scenario if isinstance(scenario, (str, Path)) and Path(scenario).is_file() else None
    demos = config.demos
    held = {f"demos{i}": p for i, p in enumerate(demos, start=1)} if isinstance(demos, tuple) and len(demos) > 1 \
        else {"demos": demos[0] if isinstance(demos, tuple) else None if isinstance(demos, pd.DataFrame) else demos}
    train_file = None if isinstance(config.train_demos, pd.DataFrame) else config.train_demos
    inputs = {**held, "train_demos": train_file, "scenario": scenario_file, "pairs": config.pairs}
    return provenance(inputs, dict(files), policy_files=policy_files,
                      extra={"scenario_sha256": text_digest(spec.to_toml())})
