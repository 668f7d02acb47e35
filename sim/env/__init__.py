"""The merge as a Gymnasium environment (optional extra ``[gym]``: ``pip install -e '.[gym]'``).

Importing this package registers ``MergeIRL/OnRampMerge-v0``::

    import gymnasium as gym
    import sim.env  # registers the id

    env = gym.make("MergeIRL/OnRampMerge-v0", scenario="synthetic", action_type="discrete")

``import sim`` does not import gymnasium; only this package does. The environment:
:class:`sim.env.merge_env.MergeEnv`; its rewards: :mod:`sim.env.rewards`; the guide:
docs/environment.md.
"""

from __future__ import annotations

import gymnasium as gym

from sim.env.merge_env import MergeEnv, make_env
from sim.env.rewards import PlanningReward, TabularReward, load_reward

#: The registered environment id.
ENV_ID = "MergeIRL/OnRampMerge-v0"

if ENV_ID not in gym.registry:
    # no passive checker: when an environment's first reset raises (a second SUMO session refused in
    # one process), Gymnasium's PassiveEnvChecker is left half-set and a later step fails with its own
    # TypeError; the environment passes gymnasium.utils.env_checker.check_env in its tests
    gym.register(id=ENV_ID, entry_point="sim.env.merge_env:MergeEnv", disable_env_checker=True)

__all__ = ["ENV_ID", "MergeEnv", "PlanningReward", "TabularReward", "load_reward", "make_env"]
