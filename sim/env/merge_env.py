"""The on-ramp merge as a Gymnasium environment: the lag car A is the agent, SUMO drives the rest.

One episode is one take-over of the closed-loop controller (:mod:`sim.closed_loop.controller`): it starts
when a merging car B on the ramp reaches the take-over zone and its lag car A in the merge lane
is handed to the agent, and it ends when the controller releases A (B merged and the hold
passed, a collision, A left the section or its lane, B vanished, ``max_control_s``). Every
``decision_step_s`` (0.3 s by default) the agent chooses A's action; the controller applies it
exactly as it applies a driver's (:meth:`sim.closed_loop.controller.Controller.apply`). Everything else,
including every other merge of the run, is SUMO's.

Spaces:

* observation: ``Box(OBS_LOW, OBS_HIGH, (7,), float64)``, the driver's continuous observation
  as a policy sees it (:func:`sim.drivers.observe.policy_observation`, filled and clipped), columns
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
``action_bin`` (the applied acceleration's merge action, step only), ``acc_ft_s2`` (applied),
``release_reason`` (one of :data:`sim.closed_loop.records.RELEASE_REASONS`, at the episode's end),
``collision_kind``, ``seed`` (the SUMO run's), ``time_s``, ``a_id`` / ``b_id`` (Vehicle_IDs).

Termination (Gymnasium's terms): ``terminated`` when the controller releases A for a reason of the
merge itself (``merge_done``, ``collision``, ``left_section``, ``left_lane``, ``b_lost``,
``arrived``, ``removed``, ``teleported``); ``truncated`` at a time limit (``timeout``:
``max_control_s`` of :class:`~sim.closed_loop.config.ControllerConfig`; ``end_of_run``: the SUMO
run reached ``run_s``). The last observation is A's at the release frame when A and B are still
in the network, else the previous one.

Reward: ``reward(obs, action_bin, acc_ft_s2)`` of the decision, returned by the step that applies it
(:mod:`sim.env.rewards`): a model file (a tabular IRL model's ``theta . phi(s, a)`` or a planning
driver's step reward), a callable, or None (0: for imitation learners, which learn their own).

Runs and seeds: ``reset(seed=s)`` starts a new SUMO run with seed ``s`` (the same seed gives the
same episode for the same actions); ``reset()`` continues the current run to its next take-over,
which saves SUMO's start and warm-up, and starts a new run (seed drawn from the environment's
generator) when none is left. libsumo runs one simulation per process: use one environment per
process, and ``gymnasium.vector.AsyncVectorEnv`` for several (see docs/environment.md).
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from irl.domains.merge.actions import ACTION_ACC_FT_S2, N_ACTIONS, action_of
from irl.domains.merge.bins import MergeBins
from irl.domains.merge.car_following import OBS_COLUMNS
from merge_irl.units import FT_PER_M
from scenarios.spec.model import ScenarioSpec
from sim.closed_loop.records import Control
from sim.closed_loop.controller import Controller
from sim.closed_loop.config import ControllerConfig
from sim.env.rewards import RewardFn, load_reward
from sim.runtime.hooks import FrameState
from sim.drivers.observe import POLICY_OBS_HIGH, POLICY_OBS_LOW, MergeObservation, policy_observation
from sim.drivers.policy import NO_LIKELIHOOD, PolicyDefaults
from sim.runtime.session import SumoSession

#: Bounds of the observation ``Box`` (ft, ft/s): the policy observation's (:func:`sim.drivers.observe.policy_rows`).
OBS_LOW, OBS_HIGH = POLICY_OBS_LOW, POLICY_OBS_HIGH
#: Release reasons that truncate an episode (a time limit); every other one terminates it.
TRUNCATING_REASONS = frozenset({"timeout", "end_of_run"})
#: SUMO runs in a row that may end without a take-over before ``reset`` gives up.
MAX_EMPTY_RUNS = 3


class _AgentPolicy(PolicyDefaults):
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


class MergeEnv(gym.Env):
    """The merge as a Gymnasium environment (module docstring: spaces, episodes, rewards, seeds).

    Args:
        scenario: a preset name (``"synthetic"``, ``"i80"``), a TOML path or a
            :class:`~scenarios.spec.model.ScenarioSpec`.
        action_type: ``"discrete"`` (``Discrete(5)``) or ``"continuous"`` (A's acceleration, m/s^2).
        reward: a model file path, a callable ``(obs, action_bin, acc_ft_s2) -> float`` or None (0).
        controller: the controller's settings (decision step, take-over zone, hold, time limit,
            ``high_brake``); its ``seed`` is unused (the agent decides).
        run_s: simulated seconds of one SUMO run (warm-up included); episodes follow each other in
            a run until it ends.
        acc_bounds_mps2: the continuous action's bounds (m/s^2).
        render_mode: None only (recordings: :mod:`analysis.recording` on a closed-loop run).

    Raises:
        ValueError: an unknown ``action_type`` or bad bounds.
        TypeError: ``reward`` neither a path, a callable nor None; ``controller`` not a
            :class:`~sim.closed_loop.config.ControllerConfig`.
        scenarios.errors.SpecError: an unknown scenario, or ``run_s`` not a possible and plausible
            duration for it (positive, longer than its warm-up, at most 6 h unless the spec allows
            implausible values).
    """

    metadata: dict[str, Any] = {"render_modes": []}

    def __init__(self, scenario: str | os.PathLike | ScenarioSpec = "synthetic", *, action_type: str = "discrete",
                 reward: str | os.PathLike | RewardFn | None = None,
                 controller: ControllerConfig = ControllerConfig(decision_step_s=0.3),
                 run_s: float = 1800.0, acc_bounds_mps2: tuple[float, float] = (-9.0, 4.0),
                 render_mode: str | None = None):
        if action_type not in ("discrete", "continuous"):
            raise ValueError(f"action_type must be 'discrete' or 'continuous', got {action_type!r}")
        lo, hi = (float(x) for x in acc_bounds_mps2)
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < 0 < hi):
            raise ValueError(f"acc_bounds_mps2 must be (negative, positive) m/s^2, got {acc_bounds_mps2!r}")
        if render_mode is not None:
            raise ValueError(f"render_mode: this environment renders nothing, got {render_mode!r}")
        if not (reward is None or isinstance(reward, str | os.PathLike) or callable(reward)):
            raise TypeError(f"reward must be a model file path, a callable (obs, action_bin, acc_ft_s2) -> float "
                            f"or None, got {type(reward).__name__} {reward!r}")
        if not isinstance(controller, ControllerConfig):
            raise TypeError(f"controller must be a sim.closed_loop.config.ControllerConfig, got "
                            f"{type(controller).__name__}")
        if isinstance(scenario, ScenarioSpec):
            self.spec_ = scenario
        else:
            from scenarios.loader import load_scenario

            self.spec_ = load_scenario(scenario if isinstance(scenario, str) else Path(scenario))
        from scenarios.spec.parse import with_overrides

        with_overrides(self.spec_, duration_s=run_s)  # refuse a bad run_s now, not at the first reset
        self.action_type = action_type
        self.run_s = float(run_s)
        self.controller_config = controller
        self.reward_fn: RewardFn | None = load_reward(reward) if isinstance(reward, str | os.PathLike) else reward
        # a reward over discrete states (a tabular model's) brings the bins to encode them with
        encoder = getattr(self.reward_fn, "encoder", None) or MergeBins.assumed_authors()
        acc5 = tuple(getattr(self.reward_fn, "action_acc_ft_s2", ()) or ACTION_ACC_FT_S2)
        self._agent = _AgentPolicy(encoder, str(getattr(self.reward_fn, "state_encoding", "paper") or "paper"),
                                   tuple(float(x) for x in acc5))
        self.observation_space = spaces.Box(OBS_LOW, OBS_HIGH, dtype=np.float64)
        self.action_space: spaces.Space[Any] = (
            spaces.Discrete(N_ACTIONS) if action_type == "discrete"
            else spaces.Box(np.float32(lo), np.float32(hi), shape=(1,), dtype=np.float32))
        self.render_mode = render_mode
        self._session: SumoSession | None = None
        self._ctl: Controller | None = None
        self._control: Control | None = None
        self._pending: tuple[FrameState, int, int | None, MergeObservation] | None = None
        self._last_obs = np.zeros(len(OBS_COLUMNS))
        self._run_seed = -1
        self._time_s = math.nan  # simulated time of the last frame the agent saw

    # -- Gymnasium API --------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start the next episode: a new SUMO run with ``seed`` (given), or the current run's next
        take-over (a new run, seeded from the environment's generator, when none is left).

        Raises:
            ValueError: ``options`` holds any key: this environment reads none (issue 35: they
                were ignored silently); the scenario, reward and driving are set when it is made.
            sim.errors.SimulationError: SUMO fails, or ``MAX_EMPTY_RUNS`` runs in a row have no take-over.
        """
        if options:
            raise ValueError(f"MergeEnv.reset: options {sorted(map(str, options))} are not read by this environment "
                             "(it takes none); set the scenario, reward and action space when making it "
                             "(gymnasium.make('MergeIRL/OnRampMerge-v0', scenario=..., reward=...)) and the run "
                             "with reset(seed=...)")
        super().reset(seed=seed)
        if seed is not None:
            self._start_run(int(seed))
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
                self._last_obs = policy_observation(obs)
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
        """
        if self._pending is None or self._control is None or self._ctl is None or self._session is None:
            raise RuntimeError("MergeEnv.step: no episode is running; call reset() first")
        c, ctl = self._control, self._ctl
        frame, ia, ic, obs = self._pending
        if self.action_type == "discrete":
            arr = np.asarray(action)
            if (arr.size != 1 or arr.dtype.kind not in "iuf"
                    or (arr.dtype.kind == "f" and not float(arr.item()).is_integer())):
                raise ValueError(f"action must be an integer in 0..{N_ACTIONS - 1}, got {action!r}")
            a = int(arr.item())
            if not 0 <= a < N_ACTIONS:
                raise ValueError(f"action must be in 0..{N_ACTIONS - 1}, got {action!r}")
            acc = ctl.apply(c, frame, ia, ic, obs, np.eye(N_ACTIONS)[a], a)
        else:
            arr = np.asarray(action)
            if arr.size != 1 or arr.dtype.kind not in "iuf" or not np.isfinite(arr).all():
                raise ValueError(f"action must be one finite acceleration (m/s^2), got {action!r}")
            acc_mps2 = float(np.clip(arr.astype(np.float64).reshape(-1)[0],
                                     self.action_space.low[0], self.action_space.high[0]))  # type: ignore[attr-defined]
            a = action_of(acc_mps2 * FT_PER_M)
            acc = ctl.apply(c, frame, ia, ic, obs, np.eye(N_ACTIONS)[a], a, acc_ft_s2=acc_mps2 * FT_PER_M)
        applied_bin = action_of(acc)
        reward = float(self.reward_fn(obs, applied_bin, acc)) if self.reward_fn is not None else 0.0
        self._pending = None
        step_info = {"action_bin": applied_bin, "acc_ft_s2": acc}
        while True:
            st = self._session.step()
            if st is None:
                ctl.release(c, ctl.last_frame, "end_of_run", present=True)
                break
            due = ctl.advance(st.frame, max_take_overs=0)
            self._time_s = st.frame.time_s
            if not c.active:
                self._observe_at_release(st.frame)
                break
            for dc, ia2, ib2, ic2 in due:
                if dc is c:
                    o = ctl.observe(c, st.frame, ia2, ib2, ic2)
                    self._pending = (st.frame, ia2, ic2, o)
                    self._last_obs = policy_observation(o)
                    return self._last_obs.copy(), reward, False, False, {**self._info(o), **step_info}
        truncated = c.reason in TRUNCATING_REASONS
        info = {**self._info(None), **step_info, "release_reason": c.reason, "collision_kind": c.collision_kind}
        return self._last_obs.copy(), reward, not truncated, truncated, info

    def close(self) -> None:
        """Close SUMO (idempotent)."""
        if self._session is not None:
            self._session.close()
        self._session = None
        self._ctl = None
        self._control = None
        self._pending = None
        super().close()

    # -- internals ------------------------------------------------------------------------
    def _draw_seed(self) -> int:
        return int(self.np_random.integers(0, 2**31 - 1))

    def _start_run(self, seed: int) -> None:
        if self._session is not None:
            self._session.close()
        self._session = SumoSession(self.spec_, seed, duration_s=self.run_s, record=False)
        self._ctl = Controller(self._agent, self.controller_config)
        ctx = self._session.start()
        self._ctl.on_start(ctx)
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
                    self._pending = (st.frame, ia, ic, ctl.observe(dc, st.frame, ia, ib, ic))
                    return True
        return False

    def _observe_at_release(self, frame: FrameState) -> None:
        c, ctl = self._control, self._ctl
        assert c is not None and ctl is not None
        rows = dict(zip(frame.vehicle_id.tolist(), range(len(frame.sumo_ids))))
        ia, ib = rows.get(c.a_id), rows.get(c.b_id)
        if ia is None or ib is None:
            return
        from sim.drivers.observe import lead_of

        ic = lead_of(frame, float(frame.local_y[ia]), lane=ctl.merge_lane, exclude=(ia, ib))
        self._last_obs = policy_observation(ctl.observe(c, frame, ia, ib, ic))

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
