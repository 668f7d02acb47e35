"""The controller's observation assembly: what lag car A sees of B and C at a decision, as the
driver's :class:`~sim.drivers.observe.MergeObservation`, with the state encoded by the policy's
encoder (:meth:`sim.closed_loop.controller.Controller.observe`)."""

from __future__ import annotations

import math

from irl.domains.merge.actions import ZERO_ACTION, action_of
from sim.closed_loop.records import Control
from sim.drivers.observe import MergeObservation, observe
from sim.drivers.policy import Policy
from sim.runtime.hooks import FrameState


def control_observation(policy: Policy, c: Control, frame: FrameState, ia: int, ib: int, ic: int | None,
                        step_s: float) -> MergeObservation:
    """What A (row ``ia``) of control episode ``c`` sees of B (``ib``) and C (``ic``, None without
    C) at ``frame``, with the state encoded by ``policy``'s encoder (-1 without one); ``step_s``
    is the controller's decision step (s), over which C's acceleration is its speed change.
    Reads, changes nothing."""
    d_ac, d_ab, v_ac, v_ab, truck = observe(frame, ia, ib, ic)
    encoder = policy.encoder
    encoding = policy.state_encoding
    # before the first decision: the bin of A's acceleration in the last frame (SUMO's, over 0.1 s)
    acc_now = float(frame.acc[ia])
    initial = action_of(acc_now) if c.prev_action < 0 and math.isfinite(acc_now) else -1
    # C's acceleration as A sees it: its speed change since the previous decision (same C only)
    c_id = int(frame.vehicle_id[ic]) if ic is not None else 0
    v_c = float(frame.speed[ic]) if ic is not None else math.nan
    acc_c = (v_c - c.prev_v_c) / step_s if c_id and c_id == c.c_id and math.isfinite(c.prev_v_c) else 0.0
    acc_prev = c.prev_acc if c.prev_action >= 0 else acc_now
    if encoder is None:
        state = -1
    elif encoding == "paper":
        state = encoder.state(d_ac, d_ab, v_ac, v_ab, truck)
    else:  # paper state x A's previous action (the initial one before the first decision, else Zero)
        prev = c.prev_action if c.prev_action >= 0 else (initial if initial >= 0 else ZERO_ACTION)
        state = encoder.state(d_ac, d_ab, v_ac, v_ab, truck, prev_action=prev, encoding=encoding)
    return MergeObservation(d_ac, d_ab, v_ac, v_ab, truck, state, float(frame.speed[ia]), c.prev_action, initial,
                            c.merge_frame >= 0, float(frame.length[ic]) if ic is not None else math.nan,
                            float(frame.length[ib]), acc_prev, acc_c)
