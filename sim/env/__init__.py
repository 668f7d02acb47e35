"""The merge as a Gymnasium environment (optional extra ``[gym]``: ``pip install -e '.[gym]'``) and
as a PettingZoo ``ParallelEnv`` (extra ``[marl]``).

Importing this package registers ``MergeIRL/OnRampMerge-v0``::

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

import gymnasium as gym

from sim.drivers.learned import TabularReward
from sim.drivers.planning import PlanningReward
from sim.env.config import MergeEnvConfig
from sim.env.merge_env import MergeEnv, make_env
from sim.env.rewards import load_reward
from sim.env.task_reward import TASK_REWARDS, TaskReward

#: The registered environment id.
ENV_ID = "MergeIRL/OnRampMerge-v0"
#: The spec's ``max_episode_steps``: the decisions of the controller's default time limit
#: (``max_control_s`` 60 s at 0.3 s), where the controller itself truncates (``timeout``).
MAX_EPISODE_STEPS = 200

if ENV_ID not in gym.registry:
    # no passive checker: when an environment's first reset raises (options it refuses, for example),
    # Gymnasium's PassiveEnvChecker is left half-set and a later step fails with its own TypeError;
    # the environment passes gymnasium.utils.env_checker.check_env, as users call it, in its tests
    gym.register(id=ENV_ID, entry_point="sim.env.merge_env:MergeEnv", max_episode_steps=MAX_EPISODE_STEPS,
                 disable_env_checker=True)

__all__ = ["ENV_ID", "MAX_EPISODE_STEPS", "MergeEnv", "MergeEnvConfig", "MergeParallelEnv", "PlanningReward",
           "TASK_REWARDS", "TabularReward", "TaskReward", "load_reward", "make_env"]


def __getattr__(name: str) -> Any:
    if name == "MergeParallelEnv":  # pettingzoo (the [marl] extra) only when asked for
        from sim.env.multi_agent import MergeParallelEnv

        return MergeParallelEnv
    raise AttributeError(f"module 'sim.env' has no attribute {name!r}")
