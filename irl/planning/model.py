"""The planner's settings, its fine acceleration grid and the path tensors (kinematics).

**Observation** of one decision: ``obs [N, 7] = (d_AC, v_AC, d_AB, v_AB, v_A, len_C, len_B)``
(front-to-front gaps ft; closing speeds ``v_A - v_X`` ft/s; A's speed ft/s; leader lengths ft,
NaN unknown -> a 4.5 m car; ``d_AC``/``v_AC`` NaN without C; B a leader when ``d_AB > 0``),
``prev_acc [N]`` the acceleration A held over the previous decision (ft/s^2, NaN -> 0) and
``acc_C [N]`` C's acceleration estimated from its last speed change (ft/s^2, NaN -> 0).

**Action tree**: ``n = round(horizon_s / decision_step_s)`` steps. The first action (step 0) is
one of the ``G`` values of the fine grid (:data:`GRIDS`); each later segment holds one of ``C``
coarse accelerations, the five paper actions' training means (``later="bins"``) or those plus
"hold the first action" (``later="bins+hold"``, ``C = 6``). ``depth=2``: one later segment,
steps ``1..n-1``; ``depth=3``: steps ``1..m-1`` and ``m..n-1``, ``m = 1 + (n - 1) // 2``. A
path's features are ``Phi = sum_k gamma^k phi(s_{k+1}, a_k, a_{k-1})``, ``[N, G, C, (C), K]``,
and its collisions ``Col = sum_k gamma^k col(k+1)`` (plus ``unsafe`` below, undiscounted).

**Kinematic model** (no theta): A holds each step's acceleration exactly (constant
acceleration, speed stopping at 0); C at constant velocity (``c_model="cv"``) or constant
acceleration ``acc_C`` until it stops (``"ca"``); B at constant velocity, a leader only if it was
ahead at the observation (``d_AB > 0``). Positions relative to A's.

**Road model** (:attr:`PlannerConfig.road_model`). ``"legacy"``: ``col = 1[s_C <= 0]``, C as
predicted above, and B counts (features) only while predicted ahead (front to front).
``"driver"``, a driver's view of the road from A's observation alone:

* B ahead at the observation stays a leader over the whole path (nothing drives through a car:
  its features saturate instead of vanishing once the prediction puts it behind A), unless its
  front is beyond C's rear (``d_AB > d_AC - len_C``: beside or ahead of C, so not between A and
  C, and C is the leader);
* ``col``: a leader (C, or B ahead) at a bumper gap ``<= 0``, or below ``margin_ft`` while A is
  faster than it (:func:`~irl.planning.features.closing_margin`); a leader whose bumper gap is
  not positive at the observation (a car alongside, in the other lane) is no collision partner;
* ``unsafe`` (1 per path of an unsafe first action; Gipps-style safe distance): a leader may
  brake from now on at ``b_L = c_brake_ft_s2`` (C: ``max(c_brake_ft_s2, -acc_C)``, harder if it
  is seen braking harder), and A, after its first step, at its emergency deceleration
  (``-min(EMERGENCY_FT_S2)``); the first action is unsafe when the smallest bumper gap of that
  scenario from the end of the first step on (:func:`~irl.planning.features.min_gap_braking`)
  is ``<= 0``, or below ``margin_ft`` and below the gap at the observation (the gap closes).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from irl.domains.merge.actions import N_ACTIONS, actions_of
from irl.domains.merge.mdp import DEFAULT_DECISION_STEP_S, frames_per_step
from irl.errors import ConfigError
from irl.planning.features import (
    DEFAULT_LENGTH_FT,
    Shape,
    closing_margin,
    collision,
    feature_names,
    min_gap_braking,
    step_features,
)
from merge_irl.units import FT_PER_M

BACKUPS = ("avg", "boltzmann", "softmax")
C_MODELS = ("cv", "ca")
LATER = ("bins", "bins+hold")
#: Road models of the planner's prediction (module docstring).
ROAD_MODELS = ("driver", "legacy")
#: Fine acceleration grids of the first action (ft/s^2); ``"bins"``: the five paper actions'
#: training means (the coarse driver, for comparison).
#: A's emergency braking (ft/s^2) on every fine grid: about 9 and 6.5 m/s^2, a car's physical
#: range (SUMO's emergencyDecel), which demonstrations rarely show but a planner must be able to
#: choose when its model predicts a collision (comfort makes them unlikely otherwise).
EMERGENCY_FT_S2 = (-28.0, -21.0)
GRIDS: dict[str, tuple[float, ...]] = {
    "bins": (),
    "g13": EMERGENCY_FT_S2 + tuple(float(x) for x in np.linspace(-14.0, 10.0, 13)),  # 2 ft/s^2 apart
    "g24": EMERGENCY_FT_S2 + tuple(float(x) for x in np.arange(-14.0, 10.0, 1.0)),  # 1 ft/s^2 apart
}


#: The road model of a planner fitted by likelihood (:func:`~irl.planning.driver.learn_planning_driver`):
#: ``"legacy"``. The driver's road model counts as a collision every first action it calls unsafe,
#: and the demonstrators of the synthetic scenario take such actions: fitted by likelihood on the
#: demo's demonstrations (2026-12-07) its held-out log-likelihood is -4.45 per decision against
#: -1.29 with the legacy model. A driver fitted by replay (what its driving does) uses ``"driver"``.
LIKELIHOOD_ROAD_MODEL = "legacy"


@dataclass(frozen=True)
class PlannerConfig:
    """Settings of the planner (selected on held-out data, not learned).

    Attributes:
        horizon_s: planning horizon (s); decision_step_s: seconds per decision (a multiple of
        0.1 s); depth: 2 or 3 segments per path; backup: one of :data:`BACKUPS`; c_model:
        ``"cv"`` or ``"ca"``; gamma: discount per step in (0, 1]; grid: a key of :data:`GRIDS`;
        later: one of :data:`LATER`; with_bias: the paper-action bias features;
        collision_penalty: reward of a step ending in a collision (<= 0, fixed);
        jerk: the jerk feature (the reward's only action history); free_road: the free-road
        feature ``(v_A / v0)^4``; lag: ``k`` in (0, 1], the actuation lag of the first step:
        A applies ``a = (1 - k) a_prev + k a*``, ``a*`` the chosen fine-grid value (1: none; see
        :func:`path_tensors`); v0_ft_s: the desired speed of the speed features (ft/s; 0: the
        fitted one of :func:`~irl.planning.features.fit_shape`); jerk_weight: a
        fixed (not fitted) weight of the jerk feature, ``<= 0``, or None: fitted (a fitted jerk
        weight makes the driver a copycat of its own last acceleration in closed loop; see the
        docs of the driver); gap_track: the symmetric gap-tracking features (``gap_track_C``,
        ``gap_track_B``); temperature: ``tau > 0`` of the policy over the first actions,
        ``softmax(Q / tau)``: it changes the likelihood, never the most likely action (a driver
        fitted by replay gets its ``tau`` from the training likelihood); road_model: one of
        :data:`ROAD_MODELS` (module docstring; files written before it load with ``"legacy"``);
        c_brake_ft_s2: the deceleration (ft/s^2, > 0) a leader may brake at from now on in the
        ``"driver"`` model (default 4.5 m/s^2); margin_ft: the bumper gap (ft, >= 0) a path must
        keep while closing on a leader in the ``"driver"`` model (default 1 m).

    Raises:
        ConfigError: a value outside the above.
    """

    horizon_s: float = 2.1
    decision_step_s: float = DEFAULT_DECISION_STEP_S
    depth: int = 2
    backup: str = "softmax"
    c_model: str = "ca"
    gamma: float = 0.9
    grid: str = "g24"
    later: str = "bins+hold"
    with_bias: bool = True
    collision_penalty: float = -100.0
    jerk: bool = False
    free_road: bool = False
    lag: float = 1.0
    v0_ft_s: float = 0.0
    jerk_weight: float | None = None
    gap_track: bool = False
    temperature: float = 1.0
    road_model: str = "driver"
    c_brake_ft_s2: float = 4.5 * FT_PER_M
    margin_ft: float = 1.0 * FT_PER_M

    def __post_init__(self) -> None:
        frames_per_step(self.decision_step_s)
        problems = []
        if self.depth not in (2, 3):
            problems.append(f"depth must be 2 or 3, got {self.depth!r}")
        for name, options in (("backup", BACKUPS), ("c_model", C_MODELS), ("grid", tuple(GRIDS)), ("later", LATER),
                              ("road_model", ROAD_MODELS)):
            if getattr(self, name) not in options:
                problems.append(f"{name} must be one of {options}, got {getattr(self, name)!r}")
        if not (isinstance(self.gamma, (int, float)) and 0 < self.gamma <= 1):
            problems.append(f"gamma must be in (0, 1], got {self.gamma!r}")
        if not (isinstance(self.horizon_s, (int, float)) and math.isfinite(self.horizon_s)
                and self.horizon_s >= 2 * self.decision_step_s - 1e-9):
            problems.append(f"horizon_s must be at least two decision steps, got {self.horizon_s!r}")
        if not (isinstance(self.collision_penalty, (int, float)) and -math.inf < self.collision_penalty <= 0):
            problems.append(f"collision_penalty must be a finite number <= 0, got {self.collision_penalty!r}")
        if not (isinstance(self.lag, (int, float)) and not isinstance(self.lag, bool) and 0 < self.lag <= 1):
            problems.append(f"lag must be in (0, 1], got {self.lag!r}")
        if not (isinstance(self.v0_ft_s, (int, float)) and math.isfinite(self.v0_ft_s) and self.v0_ft_s >= 0):
            problems.append(f"v0_ft_s must be a finite number >= 0, got {self.v0_ft_s!r}")
        if self.jerk_weight is not None and not (isinstance(self.jerk_weight, (int, float))
                                                 and not isinstance(self.jerk_weight, bool)
                                                 and math.isfinite(self.jerk_weight) and self.jerk_weight <= 0):
            problems.append(f"jerk_weight must be None or a finite number <= 0, got {self.jerk_weight!r}")
        if not (isinstance(self.temperature, (int, float)) and not isinstance(self.temperature, bool)
                and math.isfinite(self.temperature) and self.temperature > 0):
            problems.append(f"temperature must be a finite number > 0, got {self.temperature!r}")
        problems += _road_problems(self.c_brake_ft_s2, self.margin_ft)
        for name in ("jerk", "free_road", "with_bias", "gap_track"):
            if not isinstance(getattr(self, name), bool):
                problems.append(f"{name} must be true or false, got {getattr(self, name)!r}")
        if problems:
            raise ConfigError("PlannerConfig: " + "; ".join(problems))

    @property
    def n_steps(self) -> int:
        """Decision steps in the horizon."""
        return max(int(round(self.horizon_s / self.decision_step_s)), self.depth)

    @property
    def feature_names(self) -> tuple[str, ...]:
        """The ``K`` learned feature names."""
        return feature_names(self.with_bias, self.jerk, self.free_road, self.gap_track)

    def applied(self, first: np.ndarray, prev_acc: np.ndarray) -> np.ndarray:
        """``[N, G]`` the accelerations A applies for the fine choices ``first [G]`` after
        ``prev_acc [N]`` (NaN -> 0): ``(1 - lag) prev_acc + lag first``."""
        prev = np.nan_to_num(np.asarray(prev_acc, dtype=np.float64), nan=0.0)
        return (1.0 - self.lag) * prev[:, None] + self.lag * np.asarray(first, dtype=np.float64)[None, :]

    def fine_grid(self, action_acc: np.ndarray) -> np.ndarray:
        """``[G]`` accelerations of the first action (ft/s^2); ``action_acc [5]`` for ``"bins"``."""
        g = GRIDS[self.grid]
        return np.asarray(action_acc if not g else g, dtype=np.float64)

    def segment_starts(self) -> np.ndarray:
        """``[depth]`` int: the first step of each segment."""
        n = self.n_steps
        return np.array([0, 1] if self.depth == 2 else [0, 1, 1 + (n - 1) // 2])


def _road_problems(c_brake_ft_s2: object, margin_ft: object) -> list[str]:
    """The problems of the driver road model's numbers (:class:`PlannerConfig`)."""
    out = []
    for name, x, low in (("c_brake_ft_s2", c_brake_ft_s2, 1e-9), ("margin_ft", margin_ft, 0.0)):
        if not (isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) and x >= low):
            out.append(f"{name} must be a finite number {'> 0' if low else '>= 0'}, got {x!r}")
    return out


