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
"""

from __future__ import annotations

import os

from sim.drivers.formats import RewardFn, driver_reward

__all__ = ["load_reward"]


def load_reward(path: str | os.PathLike) -> RewardFn:
    """The environment's reward of a learned file, by its registered format.

    Raises:
        FileNotFoundError: no such file.
        irl.errors.ModelFileError: not a file with a reward (its format named), or malformed.
        PolicyError: a tabular model without bin edges or with mismatched features.
    """
    return driver_reward(path)
