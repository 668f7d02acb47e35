"""The multi-agent environment's agents in fixed slots: one shared policy, trained by a
single-agent library's vectorised learner (Stable-Baselines3 through SuperSuit).

:class:`AgentSlotsVectorEnv` turns a :class:`~sim.env.multi_agent.MergeParallelEnv` into a
vector environment of ``max_agents`` slots, in SuperSuit's convention (that of its
``MarkovVectorEnv``: ``observation_space`` and ``action_space`` are one slot's, ``infos`` a list
of dicts), so that SuperSuit's ``concat_vec_envs_v1`` makes it a Stable-Baselines3 ``VecEnv``::

    import supersuit as ss
    from sim.env.agent_slots import AgentSlotsVectorEnv

    venv = ss.concat_vec_envs_v1(AgentSlotsVectorEnv(scenario="synthetic", max_agents=4), 1,
                                 base_class="stable_baselines3")

A slot holds one agent (a controlled lag car) from its take-over to its release. The step that
releases it reports the slot's ``terminated`` / ``truncated``, the agent's last reward and, in
``infos[slot]["terminal_observation"]``, its last observation; the observation returned in the
slot is already the next occupant's first one, or zeros while the slot is idle (what
Stable-Baselines3 expects of an episode's end, and SuperSuit's ``black_death`` of an absent agent).
An idle slot reads zeros, reward 0, never done, and ``infos[slot]["active"]`` False; its action is
ignored. The end of the SUMO run ends every occupied slot (``end_of_run``, truncated) and starts
the next run (a seed from the parallel environment's generator).
"""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np

from sim.env.multi_agent import MergeParallelEnv

__all__ = ["AgentSlotsVectorEnv"]


class AgentSlotsVectorEnv(gymnasium.vector.VectorEnv):
    """``max_agents`` slots of a :class:`~sim.env.multi_agent.MergeParallelEnv` (module docstring).

    Args:
        env: the parallel environment; None: one built from ``**kwargs`` (its settings,
            :class:`~sim.env.config.MergeEnvConfig`).
    """

    def __init__(self, env: MergeParallelEnv | None = None, **kwargs: Any):
        self.par_env = env if env is not None else MergeParallelEnv(**kwargs)
        self.num_envs = self.par_env.config.max_agents
        self.single_observation_space = self.par_env.observation_space("")
        self.single_action_space = self.par_env.action_space("")
        # SuperSuit's convention (MarkovVectorEnv, SB3VecEnvWrapper): the spaces of one slot
        self.observation_space = self.single_observation_space
        self.action_space = self.single_action_space
        self.metadata = self.par_env.metadata
        self.render_mode = self.par_env.render_mode
        self._slots: list[str | None] = [None] * self.num_envs
        self._zeros = np.zeros(tuple(self.single_observation_space.shape or ()), dtype=np.float64)

    def reset(self, seed: int | None = None, options: dict[str, Any] | None = None  # type: ignore[override]
              ) -> tuple[np.ndarray, list[dict[str, Any]]]:  # infos a list: SuperSuit's convention
        """A new run (``seed``); returns ``obs [max_agents, 7]`` and one info dict per slot."""
        obs, infos = self.par_env.reset(seed=seed, options=options)
        self._slots = [None] * self.num_envs
        out = np.stack([self._zeros] * self.num_envs)
        slot_infos: list[dict[str, Any]] = [{"active": False} for _ in range(self.num_envs)]
        self._seat(obs, infos, out, slot_infos)
        return out, slot_infos

    def step(self, actions: Any  # type: ignore[override]
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, list[dict[str, Any]]]:
        """Every occupied slot's action (``actions``: ``[max_agents]`` or ``[max_agents, 1]``);
        returns ``obs [max_agents, 7]``, ``rewards``, ``terminated``, ``truncated`` ``[max_agents]``
        and one info dict per slot (module docstring)."""
        acts = list(actions)
        n = self.num_envs
        par_actions = {agent: acts[i] for i, agent in enumerate(self._slots) if agent is not None}
        obs, rewards, terms, truncs, infos = self.par_env.step(par_actions)
        out = np.stack([self._zeros] * n)
        rew = np.zeros(n, dtype=np.float32)
        term = np.zeros(n, dtype=bool)
        trunc = np.zeros(n, dtype=bool)
        slot_infos: list[dict[str, Any]] = [{"active": False} for _ in range(n)]
        for i, agent in enumerate(self._slots):
            if agent is None:
                continue
            rew[i] = rewards.get(agent, 0.0)
            slot_infos[i] = {**infos.get(agent, {}), "agent": agent, "active": True}
            if terms.get(agent) or truncs.get(agent):
                term[i], trunc[i] = bool(terms.get(agent)), bool(truncs.get(agent))
                slot_infos[i]["terminal_observation"] = obs[agent]
                slot_infos[i]["TimeLimit.truncated"] = bool(trunc[i])  # SB3 bootstraps a truncated end
                self._slots[i] = None
            else:
                out[i] = obs[agent]
        if not self.par_env.agents:  # the run ended: the next one
            obs, infos = self.par_env.reset()
            self._slots = [None] * n
        self._seat(obs, infos, out, slot_infos)
        return out, rew, term, trunc, slot_infos

    def _seat(self, obs: dict[str, np.ndarray], infos: dict[str, dict[str, Any]], out: np.ndarray,
              slot_infos: list[dict[str, Any]]) -> None:
        """Put the agents new in ``obs`` into free slots (their first observations into ``out``)."""
        seated = set(self._slots)
        for agent in self.par_env.agents:
            if agent in seated:
                continue
            i = self._slots.index(None)  # the parallel environment holds at most max_agents
            self._slots[i] = agent
            out[i] = obs[agent]
            slot_infos[i] = {**slot_infos[i], **infos.get(agent, {}), "agent": agent, "active": True}

    def step_async(self, actions: Any) -> None:
        self._actions = actions

    def step_wait(self, **kwargs: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, list[dict[str, Any]]]:
        return self.step(self._actions)

    def render(self) -> Any:
        return self.par_env.render()

    def close(self, **kwargs: Any) -> None:
        self.par_env.close()

    def env_is_wrapped(self, wrapper_class: Any) -> list[bool]:
        return [False] * self.num_envs