def leaf_accelerations(config: PlannerConfig, action_acc: np.ndarray,
                       first: np.ndarray | None = None) -> np.ndarray:
    """``[..., G, C, (C), n]`` acceleration (ft/s^2) of every step on every path (module
    docstring); ``first [..., G]`` the applied first accelerations (default the fine grid, ``[G]``)."""
    fine = config.fine_grid(action_acc) if first is None else np.asarray(first, dtype=np.float64)
    lead, G = fine.shape[:-1], fine.shape[-1]
    later = np.broadcast_to(np.asarray(action_acc, dtype=np.float64), lead + (G, N_ACTIONS))
    if config.later == "bins+hold":
        later = np.concatenate([later, fine[..., None]], axis=-1)
    C = later.shape[-1]
    n = config.n_steps
    starts = config.segment_starts()
    out = np.empty(lead + (G,) + (C,) * (config.depth - 1) + (n,))
    out[..., 0] = fine.reshape(lead + (G,) + (1,) * (config.depth - 1))
    for j in range(1, config.depth):
        k0, k1 = starts[j], (starts[j + 1] if j + 1 < starts.size else n)
        shp = [G] + [1] * (config.depth - 1)
        shp[j] = C
        out[..., k0:k1] = later.reshape(lead + tuple(shp))[..., None]
    return out


