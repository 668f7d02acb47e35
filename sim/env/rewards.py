"""Rewards of the merge environment (:mod:`sim.env`): a learned model's, or any function.

A reward is a callable ``reward(obs, action, acc_ft_s2) -> float`` of one decision: the
:class:`~sim.drivers.observe.MergeObservation` at the decision (its ``state`` is the discrete state
index of the reward's encoder), the action's bin (0..4, :data:`irl.domains.merge.actions.ACTION_NAMES`)
and the acceleration applied to A (ft/s^2). The environment returns it with the step that
applies the action.

* :class:`TabularReward`: ``theta . phi(s, a)`` of a saved tabular IRL model (``merge-irl learn``,
  :class:`irl.result.SavedModel`): its feature set on its own state bins and encoding.
* :class:`PlanningReward`: the planning driver's learned one-step reward
  (:meth:`irl.domains.merge.planning.driver.PlanningDriver.step_reward`), continuous in the
  observation and the acceleration.
* :func:`load_reward`: either, from its file (told apart by the file's ``format``).
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from irl.domains.merge.bins import MergeBins
from irl.domains.merge.features import feature_set
from irl.domains.merge.planning.driver import PLANNER_FORMAT, PlanningDriver
from irl.result import SavedModel
from sim.drivers.observe import MergeObservation
from sim.drivers.policy import PolicyError

#: ``reward(obs, action, acc_ft_s2) -> float``.
RewardFn = Callable[[MergeObservation, int, float], float]


@dataclass(frozen=True)
class TabularReward:
    """``r(s, a) = theta . phi(s, a)`` of a tabular model; ``phi`` is ``[S, 5, K]`` (the model's
    feature set on its bins, encoding, decision step and action accelerations).

    Attributes:
        theta: ``[K]`` weights; phi: ``[S, 5, K]``; encoder: the model's state bins;
        state_encoding: ``"paper"`` or ``"driver"``; action_acc_ft_s2: ``[5]`` the model's
        per-action accelerations (ft/s^2; the discrete actions apply them).
    """

    theta: np.ndarray
    phi: np.ndarray
    encoder: MergeBins
    state_encoding: str = "paper"
    action_acc_ft_s2: tuple[float, ...] = ()
    name: str = "tabular"
    _r: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "_r", np.einsum("sak,k->sa", self.phi, self.theta))

    @classmethod
    def from_model(cls, model: SavedModel) -> TabularReward:
        """From a saved merge model (its ``bin_edges``, ``feature_set`` or ``feature_names``).

        Raises:
            PolicyError: the model has no bin edges or its features do not match ``theta``.
        """
        if not model.bin_edges:
            raise PolicyError(f"model {model.method!r} has no 'bin_edges': its reward needs the state bins")
        bins = MergeBins.from_dict(dict(model.bin_edges), where=f"model {model.method!r} bin_edges")
        names = model.feature_names or model.feature_set or "paper"
        # as training built them (irl.problems): the model's step, the actions' nominal accelerations
        fs = feature_set(names, bins, model.state_encoding, decision_step_s=model.decision_step_s)
        theta = np.asarray(model.theta, dtype=np.float64)
        if fs.array.shape[-1] != theta.shape[0]:
            raise PolicyError(f"model {model.method!r}: theta has {theta.shape[0]} weights, its features "
                              f"{fs.names} {fs.array.shape[-1]}")
        return cls(theta, fs.array, bins, model.state_encoding, tuple(model.action_acc_ft_s2), model.method)

    def __call__(self, obs: MergeObservation, action: int, acc_ft_s2: float) -> float:
        if obs.state < 0:
            raise PolicyError("TabularReward: the observation has no state index (the environment encodes "
                              "states with this reward's encoder)")
        return float(self._r[obs.state, action])


@dataclass(frozen=True)
class PlanningReward:
    """The planning driver's learned reward of one decision step, ``theta . phi(x, acc)`` plus
    its collision penalty (:meth:`~irl.domains.merge.planning.driver.PlanningDriver.step_reward`)."""

    driver: PlanningDriver
    name: str = "planner"

    @property
    def action_acc_ft_s2(self) -> tuple[float, ...]:
        return self.driver.action_acc_ft_s2

    def __call__(self, obs: MergeObservation, action: int, acc_ft_s2: float) -> float:
        prev = obs.acc_prev if np.isfinite(obs.acc_prev) else 0.0
        return float(self.driver.step_reward(obs.continuous(), np.array([prev]), np.array([obs.acc_C]),
                                             np.array([acc_ft_s2]))[0])


def load_reward(path: str | os.PathLike) -> TabularReward | PlanningReward:
    """The reward of a model file: a planning driver (format ``merge-irl-planner/1``) or a tabular
    IRL model (``model.json`` of ``merge-irl learn``).

    Raises:
        FileNotFoundError: no such file.
        irl.errors.ModelFileError / PolicyError: not a model file with a reward (named).
    """
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"reward model file not found: {p}")
    try:
        fmt = json.loads(p.read_text(encoding="utf-8")).get("format", "")
    except (json.JSONDecodeError, UnicodeDecodeError, AttributeError):
        fmt = ""
    if fmt == PLANNER_FORMAT:
        return PlanningReward(PlanningDriver.load(p))
    if isinstance(fmt, str) and fmt.startswith("merge-irl-cf-logit"):
        raise PolicyError(f"{p}: a car-following logit file; the environment's rewards are a tabular IRL "
                          "model's or a planning driver's")
    return TabularReward.from_model(SavedModel.load(p))
