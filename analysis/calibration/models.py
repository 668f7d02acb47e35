"""Car-following models replicating SUMO 1.28's update for a follower behind a replayed leader.

Both models follow what SUMO 1.28 does at a 0.1 s step with its default (ballistic) position
update, verified against libsumo in ``tests/test_calibration_replica.py``: the new speed is
computed from the state at the start of the step (own speed, bumper gap to the leader and
the leader's speed, both as the leader was at the start of the step); the position then
advances by ``(v + v_new) / 2 * dt`` (or, when the model asks for a negative speed, by the
distance to a stop at constant deceleration); new speeds below ``1e-5`` m/s become 0. The
speed goes through SUMO's ``MSCFModel::finalizeSpeed`` bounds:

``v_new = max(v_min, min(v_pos, v + accel*dt, maxSpeed))`` with
``v_min = min(v - d*dt, max(v_pos, v - emergencyDecel*dt))``,

where ``v_pos`` is the model's safe speed (the minimum of its free-road and following speeds)
and ``d`` the model's ``minNextSpeed`` deceleration (IDM: ``max(decel, min(emergencyDecel,
1.5))``; Krauss: ``decel``).

**IDM** (``MSCFModel_IDM::_v``): ``idmStepping`` defaults to 0.25 s, so SUMO does
``max(1, int(0.1/0.25 + 0.5)) = 1`` IDM iteration per 0.1 s step:
``s* = minGap + max(0, v*tau + v*(v - v_L) / (2*sqrt(accel*decel)))``,
``a = accel * (1 - (v/v0)^delta - (s*/max(gap, 0.001))^2)``, ``v_follow = max(0, v + a*dt)``;
the free-road speed is the same with gap 1e6 m, no minGap and leader speed ``v0``. The desired
speed ``v0`` is the vType's ``maxSpeed`` (speedFactor 1, lane limit not lower).

**Krauss** (sigma = 0, deterministic): ``v_safe`` = SUMO's ``maximumSafeStopSpeedBallistic``
for the gap plus the leader's braking distance ``v_L^2 / (2 decel)`` (the leader is assumed to
brake like the follower), with headway ``tau``; when that asks for more than ``decel``, SUMO's
emergency deceleration (1.2 x the deceleration needed to stop behind the braking leader,
within [decel, requested]) is used.

**Action step** (SUMO's vType ``actionStepLength``, a driver's reaction time as SUMO models it;
``simulate_follower(..., action_steps=k)``, k steps of 0.1 s): the vehicle decides only at every
k-th step from its insertion (the first step is one); there the model's speed is bounded as
above, except that the desired speed caps the speed reached when the new acceleration is held
until the next decision (``finalizeSpeed``'s ``aMax = (maxSpeed - v) / actionStepLength``). In
between it keeps its last acceleration (``v_new = v + a * dt``, no model call, no bounds;
``a = (max(v_new, 0) - v) / dt`` of the step before). Sample-and-hold, not a perception delay:
the decision uses the state at the decision step. Verified against libsumo for 0.2-1.5 s.
A new speed with ``|v_new| < 1e-5`` m/s is zeroed before the position update (SUMO's
``executeMove``), so only ``v_new <= -1e-5`` counts as a stop within the step.

All functions are vectorised: parameters and states are arrays broadcastable to one shape
(for example ``(P,)`` pairs, or ``(P, C)`` pairs x candidate parameter sets).
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from types import EllipsisType

import numpy as np

DT = 0.1
NUMERICAL_EPS = 0.001
EMERGENCY_DECEL_AMPLIFIER = 1.2
#: SUMO's NUMERICAL_EPS_SPEED (0.1 * NUMERICAL_EPS * TS): smaller new speeds become 0.
EPS_SPEED = 0.1 * NUMERICAL_EPS * DT


@dataclass(frozen=True)
class CFParams:
    """SUMO vType car-following attributes (SI units).

    Attributes:
        accel: maximum acceleration (m/s^2), SUMO ``accel``.
        decel: comfortable deceleration (m/s^2), SUMO ``decel``.
        tau: desired time headway (s), SUMO ``tau``.
        minGap: standstill gap (m), SUMO ``minGap``.
        maxSpeed: desired speed v0 (m/s), SUMO ``maxSpeed`` with ``speedFactor`` 1.
        delta: IDM acceleration exponent, SUMO ``delta`` (ignored by Krauss).
        emergencyDecel: hardest possible braking (m/s^2), SUMO ``emergencyDecel``.
    """

    accel: float = 2.6
    decel: float = 4.5
    tau: float = 1.0
    minGap: float = 2.5
    maxSpeed: float = 29.06
    delta: float = 4.0
    emergencyDecel: float = 9.0

    def as_dict(self) -> dict[str, float]:
        return {f.name: float(getattr(self, f.name)) for f in fields(self)}


#: SUMO's defaults for a passenger car (accel 2.6, decel 4.5, tau 1, minGap 2.5, delta 4,
#: emergencyDecel 9); desired speed = I-80's 65 mph limit (29.06 m/s), speedFactor 1.
SUMO_DEFAULTS = CFParams()

PARAM_NAMES: tuple[str, ...] = tuple(f.name for f in fields(CFParams))


def _finalize(v, v_pos, p, min_decel, action_step_s=DT):
    v_min_emerg = v - p["emergencyDecel"] * DT
    v_min = np.minimum(v - min_decel * DT, np.maximum(v_pos, v_min_emerg))
    v_max = np.minimum(np.minimum(v_pos, v + p["accel"] * DT), p["maxSpeed"])
    if action_step_s > DT:  # the acceleration is held until the next decision: reach maxSpeed there
        v_max = np.minimum(v_max, v + (p["maxSpeed"] - v) * (DT / action_step_s))
    return np.maximum(v_min, v_max)


def idm_next_speed(v, gap, v_leader, p, action_step_s=DT):
    """Next speed (m/s) of an IDM follower at a decision step; ``gap`` is the bumper-to-bumper
    gap (m), ``action_step_s`` the time (s) until the next decision."""
    accel, decel, tau, min_gap, v0, delta = (
        p["accel"], p["decel"], p["tau"], p["minGap"], p["maxSpeed"], p["delta"])
    two_sqrt_ab = 2.0 * np.sqrt(accel * decel)
    free_term = 1.0 - (v / np.maximum(NUMERICAL_EPS, v0)) ** delta
    s = min_gap + np.maximum(0.0, v * tau + v * (v - v_leader) / two_sqrt_ab)
    g = np.maximum(NUMERICAL_EPS, gap)
    v_follow = np.maximum(0.0, v + accel * (free_term - (s * s) / (g * g)) * DT)
    s_free = np.maximum(0.0, v * tau + v * (v - v0) / two_sqrt_ab)
    v_free = np.maximum(0.0, v + accel * (free_term - (s_free * s_free) / 1e12) * DT)
    v_pos = np.minimum(v_follow, v_free)
    return _finalize(v, v_pos, p, np.maximum(decel, np.minimum(p["emergencyDecel"], 1.5)), action_step_s)


def _max_safe_stop_speed_ballistic(g, v, decel, tau):
    """SUMO's ``maximumSafeStopSpeedBallistic`` (not on insertion)."""
    g = np.maximum(0.0, g - NUMERICAL_EPS)
    v0 = np.maximum(0.0, v)
    stop_within_tau = v0 * tau >= 2.0 * g
    a_stop = -v0 * v0 / (2.0 * np.maximum(g, 1e-300))
    x_stop = np.where(g == 0.0, np.where(v0 > 0, -np.inf, 0.0), v0 + a_stop * DT)
    btau2 = decel * tau / 2.0
    v1 = -btau2 + np.sqrt(np.maximum(btau2 * btau2 + decel * (2.0 * g - tau * v0), 0.0))
    x_go = v0 + (v1 - v0) / tau * DT
    return np.where(stop_within_tau, x_stop, x_go)


