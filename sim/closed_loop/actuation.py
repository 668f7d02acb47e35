"""How the controller's actuation reads the road ahead of A: the ``need`` variant of High Brake
(:attr:`ControllerConfig.high_brake <sim.closed_loop.config.ControllerConfig>`), which reads the
simulator's ground truth (A's true leader and its true acceleration), A's leader gap that it
and the safety filter act on, and the safety filter itself. The default, physical actuation reads neither."""

from __future__ import annotations

from typing import Any

from merge_irl.units import FT_PER_M
from sim.drivers.observe import lead_of
from sim.runtime.hooks import FrameState


def high_brake_need(v_a: float, v_lead: float, acc_lead: float, gap: float) -> float:
    """Constant deceleration (ft/s^2, >= 0) that keeps A behind its leader, the leader holding
    its own deceleration ``-acc_lead`` until it stops (A's speed ``v_a``, the leader's ``v_lead``,
    ft/s; ``gap`` ft, the bumper gap less A's minimum gap, > 0; the controller passes at least
    1 ft). With ``closing = v_a - v_lead``:

    * leader not braking (``acc_lead >= 0``): ``closing^2 / (2 gap)`` when closing (A reaches the
      leader's speed at the gap), else 0;
    * leader braking at ``d = -acc_lead``, A reaching its speed before it stops
      (``2 gap / closing <= v_lead / d``): ``d + closing^2 / (2 gap)``;
    * leader braking and stopping first: ``v_a^2 / (2 (gap + v_lead^2 / (2 d)))`` (A stops
      behind the leader's stopping point).

    Used by :attr:`ControllerConfig.high_brake <sim.closed_loop.config.ControllerConfig>` ``"need"``.
    """
    closing = v_a - v_lead
    if not acc_lead < 0.0:
        return closing * closing / (2.0 * gap) if closing > 0.0 else 0.0
    d = -acc_lead
    if closing > 0.0 and 2.0 * gap / closing <= v_lead / d:
        return d + closing * closing / (2.0 * gap)
    return max(v_a, 0.0) ** 2 / (2.0 * (gap + v_lead * v_lead / (2.0 * d)))


def leader_gap(frame: FrameState, ia: int, *, lane: int) -> tuple[int, float] | None:
    """A's leader in ``lane`` (the merge lane A is controlled in; I-80: 6), as its row, and the
    bumper gap to it (ft), or None without a leader: what the safety filter and High Brake by
    need act on."""
    ya = float(frame.local_y[ia])
    il = lead_of(frame, ya, lane=lane, exclude=(ia,))
    if il is None:
        return None
    return il, float(frame.local_y[il]) - ya - float(frame.length[il])


def safe_action(frame: FrameState, ia: int, action: int, acc_table, step_s: float, ttc_min: float, *,
                lane: int) -> int:
    """The safety filter (``ControllerConfig.safety_ttc_s``): ``action``, or the nearest
    harder-braking one whose predicted gap to A's leader in ``lane`` (:func:`leader_gap`) stays positive with a closing
    TTC of at least ``ttc_min`` (s) after one decision step of ``step_s`` (s), A at the actions'
    accelerations ``acc_table`` (ft/s^2, by action), its leader at constant speed (see
    :class:`~sim.closed_loop.config.ControllerConfig`); High Brake (0) if none does."""
    leader = leader_gap(frame, ia, lane=lane)
    if leader is None:
        return action
    il, gap = leader
    h = step_s
    va, vl = float(frame.speed[ia]), float(frame.speed[il])
    for a in range(action, -1, -1):
        v1 = max(0.0, va + float(acc_table[a]) * h)
        g1 = gap - 0.5 * (va + v1) * h + vl * h
        closing = v1 - vl
        if g1 > 0 and (closing <= 1e-9 or g1 / closing >= ttc_min):
            return a
    return 0


def brake_to_need(frame: FrameState, ia: int, acc: float, a_sumo: str, vehicle: Any, *, lane: int) -> float:
    """The High Brake acceleration (ft/s^2) of ``ControllerConfig.high_brake == "need"``:
    ``acc`` (the action's), or harder when A closes in on its leader in ``lane`` (:func:`leader_gap`) faster than
    ``acc`` stops it, by need at most A's ``decel`` (see :class:`~sim.closed_loop.config.ControllerConfig`).
    ``vehicle`` is libsumo's ``vehicle`` domain (A's minimum gap and ``decel``)."""
    leader = leader_gap(frame, ia, lane=lane)
    if leader is None:
        return acc
    il, bumper_gap = leader
    gap = max(bumper_gap - vehicle.getMinGap(a_sumo) * FT_PER_M, 1.0)
    need = high_brake_need(float(frame.speed[ia]), float(frame.speed[il]), float(frame.acc[il]), gap)
    return min(acc, max(-need, -vehicle.getDecel(a_sumo) * FT_PER_M))  # never softer than the action's own
