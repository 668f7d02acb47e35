"""The environments' task reward: progress, collision and near-miss penalties, comfort; by name.

:class:`TaskReward` is a reward of :mod:`sim.env.rewards`' kind, ``reward(obs, action_bin,
acc_ft_s2) -> float`` of one decision, plus an ``outcome(reason, collision_kind) -> float`` the
environment adds to the reward of the step that ends the episode. Per decision (``obs`` is A's
:class:`~sim.drivers.observe.MergeObservation` at the decision; speeds and gaps in ft, ft/s)::

    r = w_progress * clip(v_A / v_ref, 0, 1)                     # progress: A's speed, 0..1
      - w_near_miss * max(0, 1 - TTC / ttc_near_miss_s)         # closing on C, or on B ahead in A's lane
      - w_comfort * (acc / acc_ref) ** 2                         # A's acceleration (any sign)
      - w_jerk * ((acc - acc_prev) / (acc_ref)) ** 2             # its change from the last decision
    at the end: - collision_penalty when A was in a collision (release reason ``collision``)

``TTC`` is the bumper gap (``d_AC - len_C``; to B once B is in A's lane ahead of it: ``d_AB -
len_B``) over the closing speed (``v_AC``, ``v_AB`` > 0), infinite when not closing; a gap at or
below 0 counts as TTC 0. Without a lead car C only B counts. The terms are on the scale of
HighwayEnv's (progress 0..``w_progress`` per step, a collision an order of magnitude more).

Named rewards (:data:`TASK_REWARDS`), selected with ``reward="NAME"``:

* ``"task"`` (the environments' default): every term at the defaults of :class:`TaskReward`;
* ``"progress"``: progress and the collision penalty only;
* ``"zero"``: 0 at every step (for imitation learners, which learn their own; ``reward=None`` too).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from merge_irl.registry import Registry
from merge_irl.units import FT_PER_M
from sim.drivers.formats import RewardFn
from sim.drivers.observe import MergeObservation

__all__ = ["TASK_REWARDS", "TaskReward", "ZeroReward", "task_reward"]


@dataclass(frozen=True)
class TaskReward:
    """The task reward's weights and scales (module docstring: the formula).

    Attributes:
        w_progress: weight of A's speed over ``v_ref_mps`` (clipped to 0..1).
        v_ref_mps: the speed of full progress (m/s; 29 m/s = 65 mph, the synthetic main road's).
        w_near_miss: weight of the near-miss term (0..1 as TTC falls from ``ttc_near_miss_s`` to 0).
        ttc_near_miss_s: the time-to-collision under which a decision is a near miss (s).
        w_comfort: weight of the squared acceleration over ``acc_ref_mps2``.
        w_jerk: weight of the squared change of acceleration over ``acc_ref_mps2``.
        acc_ref_mps2: the acceleration scale of the comfort terms (m/s^2).
        collision_penalty: subtracted once, at the end of an episode that ends in A's collision.

    Raises:
        ValueError: a weight or penalty negative or not finite; a scale not positive.
    """

    w_progress: float = 0.4
    v_ref_mps: float = 29.0
    w_near_miss: float = 0.5
    ttc_near_miss_s: float = 2.0
    w_comfort: float = 0.05
    w_jerk: float = 0.05
    acc_ref_mps2: float = 3.0
    collision_penalty: float = 10.0

    def __post_init__(self) -> None:
        for name in ("w_progress", "w_near_miss", "w_comfort", "w_jerk", "collision_penalty"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"TaskReward.{name}: must be a finite number >= 0, got {v!r}")
        for name in ("v_ref_mps", "ttc_near_miss_s", "acc_ref_mps2"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"TaskReward.{name}: must be a positive number, got {v!r}")

    def ttc_s(self, obs: MergeObservation) -> float:
        """A's smallest time-to-collision (s) to C, and to B once B merged ahead of A; inf when closing on neither."""
        ttc = math.inf
        pairs = [(obs.d_AC, obs.len_C, obs.v_AC)]
        if obs.b_merged:
            pairs.append((obs.d_AB, obs.len_B, obs.v_AB))
        for d, length, closing in pairs:
            if not (math.isfinite(d) and d > 0):
                continue  # no such car, or it is behind A
            gap = d - (length if math.isfinite(length) else 0.0)
            if gap <= 0:
                return 0.0
            if math.isfinite(closing) and closing > 0:
                ttc = min(ttc, gap / closing)
        return ttc

    def terms(self, obs: MergeObservation, action_bin: int, acc_ft_s2: float) -> dict[str, float]:
        """The decision's terms, signed as they add up: ``progress`` (>= 0), ``near_miss``,
        ``comfort``, ``jerk`` (<= 0)."""
        progress = min(max(obs.speed_A / (self.v_ref_mps * FT_PER_M), 0.0), 1.0) if math.isfinite(obs.speed_A) else 0.0
        ttc = self.ttc_s(obs)
        near = max(0.0, 1.0 - ttc / self.ttc_near_miss_s)
        acc_ref = self.acc_ref_mps2 * FT_PER_M
        acc = acc_ft_s2 if math.isfinite(acc_ft_s2) else 0.0
        jerk = (acc - obs.acc_prev) / acc_ref if math.isfinite(obs.acc_prev) else 0.0
        return {"progress": self.w_progress * progress, "near_miss": -self.w_near_miss * near,
                "comfort": -self.w_comfort * (acc / acc_ref) ** 2, "jerk": -self.w_jerk * jerk ** 2}

    def __call__(self, obs: MergeObservation, action_bin: int, acc_ft_s2: float) -> float:
        """The reward of one decision (module docstring)."""
        return float(sum(self.terms(obs, action_bin, acc_ft_s2).values()))

    def outcome(self, reason: str, collision_kind: str = "") -> float:
        """Added to the last step's reward: ``-collision_penalty`` for ``reason == "collision"``, else 0."""
        return -self.collision_penalty if reason == "collision" else 0.0


class ZeroReward:
    """0 at every step (the ``"zero"`` reward)."""

    def __call__(self, obs: MergeObservation, action_bin: int, acc_ft_s2: float) -> float:
        return 0.0

    def __repr__(self) -> str:
        return "ZeroReward()"


#: The rewards selectable by name (``reward="task"``); ``"task"`` is the environments' default;
#: :func:`sim.env.rewards.register_reward` adds others.
TASK_REWARDS: Registry[RewardFn] = Registry("reward")
TASK_REWARDS.register("task", TaskReward())
TASK_REWARDS.register("progress", TaskReward(w_near_miss=0.0, w_comfort=0.0, w_jerk=0.0))
TASK_REWARDS.register("zero", ZeroReward())


def task_reward(name: str) -> RewardFn:
    """The named reward of :data:`TASK_REWARDS`.

    Raises:
        KeyError (RegistryError): an unknown name (the names listed).
    """
    return TASK_REWARDS[name]
