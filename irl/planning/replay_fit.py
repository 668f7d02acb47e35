"""The planning driver fitted by what its driving does: its reward weights and gap shape chosen by
replaying recorded car-following pairs, then its temperature by the training likelihood.

**Why not the likelihood.** The one-step likelihood of 0.3 s action bins can be maximised without
looking at the road (most decisions repeat the previous one), and the likelihood-fitted reward
leaves the car without a pull back to a following gap (it creeps up behind slow leaders and falls
far behind fast ones). Like a car-following model's calibration (Punzo et al. 2021, "Calibration
of car-following models with single- and multi-step approaches", Transp. Res. B), the weights
here are chosen by the closed-loop (multi-step) error of the driving itself.

**Criterion** (:func:`replay_objective`): each training pair's recorded leader moves as recorded
and the driver follows from the recorded initial state, taking its most likely action every
decision (:func:`irl.planning.replay.replay`); the objective is the mean over pairs
of the spacing RMSE (m) plus ``collision_cost_m`` for a pair whose bumper gap reached 0, or
their median, or (the default) the average of the mean and the median: the targets name both,
and the mean alone is led by a few pairs nobody follows well (on the I-80 pairs it chose a
desired speed of 29 ft/s and a held-out median of 4.28 m against 4.02 m for the average).

**Parameters** (:class:`ReplayFitConfig`): the weights of the cost features in ``free`` (each
``-exp(u)``: a cost stays a cost, never silently changes sign; started from
:data:`START_WEIGHTS`) and the shape's ``T_s``, ``s0_ft`` and desired speed ``v0_ft_s``
(``exp(u)``, started from :data:`START_SHAPE`), all on a log scale, clipped to :data:`SHAPE_BOUNDS`, by scipy's
Nelder-Mead (derivative-free: the replay's argmax is piecewise constant in the weights).
``comfort``'s weight is held at -1 (the scale: the most likely action depends only on the
weights' ratios, and the temperature is fitted after). The merging car's terms (``*_B``) have no
data in car-following pairs: with ``tie_B`` they take the lead car's weights (B, once ahead,
is treated as a leader), a fixed rule, not learned.

**Temperature** (:func:`fit_temperature`): ``tau`` of ``softmax(Q / tau)`` maximising the
training decisions' likelihood of their paper actions (1-D, bounded); it changes the
likelihood, never the most likely action, so the replay criterion is untouched.

**Intervals** (:func:`bootstrap_intervals`): each fitted parameter's percentile interval over
refits on bootstrap resamples of the training followers (from the fit, fewer evaluations).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from scipy.optimize import minimize, minimize_scalar

from irl.errors import ConfigError, DemonstrationError
from irl.planning.decisions import PlanningDecisions
from irl.planning.driver import PlanningDriver
from irl.planning.features import Shape
from irl.planning.model import PlannerConfig, path_tensors
from irl.planning.policy import bin_log_policy_of_fine, log_softmax, path_returns, q_values
from irl.planning.replay import ReplayPair, ReplayResult, replay
from merge_irl.units import FT_PER_M

#: Shape parameters the fit may free, with their bounds (ft, s).
SHAPE_BOUNDS: dict[str, tuple[float, float]] = {"T_s": (0.3, 3.0), "s0_ft": (1.0, 10.0 * FT_PER_M),
                                                "v0_ft_s": (15.0, 45.0 * FT_PER_M)}
#: The shape the fit starts from: SUMO's passenger car's minGap (2.5 m), a 1.2 s time headway and
#: a desired speed of 60 ft/s (18 m/s): a start near SUMO's car following, not a result.
START_SHAPE = Shape(T_s=1.2, v0_ft_s=60.0)
#: The weights the fit starts from (comfort -1 is the scale): the gap tracked firmly, closing
#: speed and the desired speed less.
START_WEIGHTS: tuple[tuple[str, float], ...] = (("gap_track_C", -5.0), ("inv_ttc_C", -2.0), ("speed_dev", -2.0))
#: The reward's features when fitted by replay: the lead car's symmetric gap tracking and closing
#: speed, the merging car's the same (tied), the desired speed and comfort; no action history.
REPLAY_CONFIG = PlannerConfig(gap_track=True, with_bias=False, jerk=False, grid="g13", later="bins", depth=2,
                              horizon_s=2.1, backup="softmax", c_model="ca", gamma=0.9)


@dataclass(frozen=True)
class ReplayFitConfig:
    """Settings of :func:`fit_by_replay` (defaults: the I-80 pairs' fit of docs/closed-loop.md).

    Attributes:
        planner: the planner's settings (its features must include every name of ``free``).
        free: cost features whose weights are fitted (each ``-exp(u)``).
        start: ``{feature: weight}`` the fit starts from (a missing free feature: -1; a feature
            neither free nor here: 0, except ``comfort``: -1, the scale).
        shape_free: shape parameters fitted (keys of :data:`SHAPE_BOUNDS`).
        tie_B: the merging car's ``*_B`` weights equal the lead car's ``*_C`` (no B in pairs).
        collision_cost_m: added to a colliding pair's RMSE (m) in the criterion.
        criterion: the statistic over pairs minimised, one of :data:`CRITERIA`.
        max_evals: replays the optimiser may spend; xatol: its tolerance on the log parameters.

    Raises:
        ConfigError: a free feature the planner lacks, an unknown shape parameter, or a bad number.
    """

    planner: PlannerConfig = REPLAY_CONFIG
    free: tuple[str, ...] = ("gap_track_C", "inv_ttc_C", "speed_dev")
    start: tuple[tuple[str, float], ...] = START_WEIGHTS
    shape_free: tuple[str, ...] = ("T_s", "s0_ft", "v0_ft_s")
    tie_B: bool = True
    collision_cost_m: float = 30.0
    criterion: str = "mean+median"
    max_evals: int = 100
    xatol: float = 0.02

    def __post_init__(self) -> None:
        names = self.planner.feature_names
        problems = [f"free feature {f!r} is not one of the planner's {names}" for f in self.free if f not in names]
        problems += [f"shape parameter {s!r} is not one of {tuple(SHAPE_BOUNDS)}" for s in self.shape_free
                     if s not in SHAPE_BOUNDS]
        if "comfort" in self.free:
            problems.append("comfort is the scale and cannot be free")
        if self.criterion not in CRITERIA:
            problems.append(f"criterion must be one of {CRITERIA}, got {self.criterion!r}")
        if not (isinstance(self.max_evals, int) and self.max_evals >= 1):
            problems.append(f"max_evals must be an integer >= 1, got {self.max_evals!r}")
        if not (math.isfinite(self.collision_cost_m) and self.collision_cost_m >= 0):
            problems.append(f"collision_cost_m must be finite and >= 0, got {self.collision_cost_m!r}")
        if problems:
            raise ConfigError("ReplayFitConfig: " + "; ".join(problems))


@dataclass(frozen=True)
class ReplayFit:
    """What :func:`fit_by_replay` returns.

    Attributes:
        driver: the fitted driver (temperature 1; :func:`fit_temperature` sets it).
        objective: the criterion at the fit (m); start_objective: at the start (m);
        result: the replay of the training pairs at the fit; n_evals: replays spent;
        converged: the optimiser stopped on its tolerance (not its budget); seconds: wall time;
        params: ``{name: value}`` of the fitted parameters (weights; shape in ft and s).
    """

    driver: PlanningDriver
    objective: float
    start_objective: float
    result: ReplayResult
    n_evals: int
    converged: bool
    seconds: float
    params: dict[str, Any] = field(default_factory=dict)


#: The statistics over pairs a replay fit can minimise (:attr:`ReplayFitConfig.criterion`).
CRITERIA = ("mean", "median", "mean+median")


def replay_objective(result: ReplayResult, collision_cost_m: float, criterion: str = "mean") -> float:
    """The criterion (m): the ``criterion`` (mean, median, or the average of both) over pairs of
    ``rmse_m + collision_cost_m * collided``.

    Raises:
        ConfigError: an unknown criterion.
    """
    x = result.rmse_m + collision_cost_m * result.collided
    if criterion == "mean":
        return float(np.mean(x))
    if criterion == "median":
        return float(np.median(x))
    if criterion == "mean+median":
        return 0.5 * float(np.mean(x) + np.median(x))
    raise ConfigError(f"criterion must be one of {CRITERIA}, got {criterion!r}")


def _theta(config: ReplayFitConfig, free_w: dict[str, float]) -> np.ndarray:
    names = config.planner.feature_names
    start = dict(config.start)
    w = {n: start.get(n, -1.0 if n == "comfort" else 0.0) for n in names}
    w.update(free_w)
    if config.tie_B:
        for n in names:
            if n.endswith("_B") and n[:-2] + "_C" in w:
                w[n] = w[n[:-2] + "_C"]
    return np.array([w[n] for n in names], dtype=np.float64)


def _unpack(config: ReplayFitConfig, u: np.ndarray) -> tuple[dict[str, float], dict[str, float]]:
    k = len(config.free)
    weights = {f: -float(np.exp(x)) for f, x in zip(config.free, u[:k])}
    shape = {}
    for s, x in zip(config.shape_free, u[k:]):
        lo, hi = SHAPE_BOUNDS[s]
        shape[s] = float(np.clip(np.exp(x), lo, hi))
    return weights, shape


def build_driver(config: ReplayFitConfig, weights: dict[str, float], shape: dict[str, float], base_shape: Shape,
                 action_acc_ft_s2: Sequence[float], info: dict[str, Any] | None = None) -> PlanningDriver:
    """The driver of free ``weights`` and ``shape`` parameters on ``base_shape`` (its ``v0``)."""
    cfg = config.planner
    return PlanningDriver(_theta(config, weights), cfg.feature_names, cfg, replace(base_shape, **shape),
                          cfg.decision_step_s, tuple(action_acc_ft_s2), info=dict(info or {}))


def fit_by_replay(pairs: Sequence[ReplayPair], base_shape: Shape, action_acc_ft_s2: Sequence[float],
                  config: ReplayFitConfig = ReplayFitConfig(), *, u0: np.ndarray | None = None,
                  log: Callable[[str], None] = lambda s: None) -> ReplayFit:
    """Fit the free weights and shape parameters by replay of ``pairs`` (module docstring).

    Args:
        pairs: the training pairs (ft, ft/s); base_shape: the shape whose ``v0`` (and fixed
            parameters) the driver keeps; action_acc_ft_s2: ``[5]`` the paper actions' training
            mean accelerations (the planner's later segments); config: the settings; u0: the
            log-parameters to start from (default :attr:`ReplayFitConfig.start` and
            :data:`START_SHAPE`); log: receives a progress line every 10 replays.

    Raises:
        DemonstrationError: no pairs. ConfigError: ``u0`` of the wrong length.
    """
    if not pairs:
        raise DemonstrationError("fit_by_replay: no pairs")
    t0 = time.perf_counter()
    start = dict(config.start)
    if u0 is None:
        u0 = np.array([math.log(max(-start.get(f, -1.0), 1e-6)) for f in config.free]
                      + [math.log(getattr(START_SHAPE, s)) for s in config.shape_free])
    u0 = np.asarray(u0, dtype=np.float64)
    if u0.shape != (len(config.free) + len(config.shape_free),):
        raise ConfigError(f"fit_by_replay: u0 must have {len(config.free) + len(config.shape_free)} values")
    evals: dict[str, Any] = {"n": 0, "best": math.inf}
    cache: dict[bytes, tuple[float, ReplayResult]] = {}

    def run(u: np.ndarray) -> tuple[float, ReplayResult]:
        key = np.round(u, 9).tobytes()
        if key not in cache:
            w, s = _unpack(config, u)
            drv = build_driver(config, w, s, base_shape, action_acc_ft_s2)
            res = replay(pairs, drv.act, config.planner.decision_step_s)
            cache[key] = (replay_objective(res, config.collision_cost_m, config.criterion), res)
            evals["n"] += 1
            evals["best"] = min(evals["best"], cache[key][0])
            if evals["n"] % 10 == 0:
                log(f"  replay fit: {evals['n']} replays, best {evals['best']:.3f} m "
                    f"({time.perf_counter() - t0:.0f} s)")
        return cache[key]

    start_obj = run(u0)[0]
    res = minimize(lambda u: run(u)[0], u0, method="Nelder-Mead",
                   options={"maxfev": config.max_evals, "xatol": config.xatol, "fatol": 1e-3, "adaptive": True,
                            "initial_simplex": u0 + np.vstack([np.zeros(u0.size), 0.7 * np.eye(u0.size)])})
    obj, rr = run(res.x)
    w, s = _unpack(config, res.x)
    drv = build_driver(config, w, s, base_shape, action_acc_ft_s2,
                       info={"fit": "replay", "replay_objective_m": obj, "replay_start_objective_m": start_obj,
                             "replay_evals": evals["n"], "replay_pairs": len(pairs),
                             "collision_cost_m": config.collision_cost_m, "criterion": config.criterion,
                             "tie_B": config.tie_B})
    return ReplayFit(drv, obj, start_obj, rr, evals["n"], bool(res.success), time.perf_counter() - t0,
                     {**w, **s, "u": list(map(float, res.x))})


def fit_temperature(driver: PlanningDriver, decisions: PlanningDecisions, *, chunk: int = 4000,
                    bounds: tuple[float, float] = (0.01, 100.0)) -> tuple[PlanningDriver, float]:
    """``(driver with its temperature, training LL per decision)``: ``tau`` maximising the mean
    ``log P(b | x)`` of ``decisions`` under ``softmax(Q / tau)`` (bounded, on ``log tau``); the
    backed-up values ``Q`` are computed once, in chunks of ``chunk`` decisions (memory).

    Raises:
        DemonstrationError: no decisions.
    """
    if decisions.n == 0:
        raise DemonstrationError("fit_temperature: no decisions")
    cfg = driver.config
    Qs: list[np.ndarray] = []
    bins = np.zeros(0, dtype=np.int64)
    for lo in range(0, decisions.n, chunk):
        d = decisions.take(np.arange(lo, min(lo + chunk, decisions.n)))
        T = path_tensors(d.obs, d.prev_acc, d.acc_C, driver.action_acc_ft_s2, driver.shape, cfg)
        Q, _ = q_values(path_returns(T, driver.theta, cfg.collision_penalty), cfg.backup, need_weights=False)
        Qs.append(Q)
        bins = T.bins
    Q = np.concatenate(Qs)
    y = decisions.actions

    def nll(log_tau: float) -> float:
        lp = bin_log_policy_of_fine(log_softmax(Q / math.exp(log_tau)), bins)
        return -float(lp[np.arange(y.size), y].mean())

    r = minimize_scalar(nll, bounds=tuple(math.log(b) for b in bounds), method="bounded", options={"xatol": 1e-3})
    tau = float(math.exp(r.x))
    fitted = replace(driver, config=replace(cfg, temperature=tau), info={**driver.info, "temperature": tau})
    return fitted, -float(r.fun)


def bootstrap_intervals(pairs: Sequence[ReplayPair], groups: Sequence[str], fit: ReplayFit, base_shape: Shape,
                        action_acc_ft_s2: Sequence[float], config: ReplayFitConfig, *, n_boot: int = 8,
                        evals: int = 30, seed: int = 0,
                        log: Callable[[str], None] = lambda s: None) -> dict[str, tuple[float, float]]:
    """``{parameter: (2.5 %, 97.5 %)}`` over refits (``evals`` replays each, from the fit) on
    ``n_boot`` resamples of the training followers (``groups [P]``, drawn with replacement).

    Raises:
        DemonstrationError: ``groups`` not one per pair.
    """
    if len(groups) != len(pairs):
        raise DemonstrationError("bootstrap_intervals: one group per pair expected")
    rng = np.random.default_rng(seed)
    g = np.asarray(groups)
    uniq = np.unique(g)
    by = {x: np.flatnonzero(g == x) for x in uniq}
    draws: dict[str, list[float]] = {}
    u0 = np.asarray(fit.params["u"], dtype=np.float64)
    for b in range(n_boot):
        idx = np.concatenate([by[x] for x in rng.choice(uniq, size=uniq.size, replace=True)])
        f = fit_by_replay([pairs[i] for i in idx], base_shape, action_acc_ft_s2, replace(config, max_evals=evals),
                          u0=u0)
        for k, v in f.params.items():
            if k != "u":
                draws.setdefault(k, []).append(float(v))
        log(f"  bootstrap {b + 1}/{n_boot}: objective {f.objective:.3f} m")
    return {k: (float(np.percentile(v, 2.5)), float(np.percentile(v, 97.5))) for k, v in draws.items()}
