"""Rewards of the merge environment (:mod:`sim.env`): a learned file's, or any function.

A reward is a callable ``reward(obs, action, acc_ft_s2) -> float`` of one decision
(:data:`sim.drivers.formats.RewardFn`): the :class:`~sim.drivers.observe.MergeObservation` at the
decision (its ``state`` is the discrete state index of the reward's ``encoder``, when it has one),
the action's bin (0..4, :data:`irl.domains.merge.actions.ACTION_NAMES`) and the acceleration
applied to A (ft/s^2). The environment returns it with the step that applies the action.

:func:`load_reward` reads a learned file through the driver-format registry
(:func:`sim.drivers.formats.driver_reward`): a tabular IRL model gives
:class:`~sim.drivers.learned.TabularReward` (``theta . phi(s, a)`` on its own bins and
encoding), a planning driver :class:`~sim.drivers.planning.PlanningReward` (its learned one-step
reward, continuous in the observation and the acceleration), a registered format its own.
Optional members of a reward, read when present: ``encoder`` and ``state_encoding`` (the
environment encodes the observation's state with them), ``action_acc_ft_s2`` (``[5]`` ft/s^2, the
discrete actions' accelerations).

What the environment reads of a reward is typed here: :class:`Reward` (the call, required),
:class:`RewardWithTerms` (``terms``: the decision's named terms, ``info["rewards"]``),
:class:`RewardWithOutcome` (``outcome``: added to the episode's last step),
:class:`RewardOverStates` (``encoder``, ``state_encoding``) and
:class:`RewardWithActionAccelerations` (``action_acc_ft_s2``); :func:`reward_parts` reads them,
with their defaults, in one place. :func:`reward_value` checks every value a reward
returns where it enters the environment, and :func:`register_reward` adds a reward by name.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import numpy as np

from sim.drivers.formats import RewardFn, driver_reward
from sim.drivers.observe import MergeObservation
from sim.env.task_reward import TASK_REWARDS
from sim.errors import RewardError

__all__ = ["Reward", "RewardOverStates", "RewardParts", "RewardWithActionAccelerations", "RewardWithOutcome",
           "RewardWithTerms", "build_reward", "load_reward", "looks_like_path", "register_reward", "reward_parts",
           "reward_value"]


@runtime_checkable
class Reward(Protocol):
    """A reward of one decision: ``reward(obs, action_bin, acc_ft_s2) -> float`` (module
    docstring). Its value must be one finite real number (:func:`reward_value`)."""

    def __call__(self, obs: MergeObservation, action_bin: int, acc_ft_s2: float) -> float: ...


@runtime_checkable
class RewardWithTerms(Protocol):
    """A reward that names its terms: ``terms(obs, action_bin, acc_ft_s2) -> {name: value}``,
    which should add up to its call (the environment returns them in ``info["rewards"]``)."""

    def terms(self, obs: MergeObservation, action_bin: int, acc_ft_s2: float) -> Mapping[str, float]: ...


@runtime_checkable
class RewardWithOutcome(Protocol):
    """A reward with a term for how the episode ended, added to its last step (``"outcome"`` in
    ``info["rewards"]``)."""

    def outcome(self, reason: str, collision_kind: str = "") -> float: ...


@runtime_checkable
class RewardOverStates(Protocol):
    """A reward over discrete states (a tabular model's): the environment encodes each decision's
    state with its ``encoder`` (:class:`~irl.domains.merge.bins.MergeBins`) and ``state_encoding``
    (``"paper"`` or ``"driver"``), and ``info["state"]`` is that index."""

    encoder: Any
    state_encoding: str


@runtime_checkable
class RewardWithActionAccelerations(Protocol):
    """A reward that brings the discrete actions' accelerations (``[5]`` ft/s^2), which the
    environment applies for ``Discrete(5)`` actions."""

    action_acc_ft_s2: tuple[float, ...]


@dataclass(frozen=True)
class RewardParts:
    """What the environment reads of a reward, its optional members resolved once.

    Attributes:
        fn: the reward (None: 0 at every step).
        name: how messages name it (the ``reward=`` name or path, else the callable's name).
        terms, outcome: the bound members (:class:`RewardWithTerms`, :class:`RewardWithOutcome`) or None.
        encoder: the bins its states are encoded with (a tabular reward's), or None.
        state_encoding: ``"paper"`` or ``"driver"`` (the encoder's), else ``"paper"``.
        action_acc_ft_s2: ``[5]`` the discrete actions' accelerations (ft/s^2), or ``()``.
    """

    fn: RewardFn | None
    name: str
    terms: Any = None
    outcome: Any = None
    encoder: Any = None
    state_encoding: str = "paper"
    action_acc_ft_s2: tuple[float, ...] = ()


def reward_parts(fn: RewardFn | None, name: str) -> RewardParts:
    """The :class:`RewardParts` of ``fn`` (its optional members read here, nowhere else)."""
    if fn is None:
        return RewardParts(None, name)
    parts = RewardParts(fn, name, terms=fn.terms if isinstance(fn, RewardWithTerms) else None,
                        outcome=fn.outcome if isinstance(fn, RewardWithOutcome) else None)
    if isinstance(fn, RewardOverStates):
        parts = replace(parts, encoder=fn.encoder, state_encoding=str(fn.state_encoding or "paper"))
    if isinstance(fn, RewardWithActionAccelerations):
        parts = replace(parts, action_acc_ft_s2=tuple(float(x) for x in (fn.action_acc_ft_s2 or ())))
    return parts


def reward_value(value: object, where: str) -> float:
    """``value`` as a float when it is one finite real number: a Python ``int`` or ``float`` or a
    numpy integer or floating scalar. A bool (a flag returned by mistake), a string ('0.5'), None,
    an array of any shape (one element too: a batch where one number is due) are refused.

    Raises:
        sim.errors.RewardError: anything else, or NaN or an infinity; the message starts with
            ``where`` (the reward and the environment).
    """
    if isinstance(value, bool | np.bool_) or not isinstance(value, int | float | np.integer | np.floating):
        shown = repr(value) if len(repr(value)) <= 60 else repr(value)[:57] + "..."
        raise RewardError(f"{where} returned {type(value).__name__} {shown}; a reward must be one finite real "
                          "number (int or float; not bool, str, None or an array)")
    v = float(value)
    if not math.isfinite(v):
        raise RewardError(f"{where} returned {v}; a reward must be finite")
    return v


def looks_like_path(text: str) -> bool:
    """Whether a ``reward=`` string is meant as a file: it has a directory part or a suffix
    (``model.json``, ``runs/x``), or such a file exists. A bare word (``"fast"``) is a name."""
    seps = {"/", os.sep, os.altsep or "/"}
    return any(sep in text for sep in seps) or bool(Path(text).suffix) or Path(text).exists()


def build_reward(reward: str | os.PathLike | RewardFn | None) -> RewardFn | None:
    """The reward of ``MergeEnvConfig.reward``: a registered name (:data:`~sim.env.task_reward.TASK_REWARDS`),
    a model file (a path, or a string that :func:`looks_like_path`), a callable, or None.

    Raises:
        merge_irl.registry.RegistryError: a string that is neither a name nor a path (the names listed).
        FileNotFoundError, irl.errors.ModelFileError, PolicyError: as :func:`load_reward`.
    """
    if isinstance(reward, str) and reward in TASK_REWARDS:
        return TASK_REWARDS[reward]
    if isinstance(reward, str):
        check_reward_name(reward)
    if isinstance(reward, str | os.PathLike):
        return load_reward(Path(reward))
    return reward


def check_reward_name(reward: str) -> None:
    """Refuse a ``reward=`` string that is neither a registered name nor like a path.

    Raises:
        merge_irl.registry.RegistryError: one line, the known names listed.
    """
    if reward not in TASK_REWARDS and not looks_like_path(reward):
        raise TASK_REWARDS.error(f"unknown reward {reward!r}; known: {', '.join(TASK_REWARDS)} (a model file is "
                                 f"given as a path, e.g. ./{reward}.json)")


def register_reward(name: str, fn: RewardFn, *, replace: bool = False) -> None:
    """Make ``fn`` (a :class:`Reward`) selectable as ``reward=name`` in every environment made after.

    Raises:
        TypeError: ``fn`` not callable.
        merge_irl.registry.RegistryError: an empty name, or one registered already (not ``replace``).
    """
    if not callable(fn):
        raise TypeError(f"register_reward({name!r}, ...): a reward must be a callable (obs, action_bin, acc_ft_s2) "
                        f"-> float, got {type(fn).__name__}")
    TASK_REWARDS.register(name, fn, replace=replace)


def load_reward(path: str | os.PathLike) -> RewardFn:
    """The environment's reward of a learned file, by its registered format.

    Raises:
        FileNotFoundError: no such file.
        irl.errors.ModelFileError: not a file with a reward (its format named), or malformed.
        PolicyError: a tabular model without bin edges or with mismatched features.
    """
    return driver_reward(path)
