"""The environments' settings: :class:`MergeEnvConfig`, one frozen dataclass for
:class:`sim.env.merge_env.MergeEnv` and :class:`sim.env.multi_agent.MergeParallelEnv`.

The ecosystem's two conventions both work: keyword arguments of ``gym.make`` (Gymnasium's,
sumo-rl's) and a ``config`` mapping (HighwayEnv's ``config={...}``); keywords override the mapping::

    gym.make("MergeIRL/OnRampMerge-v0", action_type="continuous", units="si")
    gym.make("MergeIRL/OnRampMerge-v0", config={"reward": "progress", "run_s": 600.0})
    MergeEnv(config=MergeEnvConfig(run_s=600.0), reward=None)

Every field is checked when the config is built, before SUMO starts (``gym.make`` raises).
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, fields, replace
from typing import Any

from scenarios.spec.model import ScenarioSpec
from sim.closed_loop.config import ControllerConfig
from sim.drivers.formats import RewardFn
from sim.env.observations import DEFAULT_OBSERVATION, ObservationFactory, observation_factory
from sim.env.rewards import check_reward_name

#: ``units`` values: observations in feet and ft/s (NGSIM's, the project's) or metres and m/s.
UNITS = ("ft", "si")
ACTION_TYPES = ("discrete", "continuous")


@dataclass(frozen=True)
class MergeEnvConfig:
    """Settings of the merge environments (single- and multi-agent).

    Attributes:
        scenario: a preset name (``"synthetic"``, ``"i80"``), a TOML path or a
            :class:`~scenarios.spec.model.ScenarioSpec`.
        action_type: ``"discrete"`` (``Discrete(5)``, the merge actions) or ``"continuous"`` (A's
            acceleration in m/s^2, ``Box((1,))``).
        reward: a registered reward's name (:data:`sim.env.task_reward.TASK_REWARDS`: ``"task"``, the
            default, ``"progress"``, ``"zero"``, and those of :func:`sim.env.rewards.register_reward`),
            a learned model file (a path; a ``str`` with a directory part or a suffix, or that exists),
            a callable ``(obs, action_bin, acc_ft_s2) -> float`` (:class:`sim.env.rewards.Reward`) or None (0).
        controller: the closed-loop controller's settings (decision step, take-over zone, hold,
            time limit, ``high_brake``); its ``seed`` is unused (the agent decides).
        run_s: simulated seconds of one SUMO run, warm-up included (s).
        acc_bounds_mps2: the continuous action's bounds (m/s^2): (negative, positive).
        units: ``"ft"`` (observations in ft and ft/s, the default) or ``"si"`` (m and m/s; the same
            columns times 0.3048). Rewards and ``info`` stay as documented (``info`` has both
            ``acc_ft_s2`` and ``acc_mps2``).
        max_agents: the multi-agent environment's agent slots (``possible_agents``): at most this
            many lag cars are controlled at once; a take-over with every slot taken is left to
            SUMO. Unused by the single-agent environment.
        observation: what the agent sees, by name (:mod:`sim.env.observations`: ``"policy"``, the
            default, the 7 policy columns; a module of that folder; ``"module:Class"`` of your own;
            a name of :func:`~sim.env.observations.register_observation`) or a factory
            ``(config) -> Observation``.

    Raises:
        ValueError: an unknown ``action_type``, ``units``; bounds not (negative, positive) finite
            numbers; ``max_agents`` < 1.
        TypeError: ``reward`` neither a name, a path, a callable nor None; ``controller`` not a
            :class:`~sim.closed_loop.config.ControllerConfig`.
        merge_irl.registry.RegistryError: ``reward`` a string that is neither a registered name nor
            like a path (``"fast"``: the names listed); an unknown ``observation`` name (the names listed).
    """

    scenario: str | os.PathLike | ScenarioSpec = "synthetic"
    action_type: str = "discrete"
    reward: str | os.PathLike | RewardFn | None = "task"
    controller: ControllerConfig = ControllerConfig(decision_step_s=0.3)
    run_s: float = 1800.0
    acc_bounds_mps2: tuple[float, float] = (-9.0, 4.0)
    units: str = "ft"
    max_agents: int = 8
    observation: str | ObservationFactory = DEFAULT_OBSERVATION

    def __post_init__(self) -> None:
        if self.action_type not in ACTION_TYPES:
            raise ValueError(f"action_type must be 'discrete' or 'continuous', got {self.action_type!r}")
        if self.units not in UNITS:
            raise ValueError(f"units must be one of {UNITS}, got {self.units!r}")
        try:
            lo, hi = (float(x) for x in self.acc_bounds_mps2)
        except (TypeError, ValueError):
            lo = hi = math.nan
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < 0 < hi):
            raise ValueError(f"acc_bounds_mps2 must be (negative, positive) m/s^2, got {self.acc_bounds_mps2!r}")
        _check_reward(self.reward)
        if not isinstance(self.controller, ControllerConfig):
            raise TypeError(f"controller must be a sim.closed_loop.config.ControllerConfig, got "
                            f"{type(self.controller).__name__}")
        _check_observation(self.observation)
        if isinstance(self.max_agents, bool) or not isinstance(self.max_agents, int) or self.max_agents < 1:
            raise ValueError(f"max_agents must be an integer >= 1, got {self.max_agents!r}")

    @property
    def obs_scale(self) -> float:
        """Factor from the project's feet to the observation's unit (1 or 0.3048)."""
        return 1.0 if self.units == "ft" else 0.3048

    def to_dict(self) -> dict[str, Any]:
        """The fields as a dict (HighwayEnv's ``default_config()`` shape)."""
        return {f.name: getattr(self, f.name) for f in fields(self)}


def _check_reward(r: object) -> None:
    """``MergeEnvConfig.reward``: a name (known, or like a path), a path, a callable or None."""
    if not (r is None or isinstance(r, str | os.PathLike) or callable(r)):
        raise TypeError(f"reward must be a reward name, a model file path, a callable (obs, action_bin, "
                        f"acc_ft_s2) -> float or None, got {type(r).__name__} {r!r}")
    if isinstance(r, str):
        check_reward_name(r)  # a misspelled name is not read as a file


def _check_observation(o: object) -> None:
    """``MergeEnvConfig.observation``: a known name (the names listed otherwise) or a factory."""
    if isinstance(o, str):
        observation_factory(o)
    elif not callable(o):
        raise TypeError(f"observation must be a name or a factory (config) -> Observation, got {type(o).__name__}")


def resolve_config(config: MergeEnvConfig | Mapping[str, Any] | None, overrides: Mapping[str, Any]) -> MergeEnvConfig:
    """``config`` (a :class:`MergeEnvConfig`, a mapping of its fields, None: the defaults) with
    ``overrides`` (keyword arguments) on top.

    Raises:
        TypeError: ``config`` of another type, or a key that is no field (the fields named).
        ValueError, TypeError: a bad value (:class:`MergeEnvConfig`).
    """
    names = {f.name for f in fields(MergeEnvConfig)}
    extra = dict(config) if isinstance(config, Mapping) else {}
    if not (config is None or isinstance(config, MergeEnvConfig | Mapping)):
        raise TypeError(f"config must be a MergeEnvConfig or a mapping of its fields, got {type(config).__name__}")
    unknown = sorted((set(extra) | set(overrides)) - names)
    if unknown:
        raise TypeError(f"unknown environment setting(s) {unknown}; the settings are {sorted(names)}")
    base = config if isinstance(config, MergeEnvConfig) else MergeEnvConfig()
    return replace(base, **{**extra, **overrides})
