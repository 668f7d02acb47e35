"""The merge as a Gymnasium environment (optional extra ``[gym]``: ``pip install -e '.[gym]'``) and
as a PettingZoo ``ParallelEnv`` (extra ``[marl]``).

Importing this package registers ``MergeIRL/OnRampMerge-v0``, as the installed package's Gymnasium
entry point does on ``import gymnasium`` with Gymnasium 0.29 (:mod:`merge_irl.gym_plugin`; with
1.x, which loads no plugins, ``gym.make("sim.env:MergeIRL/OnRampMerge-v0")`` imports this package)::

    import gymnasium as gym
    import sim.env  # registers the id

    env = gym.make("MergeIRL/OnRampMerge-v0", scenario="synthetic", action_type="discrete")

``import sim`` does not import gymnasium; only this package does, and only
:mod:`sim.env.multi_agent` imports pettingzoo (``sim.env.MergeParallelEnv`` loads it on first
use). The environment: :class:`sim.env.merge_env.MergeEnv`; its settings:
:class:`sim.env.config.MergeEnvConfig`; its rewards: :mod:`sim.env.task_reward` (by name) and
:mod:`sim.env.rewards` (learned files); every lag car an agent: :mod:`sim.env.multi_agent`; the
guide: docs/environment.md.
"""

from __future__ import annotations

from typing import Any

from merge_irl.gym_plugin import ENV_ID, MAX_EPISODE_STEPS, register_envs
from sim.drivers.learned import TabularReward
from sim.drivers.planning import PlanningReward
from sim.env.config import MergeEnvConfig
from sim.env.merge_env import MergeEnv, make_env
from sim.env.observations import Observation, register_observation
from sim.env.rewards import Reward, load_reward, register_reward
from sim.env.task_reward import TASK_REWARDS, TaskReward

register_envs()  # MergeIRL/OnRampMerge-v0 (also Gymnasium's entry point: merge_irl.gym_plugin)

__all__ = ["ENV_ID", "MAX_EPISODE_STEPS", "MergeEnv", "MergeEnvConfig", "MergeParallelEnv", "Observation",
           "PlanningReward", "Reward", "TASK_REWARDS", "TabularReward", "TaskReward", "load_reward", "make_env",
           "register_observation", "register_reward"]


def __getattr__(name: str) -> Any:
    if name == "MergeParallelEnv":  # pettingzoo (the [marl] extra) only when asked for
        from sim.env.multi_agent import MergeParallelEnv

        return MergeParallelEnv
    raise AttributeError(f"module 'sim.env' has no attribute {name!r}")