def _emergency_decel(gap2pred, v, v_leader, pred_decel, emergency):
    """SUMO's ``calculateEmergencyDeceleration``."""
    g = np.maximum(gap2pred, 1e-300)
    b1 = 0.5 * v * v / (g + 0.5 * v_leader * v_leader / pred_decel)
    b2 = 0.5 * (v * v - v_leader * v_leader) / g
    return np.where(gap2pred <= 0, emergency, np.where(b1 <= pred_decel, b1, b2))


def krauss_next_speed(v, gap, v_leader, p, action_step_s=DT):
    """Next speed (m/s) of a Krauss follower with sigma = 0 at a decision step; ``gap`` is the
    bumper gap (m), ``action_step_s`` the time (s) until the next decision.

    May be negative: SUMO's signal for "stops within this step" (see :func:`simulate_follower`).
    """
    decel, tau, emerg = p["decel"], p["tau"], p["emergencyDecel"]
    gap2pred = gap - p["minGap"]
    brake_gap_leader = v_leader * v_leader / (2.0 * decel)
    x = _max_safe_stop_speed_ballistic(gap2pred + brake_gap_leader, v, decel, tau)
    x = np.where(gap2pred >= 0, x, v - emerg * DT)
    orig = (v - x) / DT
    safe = EMERGENCY_DECEL_AMPLIFIER * _emergency_decel(gap2pred, v, v_leader, decel, emerg)
    safe = np.minimum(np.maximum(safe, decel), orig)
    x = np.where(orig > decel + NUMERICAL_EPS, v - safe * DT, x)
    v_follow = np.maximum(np.minimum(x, v + p["accel"] * DT), v - emerg * DT)
    v_free = np.minimum(v + p["accel"] * DT, p["maxSpeed"])
    v_pos = np.minimum(v_follow, v_free)
    return _finalize(v, v_pos, p, decel, action_step_s)


