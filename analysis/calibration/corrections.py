"""How a driver corrects a gap error, beside the recorded drivers: the figures of the
driver-targets benchmark (``benchmarks/driver_targets.py``).

On the recorded states (:class:`irl.planning.decisions.PlanningDecisions` of real pairs, units
ft, ft/s, ft/s^2), a driver's acceleration ``acc [N]`` for each decision is compared with the
person's:

* :func:`bin_match` -- the decisions whose paper bin (:func:`irl.domains.merge.actions.actions_of`)
  matches the person's;
* :func:`gap_error_response` -- where the recorded bumper gap is at least ``tolerance`` (20 %)
  off a desired gap, the mean ``|acc|`` the driver asks for beside the person's on the same
  decisions. The desired gap is the caller's (:func:`planner_desired_gap_ft`,
  :func:`idm_desired_gap_ft`: a driver's own steady-state gap at the recorded speed;
  :func:`median_gap_ft`: the recorded follower's median gap in its pair).

In the closed replay of the pairs (:func:`irl.planning.replay.replay`: the leader as recorded,
the driver following), :func:`replay_commands` keeps the acceleration commanded at every
decision, per pair, and :func:`recorded_commands` gives the recorded followers' on the same
0.3 s grid. :func:`sign_changes` counts the command's sign flips between consecutive decisions
(per 100 pairs of consecutive decisions), :func:`w1_acc_jerk` the Wasserstein-1 distances of
acceleration and jerk between two sets of command series.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.stats import wasserstein_distance

from analysis.calibration.models import DT, CFParams, idm_next_speed
from irl.domains.merge.actions import actions_of
from irl.domains.merge.mdp import frames_per_step
from irl.planning.decisions import PlanningDecisions
from irl.planning.features import Shape
from irl.planning.replay import ActFn, ReplayPair, ReplayResult, replay
from merge_irl.units import FRAME_S, FT_PER_M, M_PER_FT

#: The relative gap error from which a correction is counted (0.2: 20 % off the desired gap).
GAP_TOLERANCE = 0.2


def _bumper_gap_ft(dec: PlanningDecisions) -> np.ndarray:
    """``[N]`` the recorded bumper gap (ft): ``d_AC - len_C``."""
    return dec.obs[:, 0] - dec.obs[:, 5]


def bin_match(dec: PlanningDecisions, acc_ft_s2: np.ndarray) -> tuple[int, int]:
    """``(matches, N)``: decisions whose paper bin of ``acc_ft_s2 [N]`` is the person's.

    Raises:
        ValueError: ``acc_ft_s2`` not of shape ``[N]``.
    """
    acc = np.asarray(acc_ft_s2, dtype=np.float64)
    if acc.shape != (dec.n,):
        raise ValueError(f"bin_match: acc must be [{dec.n}], got {acc.shape}")
    return int(np.sum(actions_of(acc) == dec.actions)), dec.n


@dataclass(frozen=True)
class GapResponse:
    """The response to a gap error of at least ``tolerance`` of the desired gap.

    Attributes:
        n_off: decisions whose recorded gap is off by at least ``tolerance``; n: all decisions.
        driver_abs_acc_ft_s2: mean ``|acc|`` the driver asks for on them (ft/s^2; NaN if none).
        recorded_abs_acc_ft_s2: the persons' mean ``|acc|`` on the same decisions.
        tolerance: the relative error (0.2).
    """

    n_off: int
    n: int
    driver_abs_acc_ft_s2: float
    recorded_abs_acc_ft_s2: float
    tolerance: float = GAP_TOLERANCE

    @property
    def share_off(self) -> float:
        """The share of decisions off by at least ``tolerance`` (NaN without decisions)."""
        return self.n_off / self.n if self.n else float("nan")


def gap_error_response(dec: PlanningDecisions, acc_ft_s2: np.ndarray, desired_gap_ft: np.ndarray,
                       tolerance: float = GAP_TOLERANCE) -> GapResponse:
    """The mean ``|acc_ft_s2|`` where ``|gap - desired| >= tolerance * desired`` (gap the
    recorded bumper gap, ``desired_gap_ft [N]`` > 0), beside the person's ``|dec.acc|`` there.

    Raises:
        ValueError: arrays not of shape ``[N]``, or a tolerance not > 0.
    """
    acc = np.asarray(acc_ft_s2, dtype=np.float64)
    want = np.asarray(desired_gap_ft, dtype=np.float64)
    if acc.shape != (dec.n,) or want.shape != (dec.n,):
        raise ValueError(f"gap_error_response: acc and desired gap must be [{dec.n}], got {acc.shape}, {want.shape}")
    if not tolerance > 0:
        raise ValueError(f"gap_error_response: tolerance must be > 0, got {tolerance}")
    off = np.isfinite(want) & (want > 0) & (np.abs(_bumper_gap_ft(dec) - want) >= tolerance * want)
    n_off = int(off.sum())
    nan = float("nan")
    return GapResponse(n_off, dec.n, float(np.mean(np.abs(acc[off]))) if n_off else nan,
                       float(np.mean(np.abs(dec.acc[off]))) if n_off else nan, tolerance)


def planner_desired_gap_ft(dec: PlanningDecisions, shape: Shape) -> np.ndarray:
    """``[N]`` a planning driver's desired gap at the recorded speed (ft): ``s0 + v_A T`` of
    its feature shape (the ``gap_track`` feature's, IDM's steady state without the free-road term)."""
    return shape.s0_ft + dec.obs[:, 4] * shape.T_s


def idm_desired_gap_ft(dec: PlanningDecisions, params: Sequence[CFParams]) -> np.ndarray:
    """``[N]`` IDM's steady-state gap at the recorded speed (ft): ``(s0 + v T) / sqrt(1 -
    (v / v0)^delta)`` with each decision's parameters ``params [N]`` (NaN where ``v >= v0``:
    no steady state)."""
    s0, tau, v0, delta = (np.array([getattr(p, k) for p in params]) for k in ("minGap", "tau", "maxSpeed", "delta"))
    v = dec.obs[:, 4] * M_PER_FT
    free = 1.0 - (v / v0) ** delta
    with np.errstate(invalid="ignore", divide="ignore"):
        gap = np.where(free > 0, (s0 + v * tau) / np.sqrt(np.maximum(free, 1e-12)), np.nan)
    return gap * FT_PER_M


def median_gap_ft(dec: PlanningDecisions) -> np.ndarray:
    """``[N]`` the recorded follower's median bumper gap over its group's decisions (ft)."""
    gap = _bumper_gap_ft(dec)
    out = np.empty(dec.n)
    for g in np.unique(dec.groups):
        m = dec.groups == g
        out[m] = np.median(gap[m])
    return out


def _idm_obs_acc(obs: np.ndarray, p: dict[str, Any]) -> np.ndarray:
    """``[N]`` IDM's acceleration (ft/s^2) on observations ``obs [N, 7]`` with parameters ``p``
    (scalars or ``[N]`` arrays, SI)."""
    v = obs[:, 4] * M_PER_FT
    v_lead = (obs[:, 4] - obs[:, 1]) * M_PER_FT
    gap = (obs[:, 0] - obs[:, 5]) * M_PER_FT
    return (idm_next_speed(v, gap, v_lead, p) - v) / DT * FT_PER_M


def idm_acc_ft_s2(dec: PlanningDecisions, params: Sequence[CFParams]) -> np.ndarray:
    """``[N]`` the acceleration IDM commands on the recorded states (ft/s^2): SUMO's IDM speed
    update of one 0.1 s step (:func:`analysis.calibration.models.idm_next_speed`) with each
    decision's parameters ``params [N]``."""
    return _idm_obs_acc(dec.obs, {k: np.array([getattr(q, k) for q in params], dtype=np.float64)
                                  for k in CFParams().as_dict()})