@dataclass(frozen=True)
class PathTensors:
    """Path features of ``N`` decisions (independent of theta).

    Attributes:
        Phi: ``[N, G, C, (C), K]`` discounted features of each path; Col: ``[N, G, C, (C)]``
        discounted collision count; bins: ``[G]`` paper action of each fine first action, or
        ``[N, G]`` that of the acceleration each applies (a config with an actuation lag).
    """

    Phi: np.ndarray
    Col: np.ndarray
    bins: np.ndarray

    @property
    def n(self) -> int:
        """The number of decisions ``N``."""
        return int(self.Phi.shape[0])

    def take(self, idx: np.ndarray) -> PathTensors:
        """The decisions ``idx``."""
        return PathTensors(self.Phi[idx], self.Col[idx], self.bins[idx] if self.bins.ndim == 2 else self.bins)


def path_tensors(obs: np.ndarray, prev_acc: np.ndarray, acc_C: np.ndarray, action_acc, shape: Shape,
                 config: PlannerConfig, *, chunk: int = 512, need: frozenset[str] | None = None,
                 b_merged: np.ndarray | None = None) -> PathTensors:
    """Path tensors (module docstring) of ``obs [N, 7]``, ``prev_acc [N]``, ``acc_C [N]`` with
    the paper actions' accelerations ``action_acc [5]`` (ft/s^2), in chunks of ``chunk`` decisions;
    ``need``: the features computed (the others 0: acting needs only those of nonzero weight),
    None: all (learning); ``b_merged [N]`` bool: whether B has merged into A's lane (the
    ``"driver"`` road model counts B as a collision partner only then; None: B ahead always is,
    as in demonstrations that do not say).

    Raises:
        ConfigError: ``obs`` not ``[N, 7]``, ``prev_acc``/``acc_C`` not ``[N]``, ``action_acc``
            not 5 finite numbers, ``b_merged`` not ``[N]``.
    """
    obs = np.asarray(obs, dtype=np.float64)
    if b_merged is not None and np.shape(b_merged) != (obs.shape[0],):
        raise ConfigError(f"b_merged must be [N] = [{obs.shape[0]}], got {np.shape(b_merged)}")
    prev_acc = np.nan_to_num(np.asarray(prev_acc, dtype=np.float64), nan=0.0)
    acc_C = np.nan_to_num(np.asarray(acc_C, dtype=np.float64), nan=0.0)
    acc5 = np.asarray(action_acc, dtype=np.float64)
    if obs.ndim != 2 or obs.shape[1] != 7 or prev_acc.shape != (obs.shape[0],) or acc_C.shape != prev_acc.shape:
        raise ConfigError(f"obs must be [N, 7], prev_acc and acc_C [N]; got {obs.shape}, {prev_acc.shape}, "
                          f"{acc_C.shape}")
    if acc5.shape != (N_ACTIONS,) or not np.all(np.isfinite(acc5)):
        raise ConfigError(f"action_acc must be {N_ACTIONS} finite numbers, got {acc5}")
    leaf = leaf_accelerations(config, acc5)
    tail = leaf.shape[:-1]
    leaves = leaf.reshape(-1, leaf.shape[-1])  # [L, n]
    N, K = obs.shape[0], len(config.feature_names)
    Phi = np.empty((N, leaves.shape[0], K))
    Col = np.empty((N, leaves.shape[0]))
    fine = config.fine_grid(acc5)
    lagged = config.lag < 1.0
    for lo in range(0, N, chunk):
        hi = min(lo + chunk, N)
        lv = leaf_accelerations(config, acc5, config.applied(fine, prev_acc[lo:hi])).reshape(hi - lo, -1, leaf.shape[-1]) \
            if lagged else leaves[None]
        merged = None if b_merged is None else b_merged[lo:hi]
        Phi[lo:hi], Col[lo:hi] = _paths_chunk(obs[lo:hi], prev_acc[lo:hi], acc_C[lo:hi], lv, shape, config, need,
                                              merged)
    bins = actions_of(config.applied(fine, prev_acc)) if lagged else actions_of(fine)
    return PathTensors(Phi.reshape((N, *tail, K)), Col.reshape((N, *tail)), bins)


