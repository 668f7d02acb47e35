"""Maximum-likelihood fit of the planner's reward weights and held-out selection of its settings.

Objective: the mean penalised negative log-likelihood of the observed paper actions,
``(-sum_n w_n log P(b_n | x_n) + l2/2 |theta|^2) / sum_n w_n``
(:func:`irl.planning.policy.loglik_grad`), minimised by scipy's L-BFGS-B from
``theta0`` (0 by default) with the exact gradient: deterministic. Settings are compared by the
held-out log-likelihood per decision on a split by group (encounter / pair), never by row.
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import minimize

from irl.errors import ConfigError
from irl.planning.model import BACKUPS, PathTensors, PlannerConfig
from irl.planning.policy import bin_log_policy, loglik_grad


@dataclass(frozen=True)
class PlannerFit:
    """What :func:`fit_planner` returns.

    Attributes:
        theta: ``[K]``; loglik: training log-likelihood (nats, weighted sum, no penalty);
        converged: L-BFGS-B reported success; grad_norm: norm of the gradient of the mean
        penalised objective at ``theta`` (nats per decision); n_iter: iterations; message: the
        optimiser's; seconds: wall time.
    """

    theta: np.ndarray
    loglik: float
    converged: bool
    grad_norm: float
    n_iter: int
    message: str
    seconds: float


def fit_planner(T: PathTensors, actions: np.ndarray, config: PlannerConfig, *, l2: float = 0.1,
                weights: np.ndarray | None = None, theta0: np.ndarray | None = None,
                max_iter: int = 1000) -> PlannerFit:
    """Maximum-likelihood weights (module docstring) of paths ``T`` and paper ``actions [N]``.

    For conditioning the optimiser works on centred, scaled features: each decision's path
    features minus their mean over its paths (every backup and the softmax are shift-equivariant,
    so the policy does not change), divided by each feature's standard deviation ``s_k``; the
    weights and the penalty are those of the original features. A fixed jerk weight
    (:attr:`~irl.planning.model.PlannerConfig.jerk_weight`) is not fitted: its
    feature's return joins the collision penalty's as a fixed part of every path's return, and
    the weight is returned in its place in ``theta`` (no L2 on it; ``grad_norm`` over the others).

    Raises:
        ConfigError: ``l2 < 0``, no decisions, or an observed action without a fine action.
    """
    if not l2 >= 0 or T.n == 0:
        raise ConfigError(f"fit_planner: needs l2 >= 0 and decisions, got l2 {l2} and {T.n} decisions")
    t0 = time.perf_counter()
    w = np.ones(T.n) if weights is None else np.asarray(weights, dtype=np.float64)
    wsum = float(w.sum())
    fixed = config.jerk_weight if config.jerk else None
    if fixed is not None:  # the fixed return joins the penalty's (penalty 1 on it)
        j = config.feature_names.index("jerk")
        T_full, T = T, PathTensors(np.delete(T.Phi, j, axis=-1),
                                   config.collision_penalty * T.Col + fixed * T.Phi[..., j], T.bins)
        if theta0 is not None:
            theta0 = np.delete(np.asarray(theta0, dtype=np.float64), j)
    K = T.Phi.shape[-1]
    Pc = T.Phi - T.Phi.mean(axis=tuple(range(1, T.Phi.ndim - 1)), keepdims=True)
    scale = Pc.reshape(-1, K).std(axis=0)
    scale = np.where(scale > 1e-12, scale, 1.0)
    Pc /= scale
    Tc = PathTensors(Pc, T.Col, T.bins)
    kind, pen = config.backup, (config.collision_penalty if fixed is None else 1.0)

    def f(tp: np.ndarray) -> tuple[float, np.ndarray]:
        theta = tp / scale
        ll, g = loglik_grad(tp, Tc, actions, kind, pen, w)
        return (-ll + 0.5 * l2 * float(theta @ theta)) / wsum, (-g + l2 * theta / scale) / wsum

    x0 = np.zeros(K) if theta0 is None else np.asarray(theta0, dtype=np.float64) * scale
    res = minimize(f, x0, jac=True, method="L-BFGS-B", options={"maxiter": max_iter, "ftol": 1e-12, "gtol": 1e-6})
    theta = np.asarray(res.x, dtype=np.float64) / scale
    ll, g = loglik_grad(theta, T, actions, kind, pen, w)
    grad = (-g + l2 * theta) / wsum
    if fixed is not None:
        theta = np.insert(theta, j, fixed)
        ll = loglik_grad(theta, T_full, actions, kind, config.collision_penalty, w)[0]
    return PlannerFit(theta, ll, bool(res.success), float(np.linalg.norm(grad)), int(res.nit), str(res.message),
                      time.perf_counter() - t0)


def heldout_ll_per_decision(T: PathTensors, actions: np.ndarray, theta: np.ndarray, config: PlannerConfig) -> float:
    """Mean ``log P(b_n | x_n)`` (nats per decision)."""
    lp = bin_log_policy(T, theta, config.backup, config.collision_penalty)
    return float(lp[np.arange(T.n), np.asarray(actions, dtype=np.int64)].mean())


@dataclass(frozen=True)
class Trial:
    """One setting's held-out score (nats per decision)."""

    config: PlannerConfig
    val_ll: float
    train_ll: float
    converged: bool
    seconds: float


