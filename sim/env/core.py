"""What the single- and the multi-agent environment share: the spaces, the reward, the actions
checked and applied through the controller, the SUMO run they step (:class:`EnvCore`).

One :class:`EnvCore` per environment, built from its :class:`~sim.env.config.MergeEnvConfig`;
the environments hold the episode bookkeeping (one control, or one per agent).
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from gymnasium import spaces

from irl.domains.merge.actions import ACTION_ACC_FT_S2, N_ACTIONS, action_of
from irl.domains.merge.bins import MergeBins
from merge_irl.units import FT_PER_M, M_PER_FT
from sim.closed_loop.controller import Controller
from sim.closed_loop.records import Control
from sim.drivers.formats import RewardFn
from sim.drivers.observe import MergeObservation, lead_of
from sim.drivers.policy import NO_LIKELIHOOD, PolicyDefaults
from sim.env.config import MergeEnvConfig
from sim.env.observations import make_observation
from sim.env.rewards import build_reward, reward_parts, reward_value
from sim.errors import ObservationError, RewardError
from sim.runtime.hooks import FrameState
from sim.runtime.session import SumoSession

#: The release reason of a controlled car that vanished between two ``step`` calls (removed by
#: another TraCI client, a co-simulation or the user's code, not by SUMO during a step).
REMOVED_EXTERNALLY = "removed_externally"
#: Release reasons that truncate an episode (a time limit, or the car taken away from outside
#: the task); every other one terminates it.
TRUNCATING_REASONS = frozenset({"timeout", "end_of_run", REMOVED_EXTERNALLY})
_EYE = np.eye(N_ACTIONS)


class AgentPolicy(PolicyDefaults):
    """The controller's driver while the agent drives: its state encoder and action
    accelerations; it never decides (the environment does)."""

    name = "agent"
    controls = True
    decision_step_s = None

    def __init__(self, encoder: MergeBins, state_encoding: str, action_acc_ft_s2: tuple[float, ...]):
        self.encoder = encoder
        self.state_encoding = state_encoding
        self.action_acc_ft_s2 = action_acc_ft_s2

    def probs(self, obs: MergeObservation) -> np.ndarray:
        return np.full(N_ACTIONS, 1.0 / N_ACTIONS)

    def heldout_loglik(self, encounters: Any, *, decision_step_s: float, where: str) -> tuple[float, float]:
        return NO_LIKELIHOOD


def reward_name(reward: str | os.PathLike | RewardFn | None) -> str:
    """How messages name ``MergeEnvConfig.reward``: its name or path, else the callable's name."""
    if reward is None or isinstance(reward, str | os.PathLike):
        return str(reward)
    return str(getattr(reward, "__qualname__", None) or type(reward).__name__)


