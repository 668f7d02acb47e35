"""SUMO's car-following model as the expert in the learner's own states (DAgger's labels).

:class:`ExpertLabels` is a step hook that runs after a :class:`sim.closed_loop.controller.Controller`: at
every decision of a controlled car A it asks SUMO's car-following model of A's vehicle type
which speed it would drive next behind C (``libsumo.vehicle.getFollowSpeed`` with the bumper
gap minus A's minGap and C's speed and deceleration; on a free road without C) and records the
action bin of that acceleration over one simulation step (capped at A's emergency deceleration
and its maximum acceleration) beside what A observed. The expert is car following only: it
does not yield to the merging car B as SUMO's lane-change model makes the demonstrators do.
DAgger: Ross, Gordon & Bagnell (2011), AISTATS, "A reduction of imitation learning and
structured prediction to no-regret online learning".
"""

from __future__ import annotations

import math
from typing import NamedTuple

import pandas as pd

from irl.domains.merge.actions import action_of
from merge_irl.units import M_PER_FT
from sim.closed_loop.controller import Controller
from sim.runtime.hooks import FrameState, RunContext

FREE_GAP_M = 1e4  # the gap given to the expert when A has no lead car C


class ExpertLabel(NamedTuple):
    """One decision of the learner and the expert's action there (ft, ft/s, action indices)."""

    state: int
    d_AC: float
    v_AC: float
    d_AB: float
    v_AB: float
    v_A: float
    len_C: float
    len_B: float
    prev: int
    action: int


class ExpertLabels:
    """Step hook after a :class:`~sim.closed_loop.controller.Controller` (module docstring).

    Attributes:
        records: one :class:`ExpertLabel` per decision of a controlled A, in decision order;
            ``prev`` is A's previous action in its control episode (before the first: the
            observation's ``initial_action``, -1 if unknown).
    """

    def __init__(self, controller: Controller):
        self.ctl = controller
        self.records: list[ExpertLabel] = []

    @property
    def labels(self) -> list[tuple[int, int]]:
        """``(state, expert action)`` per decision of a learner with a state encoder (decisions
        without an encoded state, ``state`` -1, are left out)."""
        return [(r.state, r.action) for r in self.records if r.state >= 0]

    def table(self) -> pd.DataFrame:
        """The records as a DataFrame with the columns of :class:`ExpertLabel`."""
        return pd.DataFrame(self.records, columns=list(ExpertLabel._fields))

    def on_start(self, ctx: RunContext) -> None:
        self._sumo = ctx.sumo

    def on_step(self, ctx: RunContext, frame: FrameState) -> None:
        if not self.ctl.decided:
            return
        veh = self._sumo.vehicle
        latest = {c.a_id: c for c in self.ctl.controls if c.a_id in self.ctl.decided}
        for a_id, c in latest.items():
            obs = self.ctl.last[a_id][0]
            a_sumo = ctx.sumo_id_of(a_id)
            if a_sumo is None:
                continue
            v = obs.speed_A * M_PER_FT
            ic = self.ctl.rows.get(c.c_id) if c.c_id else None
            if ic is None or not math.isfinite(obs.d_AC):  # free road: a far leader at A's own speed
                v_next = veh.getFollowSpeed(a_sumo, v, FREE_GAP_M, v, veh.getDecel(a_sumo))
            else:
                min_gap = veh.getMinGap(a_sumo)
                gap = max((obs.d_AC - float(frame.length[ic])) * M_PER_FT - min_gap, 0.0)
                v_c = float(frame.speed[ic]) * M_PER_FT
                c_sumo = ctx.sumo_id_of(c.c_id)
                c_decel = veh.getDecel(c_sumo) if c_sumo is not None else veh.getDecel(a_sumo)
                v_next = veh.getFollowSpeed(a_sumo, v, gap, v_c, c_decel)
            acc = max((v_next - v) / ctx.step_length_s, -veh.getEmergencyDecel(a_sumo))
            acc = min(acc, veh.getAccel(a_sumo))
            prev = obs.prev_action if obs.prev_action >= 0 else obs.initial_action  # as the policy saw it
            self.records.append(ExpertLabel(int(obs.state), obs.d_AC, obs.v_AC, obs.d_AB, obs.v_AB, obs.speed_A,
                                            obs.len_C, obs.len_B, int(prev), action_of(acc / M_PER_FT)))

    def on_end(self, ctx: RunContext) -> None:
        pass
