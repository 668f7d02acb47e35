"""What a closed-loop evaluation is asked to do: :class:`EvaluationConfig`.

A config is inert (nothing is read when it is made); :func:`analysis.evaluation.plan.plan_evaluation`
reads and checks it. Example::

    from analysis.evaluation.config import EvaluationConfig

    cfg = EvaluationConfig("synthetic", episodes=4, seed=1, out_dir="runs/eval",
                           drivers=("runs/demo/models/qavg.json", "idm"))
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Union

import pandas as pd

from analysis.evaluation.metrics import MetricsConfig
from irl.result import SavedModel
from sim.closed_loop.config import ControllerConfig
from sim.drivers.policy import Policy

#: One driver of an evaluation (:mod:`analysis.evaluation.driver_specs`): a learned file of any
#: registered format (:mod:`sim.drivers.formats`), a baseline name (:data:`sim.drivers.baselines.BASELINES`),
#: a :class:`~irl.result.SavedModel`, a :class:`~sim.drivers.policy.Policy`, or a callable
#: ``obs -> action`` (wrapped as a :class:`sim.drivers.callables.CallablePolicy`).
DriverSpec = Union[str, "os.PathLike[str]", SavedModel, Policy, Callable[..., Any]]
#: Encounters given as a file (Parquet/CSV) or a table.
Encounters = Union[str, "os.PathLike[str]", pd.DataFrame, None]
#: Held-out encounters: one table, or several paths read as one set.
HeldOutEncounters = Union[Encounters, tuple[Union[str, "os.PathLike[str]"], ...]]  # noqa: UP007 (a runtime alias: "X | Y" cannot hold the quoted name)


@dataclass(frozen=True)
class EvaluationConfig:
    """A closed-loop evaluation: every driver over ``episodes`` seeds ``seed .. seed + episodes - 1``.

    Attributes:
        scenario: preset name, TOML path or ``ScenarioSpec``.
        episodes: episodes per driver (>= 1, checked by the plan).
        seed: first seed; episode i uses ``seed + i`` for every driver (the same traffic).
        out_dir: output folder (made by :func:`~analysis.evaluation.run.run_plan`).
        drivers: driver specs (:data:`DriverSpec`), in order; a tabular IRL model's file or a
            ``SavedModel`` is a *model* (listed first in the report, its bins feed the fitted
            baselines, its decision step is the default); a baseline name adds that baseline.
        baselines: names of :data:`sim.drivers.baselines.BASELINES`; None: its default set
            (:func:`~sim.drivers.baselines.default_baselines`: ``sumo``, ``uniform``, ``marginal``,
            ``markov``, ``bc``); ``idm``, ``sumo-in-lane`` and registered ones on request. The
            fitted ones (``marginal``, ``markov``, ``bc``) are left out, and said so in report.md,
            without ``train_demos``.
        duration_s: simulated seconds per episode; None: the scenario's.
        demos: held-out encounters (action divergence, held-out log-likelihood, W1), a table or a
            tuple of paths read as one set; None: NaN.
        train_demos: training encounters of the fitted baselines (``marginal``, ``markov``, ``bc``).
        controller: the controller; ``decision_step_s`` None is fixed by the plan.
        metrics: the metric settings.
        workers: processes (shorthand for ``executor="process:<workers>"``); None with
            ``executor`` None: every core (the same default as ``merge-irl evaluate``).
        executor: ``serial``, ``process[:N]``, ``dask-local[:N]`` or ``dask://HOST:PORT``;
            overrides ``workers``.
        rrd: write a rerun recording of each driver's first episode.
        progress: show a progress bar.
        allow_implausible: run a scenario (and ``duration_s``) outside the plausibility bounds.
        pairs: a folder of recorded car-following pairs (:func:`analysis.calibration.pairs.load_pairs`,
            e.g. NGSIM I-80): the ``recorded drivers`` row of the human-likeness table and every
            driver's W1 distances to it (:mod:`analysis.evaluation.recorded`); None: no such row.
        policy_weights: files the callable policies (``--policy``) load, e.g. a Stable-Baselines3
            ``.zip``: their SHA-256 goes into the provenance (``policy_files``) of every callable
            policy, with its ``VecNormalize`` statistics file.
    """

    scenario: Any
    episodes: int
    seed: int
    out_dir: str | os.PathLike[str]
    drivers: tuple[DriverSpec, ...] = ()
    baselines: tuple[str, ...] | None = None
    duration_s: float | None = None
    demos: HeldOutEncounters = None
    train_demos: Encounters = None
    controller: ControllerConfig = ControllerConfig()
    metrics: MetricsConfig = MetricsConfig()
    workers: int | None = None
    executor: str | None = None
    rrd: bool = True
    progress: bool = True
    allow_implausible: bool = False
    pairs: str | os.PathLike[str] | None = None
    policy_weights: tuple[str | os.PathLike[str], ...] = ()

    def __post_init__(self) -> None:
        # one spec given alone (a path, a SavedModel, a driver) is a list of one, not a string's
        # characters; a list becomes the tuple the field holds
        drivers = self.drivers
        if isinstance(drivers, (str, os.PathLike)) or not isinstance(drivers, (tuple, list)):
            drivers = (drivers,)
        object.__setattr__(self, "drivers", tuple(drivers))
