"""Held-out replay of real car-following pairs with a driver (pure numpy; ft internally, m
reported).

Each pair's leader moves as recorded; the driver follows from the recorded initial position and
speed, deciding every ``k = decision_step_s / 0.1 s`` frames. Its observation at a decision is
``(d_AC, v_AC, NaN, NaN, v_A, leader_length, NaN)`` from the simulated follower and the recorded
leader; ``prev_acc`` the acceleration it applied over its last decision (0 at the start) and
``acc_C = (v_l(t) - v_l(t - k)) / (k 0.1 s)`` from the recorded leader (0 for ``t < k``). A's
kinematics are integrated exactly at 0.1 s (constant acceleration, speed stopping at 0). Scored
per pair: the spacing RMSE (bumper gap, m) over frames ``1 .. T-1``, and a collision when the
simulated bumper gap is ever ``<= 0``. All pairs run as one batch.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from irl.domains.merge.mdp import DEFAULT_DECISION_STEP_S, frames_per_step
from irl.errors import DemonstrationError
from merge_irl.units import FRAME_S, M_PER_FT

#: ``act(obs [P, 7], prev_acc [P], acc_C [P]) -> acceleration [P]`` (ft/s^2) of each follower.
ActFn = Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]


@dataclass(frozen=True)
class ReplayPair:
    """One recorded pair, ``[T]`` arrays at 0.1 s frames (ft, ft/s; fronts of the cars).

    Raises:
        DemonstrationError: arrays of different lengths or fewer than 2 frames, a value that
            is not finite, or a leader length not > 0.
    """

    name: str
    x_follower: np.ndarray
    v_follower: np.ndarray
    x_leader: np.ndarray
    v_leader: np.ndarray
    leader_length_ft: float

    def __post_init__(self) -> None:
        arrays = [np.asarray(getattr(self, k), dtype=np.float64)
                  for k in ("x_follower", "v_follower", "x_leader", "v_leader")]
        if len({a.shape for a in arrays}) != 1 or arrays[0].ndim != 1 or arrays[0].size < 2 \
                or not all(np.isfinite(a).all() for a in arrays) \
                or not (np.isfinite(self.leader_length_ft) and self.leader_length_ft > 0):
            raise DemonstrationError(f"replay pair {self.name!r}: needs four finite [T] arrays (T >= 2) and a "
                                     f"leader length > 0 ft")
        for k, a in zip(("x_follower", "v_follower", "x_leader", "v_leader"), arrays):
            object.__setattr__(self, k, a)

    @property
    def gap_ft(self) -> np.ndarray:
        """``[T]`` recorded bumper gap (ft)."""
        return self.x_leader - self.leader_length_ft - self.x_follower


@dataclass(frozen=True)
class ReplayResult:
    """Per-pair results, in the order of the pairs given.

    Attributes:
        names: the pairs; rmse_m: ``[P]`` spacing RMSE (m); collided: ``[P]`` bool;
        min_gap_m: ``[P]`` smallest simulated bumper gap (m).
    """

    names: tuple[str, ...]
    rmse_m: np.ndarray
    collided: np.ndarray
    min_gap_m: np.ndarray

    def summary(self) -> dict[str, float]:
        """Pairs, median and mean RMSE (m), collisions."""
        return {"pairs": len(self.names), "rmse_median_m": float(np.median(self.rmse_m)),
                "rmse_mean_m": float(np.mean(self.rmse_m)), "collisions": int(self.collided.sum())}


def replay(pairs: Sequence[ReplayPair], act: ActFn,
           decision_step_s: float = DEFAULT_DECISION_STEP_S) -> ReplayResult:
    """Replay ``pairs`` with the driver ``act`` (module docstring).

    Raises:
        DemonstrationError: no pairs; ConfigError: a bad decision step.
    """
    if not pairs:
        raise DemonstrationError("replay: no pairs")
    k = frames_per_step(decision_step_s)
    P = len(pairs)
    lens = np.array([p.x_follower.size for p in pairs])
    T = int(lens.max())
    x_l = np.full((P, T), np.nan)
    v_l = np.full((P, T), np.nan)
    gap_obs = np.full((P, T), np.nan)
    for i, p in enumerate(pairs):
        x_l[i, :lens[i]], v_l[i, :lens[i]] = p.x_leader, p.v_leader
        gap_obs[i, :lens[i]] = p.gap_ft
    L = np.array([p.leader_length_ft for p in pairs])
    x = np.array([p.x_follower[0] for p in pairs])
    v = np.array([p.v_follower[0] for p in pairs])
    acc = np.zeros(P)
    gap_sim = np.full((P, T), np.nan)
    gap_sim[:, 0] = x_l[:, 0] - L - x
    nan = np.nan
    for f in range(T - 1):
        live = f < lens - 1
        if f % k == 0:
            idx = np.flatnonzero(live)
            acc_C = (v_l[idx, f] - v_l[idx, f - k]) / (k * FRAME_S) if f >= k else np.zeros(idx.size)
            obs = np.column_stack([x_l[idx, f] - x[idx], v[idx] - v_l[idx, f], np.full(idx.size, nan),
                                   np.full(idx.size, nan), v[idx], L[idx], np.full(idx.size, nan)])
            acc[idx] = np.asarray(act(obs, acc[idx].copy(), acc_C), dtype=np.float64)
        v_end = v + acc * FRAME_S
        stops = v_end < 0
        dx = np.where(stops, v * v / (2 * np.maximum(-acc, 1e-9)), v * FRAME_S + 0.5 * acc * FRAME_S ** 2)
        x = np.where(live, x + dx, x)
        v = np.where(live, np.maximum(v_end, 0.0), v)
        gap_sim[:, f + 1] = np.where(live, x_l[:, f + 1] - L - x, np.nan)
    err = (gap_sim[:, 1:] - gap_obs[:, 1:]) * M_PER_FT
    rmse = np.sqrt(np.nanmean(err ** 2, axis=1))
    min_gap = np.nanmin(gap_sim, axis=1) * M_PER_FT
    return ReplayResult(tuple(p.name for p in pairs), rmse, min_gap <= 0, min_gap)