def first_step(obs: np.ndarray, prev_acc: np.ndarray, acc_C: np.ndarray, acc: np.ndarray, shape: Shape,
               config: PlannerConfig) -> tuple[np.ndarray, np.ndarray]:
    """``([N, K] features, [N] collision count)`` of the one decision step that applies ``acc [N]``
    (ft/s^2) from ``obs [N, 7]`` (``prev_acc``, ``acc_C`` ``[N]``, NaN -> 0): the first step of a
    path of :func:`path_tensors`, undiscounted (0/1; ``"driver"`` road model: 0-2, the step's
    ``col`` plus ``unsafe``).

    Raises:
        ConfigError: arrays of other shapes.
    """
    obs = np.asarray(obs, dtype=np.float64)
    n = obs.shape[0] if obs.ndim == 2 else -1
    prev_acc = np.nan_to_num(np.asarray(prev_acc, dtype=np.float64), nan=0.0)
    acc_C = np.nan_to_num(np.asarray(acc_C, dtype=np.float64), nan=0.0)
    acc = np.asarray(acc, dtype=np.float64)
    if obs.ndim != 2 or obs.shape[1] != 7 or any(x.shape != (n,) for x in (prev_acc, acc_C, acc)):
        raise ConfigError(f"obs must be [N, 7], prev_acc, acc_C and acc [N]; got {obs.shape}, {prev_acc.shape}, "
                          f"{acc_C.shape}, {acc.shape}")
    # one path of one step per decision: leaves [N, 1, 1]
    phi, col = _paths_chunk(obs, prev_acc, acc_C, acc[:, None, None], shape, replace(config, depth=2))
    return phi[:, 0, :], col[:, 0]


