"""The Gymnasium plugin: :func:`register_envs` registers ``MergeIRL/OnRampMerge-v0``.

``pyproject.toml`` names it in Gymnasium's entry-point group::

    [project.entry-points."gymnasium.envs"]
    MergeIRL = "merge_irl.gym_plugin:register_envs"

so Gymnasium 0.29 (what imitation 1.0.1 and Stable-Baselines3 2.2 pin), which loads that group on
``import gymnasium`` (``gymnasium.envs.registration.load_plugin_envs``, inside the namespace
``MergeIRL``, the entry point's name), registers the id for every installed copy:
``gym.make("MergeIRL/OnRampMerge-v0")`` needs no other import. Gymnasium 1.x loads no plugins
(``load_plugin_envs`` is gone); there the id names the module that registers it,
``gym.make("sim.env:MergeIRL/OnRampMerge-v0")``, or ``import sim.env`` first (which calls
:func:`register_envs` too).

The environment's class is named as a string, so registering imports nothing of ours, and
Gymnasium only inside the function (this module stays on the ground floor). Gymnasium imports
the environment (:class:`sim.env.merge_env.MergeEnv`) at the first ``gym.make``.
"""

from __future__ import annotations

__all__ = ["ENV_ENTRY_POINT", "ENV_ID", "MAX_EPISODE_STEPS", "register_envs"]

#: The registered environment id.
ENV_ID = "MergeIRL/OnRampMerge-v0"
#: What Gymnasium imports at ``gym.make``.
ENV_ENTRY_POINT = "sim.env.merge_env:MergeEnv"
#: The spec's ``max_episode_steps``: the decisions of the controller's default time limit
#: (``max_control_s`` 60 s at 0.3 s), where the controller itself truncates (``timeout``).
MAX_EPISODE_STEPS = 200


def register_envs() -> None:
    """Register :data:`ENV_ID` with Gymnasium, once (a second call does nothing)."""
    from gymnasium.envs.registration import register, registry

    if ENV_ID in registry:
        return
    # no passive checker: when an environment's first reset raises (options it refuses, for example),
    # Gymnasium's PassiveEnvChecker is left half-set and a later step fails with its own TypeError;
    # the environment passes gymnasium.utils.env_checker.check_env, as users call it, in its tests
    register(id=ENV_ID, entry_point=ENV_ENTRY_POINT, max_episode_steps=MAX_EPISODE_STEPS, disable_env_checker=True)