MODELS = {"idm": idm_next_speed, "krauss": krauss_next_speed}
#: Every model the calibration knows -> its SUMO ``carFollowModel``. ``MODELS`` (the numpy
#: replica) covers IDM and Krauss; EIDM keeps internal state between steps (reaction-time
#: action points, jerk limit, drive-off curve) and is simulated by real SUMO only
#: (:mod:`analysis.calibration.sumo_fit`).
CALIBRATION_MODELS = {"idm": "IDM", "krauss": "Krauss", "eidm": "EIDM"}
#: EIDM vType attributes written besides the common ones: its three noise sources (the Human
#: Driver Model's estimation and driving errors; SUMO 1.28 defaults sigmaleader 0.02, sigmagap
#: 0.1, sigmaerror 0.04) switched off, so that a run is deterministic, like Krauss with sigma 0.
#: Every other EIDM attribute stays at SUMO's default (treaction 0.5 s, tpreview 4 s, tPersDrive
#: 3 s, tPersEstimate 10 s, ccoolness 0.99, jerkmax 3 m/s^3, epsilonacc 1 m/s^2, taccmax 1.2 s,
#: Mflatness 2, Mbegin 0.7, stepping 0.25 s; SUMO's ``MSCFModel_EIDM`` constructor).
EIDM_NOISE_OFF: dict[str, float] = {"sigmaleader": 0.0, "sigmagap": 0.0, "sigmaerror": 0.0}


