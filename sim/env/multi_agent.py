"""Every merge's lag car A as an agent: the merge as a PettingZoo ``ParallelEnv`` (extra ``[marl]``).

One episode is one SUMO run (``run_s`` simulated seconds). An agent appears when the controller
takes a lag car A over for its merging car B and leaves when the controller releases A (the
reasons of :mod:`sim.closed_loop.controller`); its name is ``"A<a_id>_B<b_id>"`` (Vehicle_IDs:
a car taken over again for another B is another agent). Every agent has the single-agent
environment's spaces, observation, reward and ``info`` (:mod:`sim.env.merge_env`); the last
step of an agent carries its ``release_reason`` and ``terminated`` / ``truncated`` as there; an
agent whose car vanished between two ``step`` calls (removed by another TraCI client, a
co-simulation, the user's code) is done in the next ``step`` (``removed_externally``, truncated,
its action ignored, ``info["a_sumo"]`` its SUMO id), the other agents step as usual.

Decisions are on one clock: take-overs happen only on frames that are a multiple of the
decision step (at most ``decision_step_s - 0.1`` s later than the closed loop's, which takes
over on any frame), so every agent decides on the same frames and one ``step(actions)`` applies
all their actions and runs SUMO once, to the next frame with a decision. A step whose agents
were all released runs on to the next take-over, so ``agents`` is empty only at the end of the
run (then every agent still in control is truncated, ``end_of_run``). ``possible_agents`` lists
every agent seen since ``reset`` (PettingZoo's checker requires the agents to be among them; no
list of all can be known in advance). At most ``max_agents`` are controlled at once; a take-over
beyond is left to SUMO.

``reset(seed=s)`` starts a new run with seed ``s`` (a seed drawn from the environment's generator
without one) and runs it to the first decision. For one shared policy trained by
Stable-Baselines3 the agents go into fixed slots, :class:`sim.env.agent_slots.AgentSlotsVectorEnv`.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from pettingzoo import ParallelEnv

from sim.closed_loop.controller import Controller
from sim.closed_loop.records import Control
from sim.drivers.observe import MergeObservation
from sim.env.config import MergeEnvConfig, resolve_config
from sim.env.core import EnvCore, end_flags, removed_info
from sim.env.merge_env import MAX_EMPTY_RUNS, RENDER_MODES, check_render_mode
from sim.env.seeds import reset_seed
from sim.runtime.hooks import FrameState
from sim.runtime.session import SumoSession

__all__ = ["MergeParallelEnv", "agent_name"]


def agent_name(c: Control) -> str:
    """The agent of control episode ``c``: ``"A<a_id>_B<b_id>"``."""
    return f"A{c.a_id}_B{c.b_id}"


class MergeParallelEnv(ParallelEnv):
    """Every controlled lag car A an agent (module docstring). Arguments as
    :class:`sim.env.merge_env.MergeEnv`'s: ``config`` (a :class:`~sim.env.config.MergeEnvConfig`
    or a mapping), ``render_mode`` (None or ``"rgb_array"``: every A red, its B orange, its C
    blue), and any config field as a keyword (``max_agents``: the cap on agents at once).

    Raises:
        the errors of :class:`sim.env.merge_env.MergeEnv`'s constructor.
    """

    metadata: dict[str, Any] = {"name": "merge_irl_onramp_v0", "render_modes": list(RENDER_MODES),
                                "render_fps": 10, "is_parallelizable": True}

    def __init__(self, config: MergeEnvConfig | Mapping[str, Any] | None = None, *,
                 render_mode: str | None = None, **overrides: Any):
        self.render_mode = check_render_mode(render_mode)
        self.config = resolve_config(config, overrides)
        self._core = EnvCore(self.config)
        self.agents: list[str] = []
        self.possible_agents: list[str] = []
        self._np_random, _ = seeding.np_random(None)
        self._session: SumoSession | None = None
        self._ctl: Controller | None = None
        self._every = 1
        self._live: dict[str, Control] = {}
        self._pending: dict[str, tuple[FrameState, int, int | None, MergeObservation]] = {}
        self._last_obs: dict[str, np.ndarray] = {}
        self._frame: FrameState | None = None
        self._renderer: Any = None
        self._run_seed = -1

    def observation_space(self, agent: str) -> spaces.Space[Any]:
        """The one observation space object of every agent (PettingZoo asks for the same object)."""
        return self._core.observation_space

    def action_space(self, agent: str) -> spaces.Space[Any]:
        return self._core.action_space

    # -- PettingZoo API -------------------------------------------------------------------
    def reset(self, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[dict[str, np.ndarray], dict[str, dict[str, Any]]]:
        """Start a new SUMO run (``seed``, else one drawn from the generator) and run it to the
        first decision. Returns the first agents' observations and infos. ``seed``: as
        :class:`~sim.env.merge_env.MergeEnv`'s (:func:`sim.env.seeds.reset_seed`).

        Raises:
            sim.env.seeds.SeedError: ``seed`` a bool, a float, negative or not an integer.
            sim.errors.SimulationError: SUMO fails, or ``MAX_EMPTY_RUNS`` runs in a row have no take-over.
        """
        checked = reset_seed(seed, "MergeParallelEnv.reset")  # the same rule as MergeEnv's (sim.env.seeds)
        if checked is not None:
            self._np_random, _ = seeding.np_random(checked.seed)
        run_seed = checked.sumo if checked is not None else self._draw_seed()
        for _ in range(MAX_EMPTY_RUNS):
            self._start_run(run_seed)
            obs, _, _, _, infos = self._advance({}, {}, {})
            if self.agents:
                return obs, infos
            run_seed = self._draw_seed()
        from sim.errors import SimulationError

        raise SimulationError(f"MergeParallelEnv.reset: {MAX_EMPTY_RUNS} SUMO runs of {self.config.run_s:g} s of "
                              f"scenario {self._core.spec.name!r} had no take-over (no merge with a lag car)")

    def step(self, actions: Mapping[str, Any]) -> tuple[dict[str, np.ndarray], dict[str, float], dict[str, bool],
                                                        dict[str, bool], dict[str, dict[str, Any]]]:
        """Apply every agent's action (``actions``: agent -> action of the action space) and run
        SUMO to the next decision (or the end of the run).

        Returns ``(observations, rewards, terminations, truncations, infos)``, dicts keyed by the
        agents that acted and the agents that appeared (their first observation, reward 0).

        Raises:
            RuntimeError: no run (call ``reset``), or the run has ended.
            ValueError: an action missing for an agent, given for no agent, or outside the space.
        """
        if self._ctl is None or self._session is None or not self.agents:
            raise RuntimeError("MergeParallelEnv.step: no agent to step; call reset() first")
        missing = [a for a in self.agents if a not in actions]
        extra = [a for a in actions if a not in self._live]
        if missing or extra:
            raise ValueError(f"MergeParallelEnv.step: actions must be given for exactly the agents {self.agents}; "
                             f"missing {missing}, not agents {extra}")
        rewards: dict[str, float] = {}
        step_infos: dict[str, dict[str, Any]] = {}
        gone = {agent_name(c): c for c in self._core.removed(self._session, [self._live[a] for a in self.agents])}
        for agent, c in gone.items():  # removed since the last step: released now, reported by _advance
            self._core.parse_action(actions[agent])  # an action outside the space is still refused
            self._core.release_removed(self._ctl, c)
        for agent in self.agents:
            if agent in gone:
                continue
            frame, ia, ic, obs = self._pending[agent]
            rewards[agent], step_infos[agent] = self._core.apply(self._ctl, self._live[agent], frame, ia, ic, obs,
                                                                 actions[agent])
        self._pending = {}
        return self._advance(rewards, step_infos, dict.fromkeys(self.agents, None))

    def render(self) -> np.ndarray | None:
        """The current frame, ``uint8[160, 960, 3]`` (``render_mode="rgb_array"``), else None."""
        if self.render_mode is None or self._frame is None or self._session is None or self._ctl is None:
            return None
        if self._renderer is None:
            from sim.env.render import TopDownRenderer

            assert self._session.context is not None
            self._renderer = TopDownRenderer(self._session.context)
        return self._renderer.frame(self._frame, self._ctl.role_rows)

    def close(self) -> None:
        """Close SUMO (idempotent)."""
        if self._session is not None:
            self._session.close()
        self._session = None
        self._ctl = None
        self._frame = None
        self._live, self._pending, self._last_obs, self.agents = {}, {}, {}, []

    # -- internals ------------------------------------------------------------------------
    def _draw_seed(self) -> int:
        return int(self._np_random.integers(0, 2**31 - 1))

    def _start_run(self, seed: int) -> None:
        self.close()
        self._session, self._ctl = self._core.start(seed)
        assert self._session.context is not None
        self._every = max(1, int(round(self._ctl.decision_step_s / self._session.context.frame_s)))
        self._renderer = None
        self._run_seed = seed
        self.possible_agents = []

    def _advance(self, rewards: dict[str, float], step_infos: dict[str, dict[str, Any]],
                 acted: dict[str, None]) -> tuple[dict[str, np.ndarray], dict[str, float], dict[str, bool],
                                                  dict[str, bool], dict[str, dict[str, Any]]]:
        """Run SUMO to the next frame with a decision or to the end of the run; the step's returns."""
        assert self._session is not None and self._ctl is not None
        ctl, core, cap = self._ctl, self._core, self.config.max_agents
        obs: dict[str, np.ndarray] = {}
        infos: dict[str, dict[str, Any]] = {}
        terms: dict[str, bool] = {}
        truncs: dict[str, bool] = {}
        last = {a: self._last_obs[a] for a in acted}
        n_controls = len(ctl.controls)
        while True:
            st = self._session.step()
            if st is None:  # the run is over: whoever is still controlled is truncated
                self._release_at_end()
                ended, due = list(self._live), []
            else:
                frame = self._frame = st.frame
                on_clock = frame.frame % self._every == 0
                due = ctl.advance(frame, max_take_overs=max(0, cap - len(self._live)) if on_clock else 0)
                for c in ctl.controls[n_controls:]:  # the take-overs of this frame: new agents
                    self._live[agent_name(c)] = c
                    self.possible_agents.append(agent_name(c))
                n_controls = len(ctl.controls)
                ended = [a for a, c in self._live.items() if not c.active]
            for agent in ended:
                c = self._live.pop(agent)
                if st is not None and (o := core.observe_at_release(ctl, c, st.frame)) is not None:
                    last[agent] = core.observation(o)
                obs[agent] = last.get(agent, np.zeros(core.observation_space.shape or ()))
                step_info = dict(step_infos.get(agent, {}))
                rewards[agent] = rewards.get(agent, 0.0) + core.outcome_terms(c, step_info)
                terms[agent], truncs[agent] = end_flags(c)
                infos[agent] = {**self._info(c, None, frame_time=st.frame.time_s if st else np.nan),
                                **step_info, "release_reason": c.reason,
                                "collision_kind": c.collision_kind}
            if st is None or due:
                break
        names = {id(c): a for a, c in self._live.items()}
        for c, ia, ib, ic in due:
            assert st is not None
            agent = names[id(c)]
            o = ctl.observe(c, st.frame, ia, ib, ic)
            self._pending[agent] = (st.frame, ia, ic, o)
            obs[agent] = self._last_obs[agent] = core.observation(o)
            rewards.setdefault(agent, 0.0)
            terms[agent] = truncs[agent] = False
            infos[agent] = {**self._info(c, o, frame_time=st.frame.time_s), **step_infos.get(agent, {})}
        self.agents = list(self._live)
        for gone in set(self._last_obs) - set(self._live):
            del self._last_obs[gone]
        return obs, rewards, terms, truncs, infos

    def _release_at_end(self) -> None:
        """Release every agent still controlled at the end of the run (``end_of_run``)."""
        assert self._ctl is not None
        for c in self._live.values():
            if c.active:  # not one released in this step already (removed_externally)
                self._ctl.release(c, self._ctl.last_frame, "end_of_run", present=True)

    def _info(self, c: Control, obs: MergeObservation | None, *, frame_time: float) -> dict[str, Any]:
        return {"state": obs.state if obs is not None else -1, "seed": self._run_seed, "time_s": float(frame_time),
                "a_id": c.a_id, "b_id": c.b_id, **removed_info(c)}
