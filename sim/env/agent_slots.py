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

A slot holds one agent (a controlled lag car) from its take-over to its release; its episode is
that car's control. Per slot and step, ``infos[slot]``:

* ``active``: True when the slot's car acted in this step (its action applied, its reward in
  ``rewards[slot]``; ``agent``, ``a_id``, ``b_id`` and the rest of the parallel environment's
  ``info`` are that car's). False on an idle step: the slot held no car, its action was ignored,
  it reads reward 0 and is never done.
* on the step that releases the car: ``release_reason``, ``terminated`` / ``truncated`` in the
  slot, ``terminal_observation`` (its last observation), ``TimeLimit.truncated``, and
  ``episode = {"r": return, "l": steps, "t": seconds since the environment was made}``: the car's
  return and number of controlled steps (idle steps never count), what Stable-Baselines3's
  logger reads (``rollout/ep_rew_mean``, ``ep_len_mean``), as its ``VecMonitor`` writes it.
* ``seated``: the ``info`` of a car seated in the slot in this step (``reset`` included), with
  its ``agent``; the observation returned in the slot is then that car's first one. A car
  seated on the step that releases the slot's previous car (Stable-Baselines3's reset at an
  episode's end) keeps its ``info`` apart, under ``seated``; the rest of the slot's ``info`` is
  the released car's.

Do not wrap the vector environment in Stable-Baselines3's ``VecMonitor``: it counts every step of
a slot, idle ones included, into the next car's episode (and overwrites ``episode``).
:attr:`AgentSlotsVectorEnv.live_steps` / :attr:`~AgentSlotsVectorEnv.slot_steps` give the share
of slot-steps a car held (the rest is padding the learner still sees: fewer slots, less padding).
The end of the SUMO run ends every occupied slot (``end_of_run``, truncated) and starts the next
run (a seed from the parallel environment's generator).
"""

from __future__ import annotations

import time
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

    Attributes:
        live_steps: slot-steps a car held since the environment was made (decisions taken).
        slot_steps: slot-steps since the environment was made (``steps * max_agents``).
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
        self._ret = np.zeros(self.num_envs)  # the slot's car's return so far
        self._len = np.zeros(self.num_envs, dtype=np.int64)  # and its controlled steps
        self._t0 = time.perf_counter()
        self._zeros = np.zeros(tuple(self.single_observation_space.shape or ()), dtype=np.float64)
        self.live_steps = 0
        self.slot_steps = 0

    def reset(self, seed: int | None = None, options: dict[str, Any] | None = None  # type: ignore[override]
              ) -> tuple[np.ndarray, list[dict[str, Any]]]:  # infos a list: SuperSuit's convention
        """A new run (``seed``); returns ``obs [max_agents, 7]`` and one info dict per slot (the
        first cars' under ``seated``)."""
        obs, infos = self.par_env.reset(seed=seed, options=options)
        self._slots = [None] * self.num_envs
        self._ret[:] = 0.0
        self._len[:] = 0
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
        self.slot_steps += n
        for i, agent in enumerate(self._slots):
            if agent is None:
                continue
            self.live_steps += 1
            rew[i] = rewards.get(agent, 0.0)
            self._ret[i] += float(rew[i])
            self._len[i] += 1
            slot_infos[i] = {**infos.get(agent, {}), "agent": agent, "active": True}
            if terms.get(agent) or truncs.get(agent):
                term[i], trunc[i] = bool(terms.get(agent)), bool(truncs.get(agent))
                slot_infos[i].update(self._episode_end(i, obs[agent], bool(trunc[i])))
            else:
                out[i] = obs[agent]
        if not self.par_env.agents:  # the run ended: the next one
            obs, infos = self.par_env.reset()
            self._slots = [None] * n
        self._seat(obs, infos, out, slot_infos)
        return out, rew, term, trunc, slot_infos

    def _episode_end(self, i: int, last_obs: np.ndarray, truncated: bool) -> dict[str, Any]:
        """The ``info`` entries of slot ``i``'s release (its car's ``episode``); frees the slot."""
        entries = {"terminal_observation": last_obs,
                   "TimeLimit.truncated": truncated,  # SB3 bootstraps a truncated end
                   "episode": {"r": float(self._ret[i]), "l": int(self._len[i]),
                               "t": round(time.perf_counter() - self._t0, 6)}}
        self._slots[i] = None
        self._ret[i] = 0.0
        self._len[i] = 0
        return entries

    def _seat(self, obs: dict[str, np.ndarray], infos: dict[str, dict[str, Any]], out: np.ndarray,
              slot_infos: list[dict[str, Any]]) -> None:
        """Put the agents new in ``obs`` into free slots (their first observations into ``out``,
        their ``info`` under ``seated``)."""
        seated = set(self._slots)
        for agent in self.par_env.agents:
            if agent in seated:
                continue
            i = self._slots.index(None)  # the parallel environment holds at most max_agents
            self._slots[i] = agent
            out[i] = obs[agent]
            slot_infos[i]["seated"] = {**infos.get(agent, {}), "agent": agent}

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