def simulate_follower(
    model: str, x_leader, v_leader, leader_length, x0, v0, params, *, lengths=None, action_steps: int = 1,
) -> tuple[np.ndarray, np.ndarray]:
    """Replay leaders, simulate followers.

    Args:
        model: "idm" or "krauss".
        x_leader, v_leader: float64[B..., T] leader front position (m) and speed (m/s).
        leader_length, x0, v0: float64[B...] leader length, follower's initial position / speed.
        params: every name in :data:`PARAM_NAMES` -> float or array broadcastable to the
            output's leading shape ``S`` (the broadcast of ``B...`` and the parameter shapes;
            e.g. pairs ``(P, 1)`` x candidates ``(C,)`` -> ``(P, C)``).
        lengths: optional int[S[0]] number of valid steps per row of the first axis, sorted in
            decreasing order; rows stop being simulated after their length (values there are
            then copies of the last valid step).
        action_steps: decisions every ``action_steps`` steps of :data:`DT` (SUMO's vType
            ``actionStepLength = action_steps * DT``), the acceleration held in between; 1 (the
            default) decides every step.
    Returns:
        (x, v): float64[S..., T] follower position and speed; step 0 is the initial state.

    Raises:
        ValueError: ``lengths`` is not sorted in decreasing order, or ``action_steps`` is not a
            positive whole number.
    """
    if isinstance(action_steps, bool) or not isinstance(action_steps, (int, np.integer)) or action_steps < 1:
        raise ValueError(f"action_steps must be a positive whole number of {DT} s steps, got {action_steps!r}")
    step = MODELS[model]
    action_s = action_steps * DT
    p = {k: np.asarray(params[k], dtype=np.float64) for k in PARAM_NAMES}
    T = np.shape(x_leader)[-1]
    shape = np.broadcast_shapes(np.shape(x0), np.shape(leader_length), *(np.shape(a) for a in p.values()),
                                np.shape(x_leader)[:-1])
    own = np.shape(x_leader)[:-1]  # leader arrays keep their own (broadcastable) leading shape
    lead = (1,) * (len(shape) - len(own)) + own
    cut = bool(lead) and lead[0] != 1  # the leader has a row per follower row: slice it too
    p = {k: np.broadcast_to(a, shape) for k, a in p.items()}
    # time-major, contiguous per step: row t of xl / vl / x / v is one step of every follower
    xl = np.ascontiguousarray(np.moveaxis(np.broadcast_to(x_leader, lead + (T,)), -1, 0))
    vl = np.ascontiguousarray(np.moveaxis(np.broadcast_to(v_leader, lead + (T,)), -1, 0))
    lsl: slice | EllipsisType = ...
    ll = np.broadcast_to(leader_length, shape)
    x, v = np.empty((T,) + shape), np.empty((T,) + shape)
    x[0], v[0] = x0, v0
    if lengths is None:
        active = np.full(T, shape[0] if shape else 1)
    else:
        lengths = np.asarray(lengths)
        if np.any(np.diff(lengths) > 0):
            raise ValueError("lengths must be sorted in decreasing order")
        active = (lengths[None, :] > np.arange(T)[:, None]).sum(axis=1)
    m_prev: int | None = -1
    pm, llm = p, ll
    held = np.zeros(shape) if action_steps > 1 else None  # acceleration kept between decisions
    for t in range(1, T):
        m = int(active[t]) if shape else None
        if shape and m < shape[0]:
            x[t, m:], v[t, m:] = x[t - 1, m:], v[t - 1, m:]
        if m != m_prev:  # the active rows change only where a pair ends
            sl = slice(None, m) if shape else ...
            pm = {k: a[sl] for k, a in p.items()}
            llm = ll[sl]
            lsl = sl if cut else ...
            m_prev = m
        v_old = v[t - 1, sl]
        x_old = x[t - 1, sl]
        gap = xl[t - 1, lsl] - llm - x_old
        if held is None:
            v_raw = step(v_old, gap, vl[t - 1, lsl], pm)
        elif (t - 1) % action_steps == 0:
            v_raw = step(v_old, gap, vl[t - 1, lsl], pm, action_s)
        else:
            v_raw = v_old + held[sl] * DT
        stop = v_raw <= -EPS_SPEED  # stops within the step at constant deceleration
        v_new = np.where(v_raw < EPS_SPEED, 0.0, v_raw)
        if stop.any():
            acc = np.where(stop, (v_raw - v_old) / DT, -1.0)
            dx = np.where(stop, -0.5 * v_old * v_old / acc, 0.5 * (v_old + v_new) * DT)
        else:
            dx = 0.5 * (v_old + v_new) * DT
        v[t, sl] = v_new
        x[t, sl] = x_old + dx
        if held is not None:
            held[sl] = (v_new - v_old) / DT
    return np.moveaxis(x, 0, -1), np.moveaxis(v, 0, -1)