#: ``build(config, "fit" | "val") -> PathTensors`` of the fitting / validation decisions.
Build = Callable[[PlannerConfig, str], PathTensors]


def select(build: Build, y_fit: np.ndarray, y_val: np.ndarray, *, base: PlannerConfig | None = None,
           grids: Iterable[str] = ("bins", "g13", "g24"), horizons: Iterable[float] = (2.1, 3.0, 3.9),
           gammas: Iterable[float] = (1.0, 0.9, 0.8), l2: float = 0.1,
           log: Callable[[str], None] = lambda s: None) -> tuple[PlannerConfig, list[Trial]]:
    """Staged held-out selection (coordinate-wise, deterministic; the best by validation LL):

    1. every ``grid`` x backup, horizon 2.1 s, depth 2, C at constant velocity, ``gamma`` 1;
    2. the best x every horizon x C model (``cv``, ``ca``);
    3. the best x every ``gamma``;
    4. the best with the other later segments (``bins`` / ``bins+hold``), with depth 3, and with
       the biases switched.
    """
    trials: list[Trial] = []
    seen: set[PlannerConfig] = set()
    horizons, gammas = tuple(horizons), tuple(gammas)

    def run(cfgs: Iterable[PlannerConfig]) -> PlannerConfig:
        for cfg in cfgs:
            if cfg in seen:
                continue
            seen.add(cfg)
            Tf, Tv = build(cfg, "fit"), build(cfg, "val")
            fit = fit_planner(Tf, y_fit, cfg, l2=l2)
            tr = Trial(cfg, heldout_ll_per_decision(Tv, y_val, fit.theta, cfg), fit.loglik / Tf.n, fit.converged,
                       fit.seconds)
            trials.append(tr)
            log(f"  {label(cfg)}: val LL/dec {tr.val_ll:.4f}, train {tr.train_ll:.4f}, converged {fit.converged}, "
                f"{fit.seconds:.1f} s")
        return max(trials, key=lambda t: t.val_ll).config

    b0 = replace(base or PlannerConfig(), horizon_s=2.1, depth=2, c_model="cv", gamma=1.0)
    best = run(replace(b0, grid=g, backup=k) for g, k in itertools.product(grids, BACKUPS))
    best = run(replace(best, horizon_s=h, c_model=c) for h, c in itertools.product(horizons, ("cv", "ca")))
    best = run(replace(best, gamma=g) for g in gammas)
    other = "bins" if best.later == "bins+hold" else "bins+hold"
    return run([replace(best, later=other), replace(best, depth=3), replace(best, with_bias=not best.with_bias)]), \
        trials


def label(c: PlannerConfig) -> str:
    """A one-line description of a setting."""
    return (f"grid={c.grid:4s} {c.backup:9s} H={c.horizon_s:.1f}s depth={c.depth} C={c.c_model} "
            f"gamma={c.gamma:.2f} later={c.later} bias={'y' if c.with_bias else 'n'}")
