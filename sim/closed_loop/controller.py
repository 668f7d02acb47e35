"""The closed-loop controller: a step hook that hands merge lag cars A to a policy.

Lanes are those of the run's site profile (:attr:`sim.runtime.hooks.RunContext.site`); I-80's numbers below.
Selection (default): every vehicle B on the ramp / auxiliary lane (lane 7) that reaches the
take-over zone (``Local_Y >= zone_start_ft``) gets, once, a lag car A: the nearest lane-6
vehicle strictly behind B's ``Local_Y`` within ``max_lag_ft`` that is not already controlled
(the rule :mod:`sim.merges.take_over` applies to recorded tables).
From then on, every ``decision_step_s`` seconds the controller observes A, B and C (C = A's lead
car: the nearest lane-6 vehicle ahead of A, other than B), encodes the state and asks the policy
for its decision: a driver with a fitted decision rule (``decide``, the planning driver's most
likely acceleration: :func:`sim.drivers.policy.fitted_decision`) is driven by that rule
(``ControllerConfig.rule="fitted"``, the default); any other driver's action is sampled from its
action distribution ``probs`` (or its mode, ``mode=True``). ``probs`` is logged with every decision
either way (the driver's likelihood model). The controller applies the action's
acceleration (the rule's own, else the driver's for the action) (High Brake harder when A needs it to stop behind its leader, up to A's ``decel``:
``ControllerConfig.high_brake``) with ``vehicle.setSpeedMode(A, 0)`` + ``setLaneChangeMode(A, 0)`` +
``setAcceleration``: SUMO neither changes A's lane nor its speed on its own. A policy with
``controls = False`` (the SUMO baseline) is observed and logged the same way but never
commanded.

Release: the controller restores A's speed mode and lane-change mode (and hands the speed
back to SUMO) and records why, in :attr:`Control.reason <sim.closed_loop.records.Control.reason>`:

``merge_done``  B merged (first lane-6 frame) and ``hold_after_merge_s`` has passed;
``left_section`` A's ``Local_Y`` passed the end of the section (or A's route ended there);
``left_lane``   A left lane 6 (only SUMO's driver with lane changes on can; demonstrations end there too);
``collision``   A was in a collision (``simulation.getCollidingVehiclesIDList``);
``teleported``  SUMO teleported A;
``arrived``     A reached the end of its route elsewhere;
``removed``     A vanished from the network for any other reason;
``b_lost``      B vanished before merging;
``timeout``     A was controlled for ``max_control_s``;
``end_of_run``  the run ended first;
``removed_externally`` (the environments of :mod:`sim.env` only) A vanished between two ``step`` calls.

Who hit whom in a collision is in :attr:`Control.collision_kind <sim.closed_loop.records.Control.collision_kind>`
(one of ``COLLISION_KINDS``). Settings: :mod:`sim.closed_loop.config`; records: :mod:`sim.closed_loop.records`;
take-overs and releases: :mod:`sim.closed_loop.handover` (an object the controller holds, :attr:`Controller.hand_over`); the observation:
:mod:`sim.closed_loop.observation`; the safety filter and High Brake by need: :mod:`sim.closed_loop.actuation`.
The run continues after every release. Decisions are kept in :attr:`Controller.decisions`
(one row per decision) and control episodes in :attr:`Controller.controls`.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from irl.domains.merge.actions import HIGH_BRAKE, N_ACTIONS, action_of
from irl.domains.merge.mdp import DEFAULT_DECISION_STEP_S
from merge_irl.units import M_PER_FT
from sim.closed_loop.actuation import brake_to_need, safe_action
from sim.closed_loop.config import ControllerConfig
from sim.closed_loop.handover import HandOver
from sim.closed_loop.observation import control_observation
from sim.closed_loop.records import Control, DecisionLog
from sim.drivers.observe import MergeObservation, lead_of
from sim.drivers.policy import Policy, check_policy, choose_action, fitted_decision
from sim.runtime.hooks import FrameState, RunContext

__all__ = ["Controller"]


class Controller:
    """A :class:`sim.runtime.hooks.StepHook` that drives merge lag cars with ``policy``.

    After the run, :attr:`controls` lists every control episode and :meth:`decision_table`
    gives the decisions. :attr:`last` maps A's Vehicle_ID to its latest
    ``(observation, probs [5], action)`` for loggers that run after this hook in the same
    frame; :attr:`decided` holds the As that decided in the current frame; :attr:`roles` maps Vehicle_ID -> role char ("A", "B", "C") for the current frame.
    Take-overs and releases are :attr:`hand_over`'s (a :class:`~sim.closed_loop.handover.HandOver`).
    """

    def __init__(self, policy: Policy, config: ControllerConfig = ControllerConfig()):
        check_policy(policy, scoring=False, where="controller")
        self.policy = policy
        self.config = config
        self.hand_over = HandOver(policy, config)
        self.controls: list[Control] = self.hand_over.controls  # the same list
        self.decisions = DecisionLog()
        self.last: dict[int, tuple[MergeObservation, np.ndarray, int]] = {}
        self.roles: dict[int, str] = {}
        self.decided: set[int] = set()  # As that took a decision in the current frame
        self.rows: dict[int, int] = {}  # Vehicle_ID -> row of the current frame
        self.role_rows: dict[int, str] = {}  # row of the current frame -> role
        self._active = self.hand_over.active  # a_id -> control (the same dict)
        self._b_seen_ramp: set[int] = set()
        self._rng: np.random.Generator | None = None
        self._every = 1
        self._traci: Any = None  # the run's SUMO handle (RunContext.sumo, untyped), set by on_start
        self.n_teleports = 0  # teleports in the whole run, all vehicles

    @property
    def decision_step_s(self) -> float:
        """Seconds between two decisions: the config's, else the policy's ``decision_step_s``,
        else (a policy for any step) :data:`irl.domains.merge.mdp.DEFAULT_DECISION_STEP_S`."""
        if self.config.decision_step_s is not None:
            return float(self.config.decision_step_s)
        step = self.policy.decision_step_s
        return float(step) if step is not None else DEFAULT_DECISION_STEP_S

    # -- hook protocol -------------------------------------------------------------------
    def on_start(self, ctx: RunContext) -> None:
        self._traci = ctx.sumo
        cfg = self.config
        self._every = max(1, int(round(self.decision_step_s / ctx.frame_s)))
        self._frame_s = ctx.frame_s
        seed = cfg.seed if cfg.seed is not None else int(ctx.seed)
        self._rng = np.random.default_rng(seed)
        self.hand_over.start(ctx, ctx.sumo)

    def on_step(self, ctx: RunContext, frame: FrameState) -> None:
        for c, ia, ib, ic in self.advance(frame):
            obs = self.observe(c, frame, ia, ib, ic)
            probs, action, acc = self.decide(c, obs)
            self.apply(c, frame, ia, ic, obs, probs, action, chosen_acc_ft_s2=acc)

    def advance(self, frame: FrameState, *, max_take_overs: int | None = None) -> list[tuple[Control, int, int, int | None]]:
        """Everything of one frame but the decisions: SUMO's collisions and teleports, the
        releases due (:meth:`release`), the take-overs (:meth:`take_over`, at most
        ``max_take_overs``; None: every one due) and the roles of the frame.

        Returns the control episodes due for a decision in this frame, with the rows of A, B
        and C (None without C) in ``frame``, in the order :meth:`on_step` decides them.
        """
        sim = self._traci.simulation
        self._last_frame = frame.frame
        # short tuples (usually empty): membership tests need no set
        colliding = sim.getCollidingVehiclesIDList()
        teleported = sim.getStartingTeleportIDList()
        arrived = sim.getArrivedIDList() if self._active else ()
        self.hand_over.note_collisions(sim.getCollisions() if colliding else ())
        self.n_teleports += len(teleported)
        rows = self._rows_of(frame) if self._active else {}
        self.rows = rows
        self.roles = {}
        self.role_rows = {}
        self.decided = set()
        # 1. track B's merge, release what must be released
        for a_id, c in list(self._active.items()):
            ib = rows.get(c.b_id)
            ia = rows.get(a_id)
            if c.merge_frame < 0 and ib is not None and frame.lane_id[ib] == self.merge_lane:
                c.merge_frame = frame.frame
                c.b_ahead = bool(ia is not None and frame.local_y[ib] > frame.local_y[ia])
            reason = self.hand_over.release_reason(c, frame, ia, ib, colliding, teleported, arrived)
            if reason:
                # a teleported car is still known to SUMO (off the road for a while): it gets its
                # own speed and lane-change modes back like any other released car
                self.release(c, frame.frame, reason, present=ia is not None or reason == "teleported")
        # 2. new take-overs
        if max_take_overs is None or max_take_overs > 0:
            self.take_over(frame, limit=max_take_overs)
        if self._active and not rows:
            rows = self.rows = self._rows_of(frame)
        # 3. roles, and the decisions due
        due: list[tuple[Control, int, int, int | None]] = []
        for a_id, c in self._active.items():
            ia, ib = rows[a_id], rows[c.b_id]
            c.last_y = float(frame.local_y[ia])
            # C is A's lead car in lane 6 other than B: in every demonstration (sim.merges.encounters) C is
            # the lead of the gap A-C that B merges into, so it is ahead of A and nothing is between
            # them; B's lead would be a car behind A while B is behind A, and would hide A's real
            # lead car while B drives ahead of it on the ramp (collisions "A into other")
            ic = lead_of(frame, float(frame.local_y[ia]), lane=self.merge_lane, exclude=(ia, ib))
            self.roles[a_id] = "A"
            self.roles[c.b_id] = "B"
            self.role_rows[ia] = "A"
            self.role_rows[ib] = "B"
            if ic is not None:
                self.roles.setdefault(int(frame.vehicle_id[ic]), "C")
                self.role_rows.setdefault(ic, "C")
            if (frame.frame - c.start_frame) % self._every == 0:
                due.append((c, ia, ib, ic))
        return due

    def on_end(self, ctx: RunContext) -> None:
        for c in list(self._active.values()):
            self.release(c, self._last_frame, "end_of_run", present=True)

    @property
    def merge_lane(self) -> int:
        """The lane code A is controlled in (the run's site profile's merge lane; I-80: 6)."""
        return self.hand_over.merge_lane

    @property
    def n_collisions(self) -> int:
        """Distinct (collider, victim) pairs that collided in the whole run, all vehicles."""
        return self.hand_over.n_collisions

    def take_over(self, frame: FrameState, *, limit: int | None = None) -> list[Control]:
        """Hand new lag cars A to the policy (:meth:`sim.closed_loop.handover.HandOver.take_over`);
        returns the new control episodes (also in :attr:`controls`)."""
        return self.hand_over.take_over(frame, limit=limit)

    def release(self, c: Control, frame_no: int, reason: str, *, present: bool) -> None:
        """End control episode ``c`` at ``frame_no`` for ``reason`` and hand A back to SUMO
        (:meth:`sim.closed_loop.handover.HandOver.release`); A leaves :attr:`last`."""
        self.hand_over.release(c, frame_no, reason, present=present)
        self.last.pop(c.a_id, None)

    @property
    def last_frame(self) -> int:
        """Frame_ID of the last frame :meth:`advance` saw (-1: none)."""
        return self._last_frame

    # -- internals ----------------------------------------------------------------------
    _last_frame = -1

    @staticmethod
    def _rows_of(frame: FrameState) -> dict[int, int]:
        return dict(zip(frame.vehicle_id.tolist(), range(len(frame.sumo_ids))))

    def observe(self, c: Control, frame: FrameState, ia: int, ib: int, ic: int | None) -> MergeObservation:
        """What A (row ``ia``) sees of B (``ib``) and C (``ic``, None without C) at ``frame``, with the
        state encoded by the policy's encoder (-1 without one). Reads, changes nothing
        (:func:`sim.closed_loop.observation.control_observation`)."""
        return control_observation(self.policy, c, frame, ia, ib, ic, self._every * self._frame_s)

    def decide(self, c: Control, obs: MergeObservation) -> tuple[np.ndarray, int, float | None]:
        """The policy's decision: ``(probs [5], action, acc_ft_s2)``. ``probs`` is the driver's
        likelihood model (logged). A driver with a fitted decision rule decides by it
        (``rule="fitted"``): its action and acceleration (ft/s^2); otherwise the action is
        sampled from ``probs`` with the controller's generator (its mode with ``mode=True``) and
        ``acc_ft_s2`` is None (:meth:`apply` takes the driver's acceleration for the action). For
        a policy that does not command A (``controls = False``), ``(probs, -1, None)``:
        :meth:`apply` then logs what SUMO did.

        Raises:
            PolicyError: the driver's rule answered no action 0..4 with a finite acceleration.
        """
        probs = np.asarray(self.policy.probs(obs), dtype=np.float64)
        if not c.commanded:
            return probs, -1, None
        rule = fitted_decision(self.policy, obs) if self.config.rule == "fitted" else None
        if rule is not None:
            return probs, rule[0], rule[1]
        assert self._rng is not None, "on_start seeds the generator before any step"
        return probs, choose_action(probs, self._rng, mode=self.config.mode), None

    def apply(self, c: Control, frame: FrameState, ia: int, ic: int | None, obs: MergeObservation, probs: np.ndarray,
              action: int, *, acc_ft_s2: float | None = None, chosen_acc_ft_s2: float | None = None) -> float:
        """Apply ``action`` to A (row ``ia``; C at row ``ic``, None without C) as the controller applies every decision, and log it:
        the safety filter (``safety_ttc_s``), the action's acceleration (``chosen_acc_ft_s2``, the
        driver's fitted rule's, when given and the filter kept the action, else
        ``policy.acceleration``; ``high_brake="need"``), capped at A's emergency deceleration, held for one decision step
        with ``vehicle.setAcceleration``. ``acc_ft_s2`` (ft/s^2) replaces the action's acceleration
        (a continuous action; the logged action is then its bin, :func:`irl.domains.merge.actions.action_of`).
        Not commanded (``c.commanded`` False): nothing is applied; the action logged is the bin of
        A's acceleration in the frame. ``probs [5]``: logged with the decision (the driver's
        likelihood model). Returns the acceleration applied (ft/s^2).
        """
        c_id = int(frame.vehicle_id[ic]) if ic is not None else 0
        v_c = float(frame.speed[ic]) if ic is not None else math.nan
        step_s = self._every * self._frame_s
        state = obs.state
        d_ac, d_ab, v_ac, v_ab, truck = obs.d_AC, obs.d_AB, obs.v_AC, obs.v_AB, obs.b_is_truck
        filtered = need = False
        if c.commanded and acc_ft_s2 is not None:
            acc = float(acc_ft_s2)
            action = action_of(acc)
            acc = max(acc, -c.max_decel_ft_s2) if math.isfinite(c.max_decel_ft_s2) else acc  # A's physical limit
            self._traci.vehicle.setAcceleration(c.a_sumo, acc * M_PER_FT, step_s)
        elif c.commanded:
            action, acc, filtered, need = self._command(c, frame, ia, obs, action, chosen_acc_ft_s2)
            self._traci.vehicle.setAcceleration(c.a_sumo, acc * M_PER_FT, step_s)
        else:
            acc = float(frame.acc[ia])
            action = action_of(acc)
        c.prev_action = action
        c.prev_acc = acc
        c.prev_v_c = v_c
        c.n_decisions += 1
        c.c_id = c_id
        self.decided.add(c.a_id)
        self.last[c.a_id] = (obs, probs, action)
        self.decisions.append((
            frame.frame, frame.time_s, c.a_id, c.b_id, c_id, state, action, acc, obs.speed_A,
            d_ac, d_ab, v_ac, v_ab, truck, obs.len_C, obs.len_B, *probs.tolist(), filtered, need,
        ))
        return acc

    def _command(self, c: Control, frame: FrameState, ia: int, obs: MergeObservation, action: int,
                 chosen: float | None) -> tuple[int, float, bool, bool]:
        """``(action, acc ft/s^2, filtered, need)`` A is commanded for the driver's ``action``
        (with its own acceleration ``chosen``, or None): the safety filter, the acceleration, High
        Brake by need, A's physical limit; counts interventions and need brakes on ``c``."""
        filtered = need = False
        if self.config.safety_ttc_s is not None:
            acc_table = [self.policy.acceleration(obs, a) for a in range(N_ACTIONS)]
            if chosen is not None:
                acc_table[action] = chosen
            safe = safe_action(frame, ia, action, acc_table, self._every * self._frame_s,
                               float(self.config.safety_ttc_s or 0.0), lane=self.merge_lane)
            filtered = safe != action
            action = safe
            c.n_interventions += int(filtered)
        acc = float(chosen) if chosen is not None and not filtered else float(self.policy.acceleration(obs, action))
        if action == HIGH_BRAKE and self.config.high_brake == "need":
            own = acc
            acc = brake_to_need(frame, ia, acc, c.a_sumo, self._traci.vehicle, lane=self.merge_lane)
            need = acc < own
            c.n_need_brakes += int(need)
        acc = max(acc, -c.max_decel_ft_s2) if math.isfinite(c.max_decel_ft_s2) else acc  # A's physical limit
        return action, acc, filtered, need

    # -- results ------------------------------------------------------------------------
    def decision_table(self):
        """Decisions as a DataFrame (columns ``frame, time_s, a_id, b_id, c_id, state, action,
        acc_cmd, speed_A, d_AC, d_AB, v_AC, v_AB, b_is_truck, len_C, len_B, p0..p4``)."""
        return self.decisions.to_frame()

    def control_table(self):
        """Control episodes as a DataFrame, one row per A (fields of :class:`~sim.closed_loop.records.Control`)."""
        import pandas as pd

        cols = ("a_id", "b_id", "a_sumo", "start_frame", "end_frame", "reason", "merge_frame",
                "b_ahead", "commanded", "gap_AB_start_ft", "n_decisions", "n_interventions", "n_need_brakes",
                "collision_kind", "collision_pair")
        return pd.DataFrame([{k: getattr(c, k) for k in cols} for c in self.controls], columns=list(cols))