def idm_act(params: CFParams) -> ActFn:
    """IDM with ``params`` as a replay driver (:data:`~irl.planning.replay.ActFn`): the
    acceleration of :func:`idm_acc_ft_s2`, held over the decision."""
    p = params.as_dict()
    return lambda obs, prev_acc, acc_C: _idm_obs_acc(np.asarray(obs, dtype=np.float64), p)


def replay_commands(pairs: Sequence[ReplayPair], act: ActFn,
                    decision_step_s: float) -> tuple[ReplayResult, list[np.ndarray]]:
    """:func:`~irl.planning.replay.replay` of ``pairs`` by ``act``, and per pair the ``[D]``
    accelerations ``act`` commanded at its decisions (ft/s^2), in order.

    Raises:
        DemonstrationError: no pairs; ConfigError: a bad decision step.
    """
    k = frames_per_step(decision_step_s)
    lens = np.array([p.x_follower.size for p in pairs])
    calls: list[np.ndarray] = []

    def recording(obs: np.ndarray, prev_acc: np.ndarray, acc_C: np.ndarray) -> np.ndarray:
        out = np.asarray(act(obs, prev_acc, acc_C), dtype=np.float64)
        calls.append(out)
        return out

    res = replay(pairs, recording, decision_step_s)
    series: list[list[float]] = [[] for _ in pairs]
    for c, out in enumerate(calls):  # the replay decides at frame c k for the pairs still running
        idx = np.flatnonzero(c * k < lens - 1)
        if idx.size != out.size:
            raise RuntimeError("replay_commands: the replay's decisions do not match its pairs")
        for i, a in zip(idx, out):
            series[i].append(float(a))
    return res, [np.asarray(s) for s in series]


def recorded_commands(pairs: Sequence[ReplayPair], decision_step_s: float) -> list[np.ndarray]:
    """Per pair the recorded follower's ``[D]`` accelerations on the replay's decision grid
    (ft/s^2): ``(v(f + k) - v(f)) / (k 0.1 s)`` at frames ``f = 0, k, 2k, ...`` while ``f + k``
    is recorded.

    Raises:
        ConfigError: a bad decision step.
    """
    k = frames_per_step(decision_step_s)
    out = []
    for p in pairs:
        f = np.arange(0, p.v_follower.size - k, k)
        out.append((p.v_follower[f + k] - p.v_follower[f]) / (k * FRAME_S))
    return out


def sign_changes(series: Sequence[np.ndarray]) -> tuple[int, int]:
    """``(flips, transitions)``: consecutive decisions of one series whose commands have opposite
    signs (a product < 0; a command of exactly 0 flips nothing), over all consecutive pairs."""
    flips = sum(int(np.sum(s[1:] * s[:-1] < 0)) for s in series)
    return flips, sum(max(len(s) - 1, 0) for s in series)


def w1_acc_jerk(a: Sequence[np.ndarray], b: Sequence[np.ndarray], decision_step_s: float) -> tuple[float, float]:
    """W1 of the accelerations (m/s^2) and of the jerks (their differences over a decision,
    m/s^3) of the command series ``a`` and ``b`` (ft/s^2), pooled over the series (NaN: none)."""
    def pooled(series: Sequence[np.ndarray], jerk: bool) -> np.ndarray:
        parts = [np.diff(s) / decision_step_s if jerk else s for s in series]
        x = np.concatenate(parts) if parts else np.empty(0)
        return x[np.isfinite(x)] * M_PER_FT

    out = []
    for jerk in (False, True):
        x, y = pooled(a, jerk), pooled(b, jerk)
        out.append(float(wasserstein_distance(x, y)) if x.size and y.size else float("nan"))
    return out[0], out[1]
