"""The controller's take-over and release bookkeeping, an object the controller holds
(:class:`HandOver`, :attr:`sim.closed_loop.controller.Controller.hand_over`): which lag car A is
handed to the driver when its merging car B enters the take-over zone, why and when it is handed
back to SUMO, and who hit whom when a collision ended the control. The rules are those of the
controller's module docstring; :mod:`sim.merges.take_over` applies the same selection to recorded
tables."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from merge_irl.units import FT_PER_M
from sim.closed_loop.config import ControllerConfig
from sim.closed_loop.records import Control
from sim.drivers.observe import lag_of
from sim.drivers.policy import Policy
from sim.runtime.hooks import FrameState, RunContext
from sim.runtime.lanes import aux_lane_start_ft
from sim.runtime.schema import RAMP_LANE, RIGHTMOST_MAIN_LANE

#: A that reaches the end of its route within this of the section end has left the section (ft).
EXIT_MARGIN_FT = 150.0


class HandOver:
    """Take-overs and releases of one closed-loop run, with the run's collisions.

    Args:
        policy: the driver As are handed to (its ``controls`` and ``keep_lane`` read).
        config: the controller's settings (``max_lag_ft``, the zone, hold and time-out).

    Attributes:
        controls: every control episode of the run, in take-over order.
        active: the episodes under way, by A's Vehicle_ID.
        collision_pairs: distinct ``(collider, victim)`` SUMO ids of the run's collisions.
        merge_lane: the lane code A is controlled in (the run's site profile's; I-80: 6).
    """

    def __init__(self, policy: Policy, config: ControllerConfig) -> None:
        self.policy = policy
        self.config = config
        self.controls: list[Control] = []
        self.active: dict[int, Control] = {}  # a_id -> control
        self.collision_pairs: set[tuple[str, str]] = set()
        self.merge_lane = RIGHTMOST_MAIN_LANE  # the run's site profile's, set by start
        self._handled_b: set[int] = set()
        self._frame_collisions: list[tuple[str, str]] = []  # (collider, victim) SUMO ids of the current frame
        self._traci: Any = None  # the run's SUMO handle (untyped), set by start
        self._vehicle_id_of: Any = None
        self._ramp_lane = RAMP_LANE
        self._zone_start = 0.0
        self._section_end = math.inf
        self._hold_frames = 0
        self._max_frames = 0

    def start(self, ctx: RunContext, traci: Any) -> None:
        """Take the run's geometry, site lanes and frame length from ``ctx`` (at the run's start);
        ``traci``: the run's SUMO handle (``ctx.sumo``)."""
        cfg = self.config
        self._traci = traci
        self._hold_frames = cfg.hold_frames(ctx.frame_s)
        self._max_frames = cfg.max_frames(ctx.frame_s)
        self._section_end = float(ctx.section_length_ft)
        self._zone_start = cfg.zone_start(aux_lane_start_ft(ctx))
        self._vehicle_id_of = ctx.vehicle_id_of
        self.merge_lane = int(ctx.site.merge_lane)
        self._ramp_lane = int(ctx.site.ramp_lanes[0])

    def note_collisions(self, collisions: Any) -> None:
        """This frame's collisions (SUMO's ``simulation.getCollisions()``: objects with
        ``collider`` and ``victim`` ids), added to the run's distinct pairs."""
        self._frame_collisions = [(col.collider, col.victim) for col in collisions]
        self.collision_pairs.update(self._frame_collisions)

    @property
    def n_collisions(self) -> int:
        """Distinct (collider, victim) pairs that collided in the whole run, all vehicles."""
        return len(self.collision_pairs)

    def release_reason(self, c: Control, frame: FrameState, ia: int | None, ib: int | None, colliding: Any,
                       teleported: Any, arrived: Any) -> str:
        """Why episode ``c`` ends at ``frame`` (A at row ``ia``, B at ``ib``; None: gone), given
        SUMO's colliding, teleported and arrived ids of the frame; "" while it goes on."""
        sid = c.a_sumo
        if sid in colliding:
            return "collision"
        if sid in teleported:
            return "teleported"
        if ia is None:
            if sid in arrived:  # the route ends where the section ends: a normal exit
                return "left_section" if c.last_y >= self._section_end - EXIT_MARGIN_FT else "arrived"
            return "removed"
        if frame.local_y[ia] > self._section_end:
            return "left_section"
        if frame.lane_id[ia] != self.merge_lane:
            return "left_lane"
        if c.merge_frame < 0 and ib is None:
            return "b_lost"
        if c.merge_frame >= 0 and frame.frame - c.merge_frame >= self._hold_frames:
            return "merge_done"
        if ib is None:  # B left after merging, before the hold ended
            return "merge_done"
        if frame.frame - c.start_frame >= self._max_frames:
            return "timeout"
        return ""

    def release(self, c: Control, frame_no: int, reason: str, *, present: bool) -> None:
        """End control episode ``c`` at ``frame_no`` for ``reason`` (one of
        :data:`~sim.closed_loop.records.RELEASE_REASONS`): A gets its own speed and lane-change
        modes back (when ``present``: still known to SUMO) and SUMO drives it again."""
        c.end_frame = frame_no
        c.reason = reason
        if reason == "collision":
            c.collision_kind, c.collision_pair = self._collision_kind(c)
        self.active.pop(c.a_id, None)
        if not present or c.lane_change_mode < 0:  # gone, or never taken over (SUMO's driver, lane free)
            return
        v = self._traci.vehicle
        try:
            if c.commanded:
                v.setSpeed(c.a_sumo, -1.0)
                v.setSpeedMode(c.a_sumo, c.speed_mode)
            v.setLaneChangeMode(c.a_sumo, c.lane_change_mode)
        except self._traci.TraCIException:  # the vehicle is gone after all
            pass

    def _collision_kind(self, c: Control) -> tuple[str, str]:
        """Who hit whom (``COLLISION_KINDS``) in the current frame's collisions involving A, and
        that pair as ``"collider>victim"`` (one of the run's distinct pairs, so that the A
        collisions, counted by distinct pair, never exceed :attr:`n_collisions`)."""
        for collider, victim in self._frame_collisions:
            if c.a_sumo not in (collider, victim):
                continue
            other = victim if collider == c.a_sumo else collider
            vid = self._vehicle_id_of(other) if self._vehicle_id_of is not None else None
            pair = f"{collider}>{victim}"
            if collider == c.a_sumo:
                kind = "A into B" if vid == c.b_id else "A into C" if vid is not None and vid == c.c_id else "A into other"
                return kind, pair
            return ("B into A" if vid == c.b_id else "other into A"), pair
        # SUMO listed A as colliding without a pair (not seen): a pair of its own, counted in the run's too
        self.collision_pairs.add((c.a_sumo, "?"))
        return "A into other", f"{c.a_sumo}>?"

    def take_over(self, frame: FrameState, *, limit: int | None = None) -> list[Control]:
        """Hand the lag car A of every B newly in the take-over zone (see the module docstring) to
        the policy (at most ``limit`` of them; None: all): A's lane-change mode (and, when
        commanded, its speed mode) off. Returns the new control episodes (also appended to
        :attr:`controls`)."""
        ramp = np.flatnonzero((frame.lane_id == self._ramp_lane) & (frame.local_y >= self._zone_start))
        new: list[Control] = []
        for ib in ramp:
            if limit is not None and len(new) >= limit:
                break
            b_id = int(frame.vehicle_id[ib])
            if b_id in self._handled_b:
                continue
            yb = float(frame.local_y[ib])
            ia = lag_of(frame, yb, lane=self.merge_lane, max_gap_ft=self.config.max_lag_ft)
            if ia is None:
                continue
            a_id = int(frame.vehicle_id[ia])
            if a_id in self.active or any(c.b_id == a_id for c in self.active.values()):
                continue
            self._handled_b.add(b_id)
            c = Control(
                a_id=a_id, b_id=b_id, a_sumo=frame.sumo_ids[ia], start_frame=frame.frame,
                commanded=bool(self.policy.controls), gap_AB_start_ft=yb - float(frame.local_y[ia]),
            )
            if c.commanded or self.policy.keep_lane:
                v = self._traci.vehicle
                c.lane_change_mode = v.getLaneChangeMode(c.a_sumo)
                v.setLaneChangeMode(c.a_sumo, 0)
                if c.commanded:
                    c.speed_mode = v.getSpeedMode(c.a_sumo)
                    v.setSpeedMode(c.a_sumo, 0)
                    c.max_decel_ft_s2 = float(v.getEmergencyDecel(c.a_sumo)) * FT_PER_M
            self.controls.append(c)
            self.active[a_id] = c
            new.append(c)
        return new
