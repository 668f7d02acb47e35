"""The on-ramp merge as a Gymnasium environment: the lag car A is the agent, SUMO drives the rest.

One episode is one take-over of the closed-loop controller (:mod:`sim.closed_loop.controller`): it starts
when a merging car B on the ramp reaches the take-over zone and its lag car A in the merge lane
is handed to the agent, and it ends when the controller releases A (B merged and the hold
passed, a collision, A left the section or its lane, B vanished, ``max_control_s``). Every
``decision_step_s`` (0.3 s by default) the agent chooses A's action; the controller applies it
exactly as it applies a driver's (:meth:`sim.closed_loop.controller.Controller.apply`). Everything else,
including every other merge of the run, is SUMO's.

Spaces:

* observation: ``Box(OBS_LOW, OBS_HIGH, (7,), float64)`` (times 0.3048 with ``units="si"``: m,
  m/s), the driver's continuous observation as a policy sees it (:func:`sim.drivers.observe.policy_observation`, filled and clipped), columns
  :data:`irl.domains.merge.car_following.OBS_COLUMNS`:
  ``d_AC`` (ft, C's front bumper ahead of A's), ``v_AC`` (ft/s, A's speed minus C's),
  ``d_AB`` (ft), ``v_AB`` (ft/s), ``v_A`` (ft/s, A's speed), ``len_C``, ``len_B`` (ft). No lead
  car C reads as one :data:`sim.drivers.observe.NO_LEAD_GAP_FT` ahead at A's speed.
* action, ``action_type="discrete"``: ``Discrete(5)``, the merge actions in the controller's
  order (:data:`irl.domains.merge.actions.ACTION_NAMES`: 0 High Brake, 1 Low Brake, 2 Zero,
  3 Low Accel, 4 High Accel), each applied at its acceleration (the reward model's per-action
  accelerations when it has them, else the bins' nominal ones), capped at A's emergency
  deceleration; ``action_type="continuous"``: ``Box(low, high, (1,), float32)``, A's
  acceleration in m/s^2 (``acc_bounds_mps2``, default -9 .. 4), applied as it is (capped too).

``info`` of ``reset`` and ``step``: ``state`` (the discrete state index of the reward's encoder,
or the authors' bins without a tabular reward; -1 on the step that ends the episode),
``action_bin`` (the applied acceleration's merge action, step only), ``acc_ft_s2`` and ``acc_mps2`` (applied),
``release_reason`` (one of :data:`sim.closed_loop.records.RELEASE_REASONS`, at the episode's end),
``collision_kind``, ``seed`` (the SUMO run's), ``time_s``, ``a_id`` / ``b_id`` (Vehicle_IDs).

Termination (Gymnasium's terms): ``terminated`` when the controller releases A for a reason of the
merge itself (``merge_done``, ``collision``, ``left_section``, ``left_lane``, ``b_lost``,
``arrived``, ``removed``, ``teleported``); ``truncated`` at a time limit (``timeout``:
``max_control_s`` of :class:`~sim.closed_loop.config.ControllerConfig`; ``end_of_run``: the SUMO
run reached ``run_s``; ``removed_externally``: A vanished between two ``step`` calls, removed by
another TraCI client, a co-simulation or the user's code: that ``step`` applies nothing, runs no
SUMO, returns the last observation and names A in ``info["a_id"]`` and ``info["a_sumo"]``).
The last observation is A's at the release frame when A and B are still in the network, else
the previous one.

Reward: ``reward(obs, action_bin, acc_ft_s2)`` of the decision, returned by the step that applies it,
plus the reward's ``outcome(reason, collision_kind)`` (when it has one) on the step that ends the
episode: by default the task reward ``"task"`` (:mod:`sim.env.task_reward`: progress, near-miss,
comfort, a collision penalty); another name of :data:`sim.env.task_reward.TASK_REWARDS`, a model
file (:mod:`sim.env.rewards`: a tabular IRL model's ``theta . phi(s, a)`` or a planning driver's
step reward), a callable, or None (0: for imitation learners, which learn their own). Every value
is checked where it enters (:func:`sim.env.rewards.reward_value`: one finite real number, else
:class:`sim.errors.RewardError` naming the reward and the environment); ``info["rewards"]`` holds
the step's reward by name (the reward's ``terms``, else ``{"reward": r}``; ``"outcome"`` on the
last step), adding up to it.

Settings: :class:`sim.env.config.MergeEnvConfig`, as keyword arguments or ``config=`` (a mapping
or the dataclass); ``observation=`` chooses what the agent sees by name (:mod:`sim.env.observations`;
the spaces above are the default's, ``"policy"``). Rendering: ``render_mode="rgb_array"`` (:mod:`sim.env.render`).

Runs and seeds: ``reset(seed=s)`` starts a new SUMO run with seed ``s`` (the same seed gives the
same episode for the same actions; any integer ``s >= 0``, a seed of ``2**31`` or more run as
the SUMO seed :func:`sim.env.seeds.sumo_seed` maps it to); ``reset()`` continues the current run to its next take-over,
which saves SUMO's start and warm-up, and starts a new run (seed drawn from the environment's
generator) when none is left. libsumo runs one simulation per process: an environment reset while
another is open runs its SUMO through TraCI (several times slower; :mod:`sim.runtime.session`), so
for several at speed use ``gymnasium.vector.AsyncVectorEnv``, one process each (docs/environment.md).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any

import gymnasium as gym
import numpy as np

from sim.closed_loop.controller import Controller
from sim.closed_loop.records import Control
from sim.drivers.observe import POLICY_OBS_HIGH, POLICY_OBS_LOW, MergeObservation
from sim.env.config import MergeEnvConfig, resolve_config
from sim.env.core import EnvCore, end_flags, removed_info
from sim.env.seeds import reset_seed, unread_options
from sim.runtime.hooks import FrameState
from sim.runtime.session import SumoSession

#: Bounds of the observation ``Box`` in ft, ft/s (``units="ft"``): the policy observation's
#: (:func:`sim.drivers.observe.policy_rows`).
OBS_LOW, OBS_HIGH = POLICY_OBS_LOW, POLICY_OBS_HIGH
#: SUMO runs in a row that may end without a take-over before ``reset`` gives up.
MAX_EMPTY_RUNS = 3
#: The render modes (:mod:`sim.env.render`).
RENDER_MODES = ("rgb_array",)

__all__ = ["MAX_EMPTY_RUNS", "MergeEnv", "OBS_HIGH", "OBS_LOW", "RENDER_MODES", "make_env"]


def check_render_mode(render_mode: str | None) -> str | None:
    """``render_mode`` when it is None or one of :data:`RENDER_MODES`.

    Raises:
        ValueError: any other value.
    """
    if render_mode is not None and render_mode not in RENDER_MODES:
        raise ValueError(f"render_mode must be None or one of {RENDER_MODES}, got {render_mode!r}")
    return render_mode


class MergeEnv(gym.Env):
    """The merge as a Gymnasium environment (module docstring: spaces, episodes, rewards, seeds).

    Args:
        scenario: the scenario (``MergeEnvConfig.scenario``; positional, as before).
        config: a :class:`~sim.env.config.MergeEnvConfig` or a mapping of its fields (None: defaults).
        render_mode: None or ``"rgb_array"`` (``render()`` returns the current frame,
            ``uint8[160, 960, 3]``: :mod:`sim.env.render`).
        **overrides: any field of :class:`~sim.env.config.MergeEnvConfig` (``action_type``,
            ``reward``, ``controller``, ``run_s``, ``acc_bounds_mps2``, ``units``), over ``config``.

    Raises:
        ValueError: an unknown ``action_type``, ``units`` or ``render_mode``, bad bounds.
        TypeError: an unknown setting; ``reward`` neither a name, a path, a callable nor None;
            ``controller`` not a :class:`~sim.closed_loop.config.ControllerConfig`.
        KeyError, FileNotFoundError, irl.errors.ModelFileError: a reward file that is missing or
            has no reward.
        merge_irl.registry.RegistryError (a KeyError): an unknown reward or observation name (the
            names listed).
        scenarios.errors.SpecError: an unknown scenario, or ``run_s`` not a possible and plausible
            duration for it (positive, longer than its warm-up, at most 6 h unless the spec allows
            implausible values).
    """

    metadata: dict[str, Any] = {"render_modes": list(RENDER_MODES), "render_fps": 10}

    def __init__(self, scenario: Any = None, *, config: MergeEnvConfig | Mapping[str, Any] | None = None,
                 render_mode: str | None = None, **overrides: Any):
        if scenario is not None:
            overrides = {"scenario": scenario, **overrides}
        self.render_mode = check_render_mode(render_mode)
        self.config = resolve_config(config, overrides)
        self._core = EnvCore(self.config)
        self.spec_ = self._core.spec
        self.action_type = self.config.action_type
        self.run_s = float(self.config.run_s)
        self.controller_config = self.config.controller
        self.reward_fn = self._core.reward_fn
        self._agent = self._core.agent
        self.observation_space = self._core.observation_space
        self.action_space = self._core.action_space
        self._session: SumoSession | None = None
        self._ctl: Controller | None = None
        self._control: Control | None = None
        self._pending: tuple[FrameState, int, int | None, MergeObservation] | None = None
        self._frame: FrameState | None = None  # the last frame the agent saw (for render())
        self._renderer: Any = None
        self._last_obs = np.zeros(self.observation_space.shape or ())
        self._run_seed = -1
        self._time_s = math.nan  # simulated time of the last frame the agent saw
        #: Called as ``listener(ctx, controller, frame)`` with every frame of an episode, from the
        #: take-over to the release, once the controller is done with it (A's decision in that frame
        #: applied): what a step hook after the controller sees in the closed loop
        #: (:class:`analysis.recording.episodes.RecordRerun` writes the episodes to rerun so).
        self.frame_listeners: list[Callable[[Any, Controller, FrameState], None]] = []

    # -- Gymnasium API --------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start the next episode: a new SUMO run with ``seed`` (given), or the current run's next
        take-over (a new run, seeded from the environment's generator, when none is left).

        ``seed``: any integer ``>= 0`` (64-bit ones, as Minari's ``DataCollector`` draws, included),
        run as the SUMO seed :func:`sim.env.seeds.sumo_seed` maps it to (itself below ``2**31``).

        Raises:
            sim.env.seeds.SeedError: ``seed`` a bool, a float, negative or not an integer.
            ValueError: ``options`` holds any key but a data collector's own
                (:data:`sim.env.seeds.COLLECTOR_OPTIONS`): this environment reads none (they used
                to be ignored silently); the scenario, reward and driving are set when it is made.
            sim.errors.SimulationError: SUMO fails, or ``MAX_EMPTY_RUNS`` runs in a row have no take-over.
        """
        if unread := unread_options(options):
            raise ValueError(f"MergeEnv.reset: options {unread} are not read by this environment "
                             "(it takes none); set the scenario, reward and action space when making it "
                             "(gymnasium.make('MergeIRL/OnRampMerge-v0', scenario=..., reward=...)) and the run "
                             "with reset(seed=...)")
        checked = reset_seed(seed, "MergeEnv.reset")
        super().reset(seed=checked.seed if checked is not None else None)
        if checked is not None:
            self._start_run(checked.sumo)
        elif self._session is None or self._session.done:
            self._start_run(self._draw_seed())
        elif self._control is not None and self._control.active:  # an episode left unfinished
            assert self._ctl is not None
            self._ctl.release(self._control, self._ctl.last_frame, "end_of_run", present=True)
        self._control = None
        for _ in range(MAX_EMPTY_RUNS):
            if self._find_take_over():
                assert self._pending is not None
                obs = self._pending[3]
                self._last_obs = self._core.observation(obs)
                return self._last_obs.copy(), self._info(obs)
            self._start_run(self._draw_seed())
        from sim.errors import SimulationError

        raise SimulationError(f"MergeEnv.reset: {MAX_EMPTY_RUNS} SUMO runs of {self.run_s:g} s of scenario "
                              f"{self.spec_.name!r} had no take-over (no merge with a lag car)")

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Apply ``action`` for one decision step and run SUMO to A's next decision or release.

        Raises:
            RuntimeError: no episode is running (call ``reset``).
            ValueError: an action outside the action space (discrete: not one integer 0..4, a bool
                or a fractional number included; continuous: not one finite number).
            sim.errors.RewardError (a ValueError): the reward returned no finite real number.
        """
        if self._pending is None or self._control is None or self._ctl is None or self._session is None:
            raise RuntimeError("MergeEnv.step: no episode is running; call reset() first")
        c, ctl = self._control, self._ctl
        frame, ia, ic, obs = self._pending
        if self._core.removed(self._session, [c]):  # A removed since the last step: nothing to apply
            self._core.parse_action(action)  # an action outside the space is still refused
            self._core.release_removed(ctl, c)
            self._pending = None
            info = {**self._info(None), "release_reason": c.reason, "collision_kind": c.collision_kind,
                    **removed_info(c), "rewards": {}}
            return self._last_obs.copy(), self._core.outcome_terms(c, info), *end_flags(c), info
        reward, step_info = self._core.apply(ctl, c, frame, ia, ic, obs, action)
        self._pending = None
        self._tell(frame)
        while True:
            st = self._session.step()
            if st is None:
                ctl.release(c, ctl.last_frame, "end_of_run", present=True)
                break
            due = ctl.advance(st.frame, max_take_overs=0)
            self._time_s = st.frame.time_s
            self._frame = st.frame
            if not c.active:
                o = self._core.observe_at_release(ctl, c, st.frame)
                if o is not None:
                    self._last_obs = self._core.observation(o)
                self._tell(st.frame)
                break
            for dc, ia2, ib2, ic2 in due:
                if dc is c:
                    o = ctl.observe(c, st.frame, ia2, ib2, ic2)
                    self._pending = (st.frame, ia2, ic2, o)
                    self._last_obs = self._core.observation(o)
                    return self._last_obs.copy(), reward, False, False, {**self._info(o), **step_info}
            self._tell(st.frame)
        terminated, truncated = end_flags(c)
        info = {**self._info(None), **step_info, "release_reason": c.reason, "collision_kind": c.collision_kind}
        return self._last_obs.copy(), reward + self._core.outcome_terms(c, info), terminated, truncated, info

    def render(self) -> np.ndarray | None:
        """The current frame, ``uint8[160, 960, 3]`` (``render_mode="rgb_array"``; None without a
        render mode or before the first ``reset``): the section's lanes, A red, B orange, C blue,
        the others grey, each of A, B, C lettered, under a header with the clock, the legend and
        a scale bar (:class:`sim.env.render.TopDownRenderer`)."""
        if self.render_mode is None or self._frame is None or self._session is None or self._ctl is None:
            return None
        if self._renderer is None:
            from sim.env.render import TopDownRenderer

            assert self._session.context is not None
            self._renderer = TopDownRenderer(self._session.context)
        roles = dict(self._ctl.role_rows)
        c = self._control
        if c is not None and not c.active:  # released in this frame: still shown as A and B
            for vid, role in ((c.a_id, "A"), (c.b_id, "B")):
                if (row := self._ctl.rows.get(vid)) is not None:
                    roles[row] = role
        return self._renderer.frame(self._frame, roles)

    def close(self) -> None:
        """Close SUMO (idempotent)."""
        if self._session is not None:
            self._session.close()
        self._session = None
        self._ctl = None
        self._control = None
        self._pending = None
        self._frame = None
        super().close()

    # -- internals ------------------------------------------------------------------------
    def _tell(self, frame: FrameState) -> None:
        for listener in self.frame_listeners:
            assert self._session is not None and self._ctl is not None
            listener(self._session.context, self._ctl, frame)

    def _draw_seed(self) -> int:
        return int(self.np_random.integers(0, 2**31 - 1))

    def _start_run(self, seed: int) -> None:
        if self._session is not None:
            self._session.close()
        self._session = None
        self._session, self._ctl = self._core.start(seed)
        self._renderer = None
        self._run_seed = seed
        self._control = None
        self._pending = None

    def _find_take_over(self) -> bool:
        """Step the current run to the agent's first decision; False when the run ends first."""
        assert self._session is not None and self._ctl is not None
        ctl = self._ctl
        while (st := self._session.step()) is not None:
            due = ctl.advance(st.frame, max_take_overs=1 if self._control is None else 0)
            if self._control is None:
                new = [c for c in ctl.controls if c.active]
                if not new:
                    continue
                self._control = new[0]
            for dc, ia, ib, ic in due:
                if dc is self._control:
                    self._frame = st.frame
                    self._pending = (st.frame, ia, ic, ctl.observe(dc, st.frame, ia, ib, ic))
                    return True
        return False

    def _info(self, obs: MergeObservation | None) -> dict[str, Any]:
        c = self._control
        if self._pending is not None:
            self._time_s = self._pending[0].time_s
        return {"state": obs.state if obs is not None else -1, "seed": self._run_seed, "time_s": self._time_s,
                "a_id": c.a_id if c is not None else 0, "b_id": c.b_id if c is not None else 0}


def make_env(**kwargs: Any) -> Callable[[], MergeEnv]:
    """A factory for ``gymnasium.vector.AsyncVectorEnv``: ``[make_env(**kw)] * n`` starts one
    :class:`MergeEnv` (one SUMO) in each worker process."""
    def thunk() -> MergeEnv:
        return MergeEnv(**kwargs)
    return thunk