def _paths_chunk(obs: np.ndarray, prev_acc: np.ndarray, acc_C: np.ndarray, leaves: np.ndarray, shape: Shape,
                 config: PlannerConfig, need: frozenset[str] | None = None,
                 b_merged: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``([N, L, K], [N, L])`` of one chunk: every step of every path at once (``[N, L, n]``);
    ``leaves [1 or N, L, n]`` the paths' accelerations."""
    d_AC, v_AC, d_AB, v_AB, v_A0, len_C, len_B = (obs[:, j:j + 1, None] for j in range(7))
    len_C = np.where(np.isfinite(len_C), len_C, DEFAULT_LENGTH_FT)
    len_B = np.where(np.isfinite(len_B), len_B, DEFAULT_LENGTH_FT)
    has_C = np.isfinite(d_AC) & np.isfinite(v_AC)
    d_AC = np.where(has_C, d_AC, 1e6)
    v_C0 = np.where(has_C, v_A0 - np.where(has_C, v_AC, 0.0), 0.0)
    road = config.road_model == "driver"
    # the driver's model: B beside or ahead of C's rear is not between A and C (one car per lane spot)
    B_lead = np.isfinite(d_AB) & np.isfinite(v_AB) & (d_AB > 0) & ~(road & has_C & (d_AB > d_AC - len_C))
    d_AB = np.where(B_lead, d_AB, 1e6)
    v_B0 = np.where(B_lead, v_A0 - np.where(B_lead, v_AB, 0.0), 0.0)
    L, n = leaves.shape[1:]
    dt = config.decision_step_s
    t = dt * np.arange(1, n + 1)
    x_A = np.empty((obs.shape[0], L, n))
    v_A = np.empty_like(x_A)
    starts = config.segment_starts()
    x_s, v_s = np.zeros((1, 1, 1)), v_A0
    for j, k0 in enumerate(starts):
        k1 = starts[j + 1] if j + 1 < starts.size else n
        a = leaves[:, :, k0:k0 + 1]  # [1 or N, L, 1]
        tau = t[k0:k1] - k0 * dt
        te = np.minimum(tau, np.where(a < 0, v_s / np.maximum(-a, 1e-9), np.inf))
        x_A[:, :, k0:k1] = x_s + v_s * te + 0.5 * a * te * te
        v_A[:, :, k0:k1] = np.maximum(v_s + a * te, 0.0)
        x_s, v_s = x_A[:, :, k1 - 1:k1], v_A[:, :, k1 - 1:k1]
    a_C = acc_C[:, None, None] if config.c_model == "ca" else np.zeros((obs.shape[0], 1, 1))
    te = np.minimum(t, np.where(a_C < 0, v_C0 / np.maximum(-a_C, 1e-9), np.inf))
    s_C = d_AC + v_C0 * te + 0.5 * a_C * te * te - x_A - len_C
    v_C = np.maximum(v_C0 + a_C * te, 0.0)
    d_B = d_AB + v_B0 * t - x_A
    B_ahead = B_lead if road else B_lead & (d_B > 0)
    acc_prev = np.empty((obs.shape[0], L, n))
    acc_prev[:, :, 1:] = leaves[:, :, :-1]
    acc_prev[:, :, 0] = prev_acc[:, None]
    f = step_features(s_C, v_C, has_C, d_B - len_B, v_B0, B_ahead, v_A, leaves, acc_prev, shape,
                      config.with_bias, config.jerk, config.free_road, config.gap_track, need)
    g = config.gamma ** np.arange(n)
    Phi = np.einsum("nlsk,s->nlk", f, g)
    if not road:
        return Phi, collision(s_C, has_C) @ g
    gap_C0, gap_B0 = (d_AC - len_C)[:, :, 0], (d_AB - len_B)[:, :, 0]
    C_real, B_real = has_C[:, :, 0] & (gap_C0 > 0), B_lead[:, :, 0] & (gap_B0 > 0)
    if b_merged is not None:  # B on the ramp is no collision partner: only a merged B is in A's lane
        B_real = B_real & np.asarray(b_merged, dtype=bool).reshape(-1, 1)
    col = (closing_margin(s_C, v_A, v_C, C_real[:, :, None], config.margin_ft)
           | closing_margin(d_B - len_B, v_A, v_B0, B_real[:, :, None], config.margin_ft))
    b_C = np.maximum(config.c_brake_ft_s2, -acc_C[:, None])
    x_A1, v_A1 = x_A[:, :, 0], v_A[:, :, 0]
    unsafe = (_unsafe_first(gap_C0, v_C0[:, :, 0], b_C, C_real, x_A1, v_A1, config)
              | _unsafe_first(gap_B0, v_B0[:, :, 0], config.c_brake_ft_s2, B_real, x_A1, v_A1, config))
    return Phi, col @ g + unsafe


#: A's deceleration (ft/s^2, > 0) after its first step in the safe-distance condition.
EMERGENCY_DECEL_FT_S2 = -min(EMERGENCY_FT_S2)


def _unsafe_first(gap0: np.ndarray, v_L0: np.ndarray, b_L: np.ndarray | float, present: np.ndarray,
                  x_A1: np.ndarray, v_A1: np.ndarray, config: PlannerConfig) -> np.ndarray:
    """``[N, L]`` bool, the safe-distance condition of the ``"driver"`` road model (module
    docstring) towards one leader: bumper gap ``gap0 [N, 1]`` (ft) and speed ``v_L0 [N, 1]``
    (ft/s) at the observation, braking at ``b_L`` (ft/s^2) from now on; A after its first step at
    ``x_A1``, ``v_A1 [N or 1, L]`` (ft, ft/s), then braking at :data:`EMERGENCY_DECEL_FT_S2`."""
    te = np.minimum(config.decision_step_s, v_L0 / b_L)
    g1 = gap0 + v_L0 * te - 0.5 * b_L * te * te - x_A1
    m = min_gap_braking(g1, v_A1, np.maximum(v_L0 - b_L * te, 0.0), EMERGENCY_DECEL_FT_S2, b_L)
    return present & ((m <= 0.0) | ((m < config.margin_ft) & (m < gap0 - 1e-9)))