class EnvCore:
    """Spaces, reward and actions of an environment of ``config`` (the scenario loaded and
    ``run_s`` checked against it now: :class:`scenarios.errors.SpecError` at construction)."""

    def __init__(self, config: MergeEnvConfig):
        from scenarios.spec.model import ScenarioSpec
        from scenarios.spec.parse import with_overrides

        self.config = config
        if isinstance(config.scenario, ScenarioSpec):
            self.spec = config.scenario
        else:
            from scenarios.loader import load_scenario

            self.spec = load_scenario(config.scenario if isinstance(config.scenario, str) else Path(config.scenario))
        with_overrides(self.spec, duration_s=config.run_s)  # refuse a bad run_s now, not at the first reset
        self.reward_fn = build_reward(config.reward)
        self.reward = reward_parts(self.reward_fn, reward_name(config.reward))
        self.outcome_fn = self.reward.outcome
        #: how a reward's error names it and the environment
        self.reward_where = f"reward {self.reward.name!r} of MergeEnv (scenario {self.spec.name!r})"
        # a reward over discrete states (a tabular model's) brings the bins to encode them with
        encoder = self.reward.encoder or MergeBins.assumed_authors()
        acc5 = self.reward.action_acc_ft_s2 or ACTION_ACC_FT_S2
        self.agent = AgentPolicy(encoder, self.reward.state_encoding, tuple(float(x) for x in acc5))
        self.scale = config.obs_scale
        #: what the agent sees (:mod:`sim.env.observations`, ``config.observation``)
        self.observer = make_observation(config)
        self.observation_space = self.observer.space()
        lo, hi = (float(x) for x in config.acc_bounds_mps2)
        self.action_space: spaces.Space[Any] = (
            spaces.Discrete(N_ACTIONS) if config.action_type == "discrete"
            else spaces.Box(np.float32(lo), np.float32(hi), shape=(1,), dtype=np.float32))
        self._acc_bounds = (lo, hi)

    def observation(self, obs: MergeObservation) -> np.ndarray:
        """The agent's observation of ``obs`` (the config's :class:`~sim.env.observations.Observation`;
        by default the policy observation ``[7]`` in the config's units), a new array.

        Raises:
            sim.errors.ObservationError: ``observe`` returned no array of its space's shape (the
                observation named).
        """
        o = self.observer.observe(obs)
        shape = self.observation_space.shape
        if not isinstance(o, np.ndarray) or (shape is not None and o.shape != shape):
            got = f"shape {o.shape}" if isinstance(o, np.ndarray) else type(o).__name__
            raise ObservationError(f"observation {self.config.observation!r} returned {got}; its space() has "
                                   f"shape {shape} (return a numpy array of that shape)")
        return o

    def start(self, seed: int) -> tuple[SumoSession, Controller]:
        """A new SUMO run of ``seed`` started, and its controller (the agent's)."""
        session = SumoSession(self.spec, seed, duration_s=self.config.run_s, record=False)
        ctl = Controller(self.agent, self.config.controller)
        try:
            ctl.on_start(session.start())
        except BaseException:
            session.close()
            raise
        return session, ctl

    def parse_action(self, action: Any) -> tuple[int, float | None]:
        """``(bin, acc_ft_s2)`` of an action of the action space (``acc_ft_s2`` None for a discrete one).

        Raises:
            ValueError: discrete: not one integer 0..4 (a bool or a fractional number included);
                continuous: not one finite number.
        """
        arr = np.asarray(action)
        if self.config.action_type == "discrete":
            if (arr.size != 1 or arr.dtype.kind not in "iuf"
                    or (arr.dtype.kind == "f" and not float(arr.item()).is_integer())):
                raise ValueError(f"action must be an integer in 0..{N_ACTIONS - 1}, got {action!r}")
            a = int(arr.item())
            if not 0 <= a < N_ACTIONS:
                raise ValueError(f"action must be in 0..{N_ACTIONS - 1}, got {action!r}")
            return a, None
        if arr.size != 1 or arr.dtype.kind not in "iuf" or not np.isfinite(arr).all():
            raise ValueError(f"action must be one finite acceleration (m/s^2), got {action!r}")
        lo, hi = self._acc_bounds
        acc = float(np.clip(float(arr.reshape(-1)[0]), lo, hi)) * FT_PER_M
        return action_of(acc), acc

    def apply(self, ctl: Controller, c: Control, frame: FrameState, ia: int, ic: int | None, obs: MergeObservation,
              action: Any) -> tuple[float, dict[str, Any]]:
        """Apply ``action`` (checked, :meth:`parse_action`) to control ``c`` through the controller;
        returns the decision's reward and the step's ``info`` entries (``action_bin``,
        ``acc_ft_s2``, ``acc_mps2``, ``rewards``: :meth:`reward_terms`).

        Raises:
            ValueError: a bad action (:meth:`parse_action`).
            sim.errors.RewardError: the reward returned no finite real number (the reward and the
                environment named).
        """
        a, acc_cmd = self.parse_action(action)
        acc = ctl.apply(c, frame, ia, ic, obs, _EYE[a], a, acc_ft_s2=acc_cmd)
        applied = action_of(acc)
        reward = (reward_value(self.reward_fn(obs, applied, acc), self.reward_where)
                  if self.reward_fn is not None else 0.0)
        return reward, {"action_bin": applied, "acc_ft_s2": acc, "acc_mps2": acc * M_PER_FT,
                        "rewards": self.reward_terms(obs, applied, acc, reward)}

    def reward_terms(self, obs: MergeObservation, action_bin: int, acc_ft_s2: float, reward: float) -> dict[str, float]:
        """The decision's reward by name (``info["rewards"]``): the reward's ``terms`` when it has
        them (:class:`~sim.env.rewards.RewardWithTerms`), else ``{"reward": reward}``.

        Raises:
            sim.errors.RewardError: a term that is no finite real number, or terms not a mapping.
        """
        if self.reward.terms is None:
            return {"reward": reward}
        terms = self.reward.terms(obs, action_bin, acc_ft_s2)
        if not isinstance(terms, Mapping):
            raise RewardError(f"{self.reward_where}: terms() returned {type(terms).__name__}; expected a mapping "
                              "name -> float")
        return {str(k): reward_value(v, f"{self.reward_where}, term {k!r},") for k, v in terms.items()}

    def outcome(self, c: Control) -> float:
        """The reward's term for how ``c`` ended (a task reward's collision penalty), else 0.

        Raises:
            sim.errors.RewardError: ``outcome`` returned no finite real number.
        """
        if self.outcome_fn is None:
            return 0.0
        return reward_value(self.outcome_fn(c.reason, c.collision_kind), f"{self.reward_where}, outcome,")

    def outcome_terms(self, c: Control, info: dict[str, Any]) -> float:
        """:meth:`outcome` of ``c``, also added to ``info["rewards"]`` as ``"outcome"`` (when the
        reward has one)."""
        value = self.outcome(c)
        if self.outcome_fn is not None:
            info["rewards"] = {**info.get("rewards", {}), "outcome": value}
        return value

    @staticmethod
    def removed(session: SumoSession, controls: list[Control]) -> list[Control]:
        """The controls of ``controls`` whose A SUMO no longer knows: removed between two
        ``step`` calls (by another TraCI client, a co-simulation, the user's code), after the
        frame the environment observed it in; usually none. One ``vehicle.getIDList()`` call."""
        if not controls:
            return []
        known = set(session.sumo.vehicle.getIDList())
        return [c for c in controls if c.a_sumo not in known]

    @staticmethod
    def release_removed(ctl: Controller, c: Control) -> None:
        """Release ``c`` (one of :meth:`removed`) as ``removed_externally`` at the last frame the
        controller saw; A is gone, so nothing is handed back to SUMO."""
        ctl.release(c, ctl.last_frame, REMOVED_EXTERNALLY, present=False)

    @staticmethod
    def observe_at_release(ctl: Controller, c: Control, frame: FrameState) -> MergeObservation | None:
        """A's observation at the release frame, None when A or B has left the network."""
        rows = ctl.rows or dict(zip(frame.vehicle_id.tolist(), range(len(frame.sumo_ids))))
        ia, ib = rows.get(c.a_id), rows.get(c.b_id)
        if ia is None or ib is None:
            return None
        ic = lead_of(frame, float(frame.local_y[ia]), lane=ctl.merge_lane, exclude=(ia, ib))
        return ctl.observe(c, frame, ia, ib, ic)


def removed_info(c: Control) -> dict[str, Any]:
    """``{"a_sumo": A's SUMO id}`` when ``c`` ended as ``removed_externally``, else ``{}``: the
    ``info`` entry naming the car that vanished."""
    return {"a_sumo": c.a_sumo} if c.reason == REMOVED_EXTERNALLY else {}


def end_flags(c: Control) -> tuple[bool, bool]:
    """``(terminated, truncated)`` of a released control: truncated at a time limit."""
    truncated = c.reason in TRUNCATING_REASONS
    return not truncated, truncated
