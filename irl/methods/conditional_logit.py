"""The conditional logit over per-decision features: maximum-likelihood IRL at gamma 0.

``pi(a | x_i) = softmax_a(theta . phi(x_i, a))`` for decisions ``i`` with their own feature
rows ``F[i] [A, K]`` (McFadden's conditional logit). It is the Boltzmann policy of
:mod:`irl.boltzmann` with ``Q = F theta`` and beta 1, i.e. Q-Avg / MLIRL at discount 0 (paper
Eq. 5 with ``Q = R``), written for features of continuous observations, where every decision
is its own state, instead of a state table ``[S, A, K]`` (:func:`fit_state_logit` fits the same
logit over a state table). Beta is not separate from theta (the policy depends on ``beta theta``
only), so the scale is learned in theta.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize

from irl.boltzmann import log_policy, loglik_grad_from_counts, step_counts
from irl.errors import ConfigError, DemonstrationError


@dataclass(frozen=True)
class LogitFit:
    """What :func:`fit_conditional_logit` returns.

    Attributes:
        theta: ``[K]`` weights.
        loglik: training log-likelihood at ``theta`` (nats, without the penalty).
        n_steps: decisions fitted.
        converged: L-BFGS reported success.
        message: the optimiser's message.
    """

    theta: np.ndarray
    loglik: float
    n_steps: int
    converged: bool
    message: str


def _check(F: np.ndarray, actions: np.ndarray, weights: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    F = np.asarray(F, dtype=np.float64)
    actions = np.asarray(actions)
    if F.ndim != 3 or F.shape[0] == 0:
        raise ConfigError(f"features must be a non-empty [N, A, K] array, got shape {F.shape}")
    if not np.all(np.isfinite(F)):
        raise ConfigError("features contain NaN or infinite values")
    if actions.shape != (F.shape[0],) or not np.issubdtype(actions.dtype, np.integer):
        raise DemonstrationError(f"actions must be [N] = [{F.shape[0]}] integers, got {actions.shape} {actions.dtype}")
    if actions.size and (actions.min() < 0 or actions.max() >= F.shape[1]):
        raise DemonstrationError(f"actions must lie in 0..{F.shape[1] - 1}, got {actions.min()}..{actions.max()}")
    w = np.ones(F.shape[0]) if weights is None else np.asarray(weights, dtype=np.float64)
    if w.shape != (F.shape[0],) or not np.all(np.isfinite(w)) or np.any(w < 0):
        raise ConfigError(f"weights must be [N] = [{F.shape[0]}] finite non-negative numbers")
    return F, actions.astype(np.int64), w


def _counts(actions: np.ndarray, n_actions: int, weights: np.ndarray) -> np.ndarray:
    counts = np.zeros((actions.size, n_actions))
    counts[np.arange(actions.size), actions] = weights
    return counts


def penalised_nll(theta: np.ndarray, F: np.ndarray, counts: np.ndarray, l2: float) -> tuple[float, np.ndarray]:
    """``-sum_i sum_a counts[i, a] log pi(a | x_i) + l2/2 |theta|^2`` and its ``[K]`` gradient.

    Args:
        theta: ``[K]``; F: ``[N, A, K]``; counts: ``[N, A]`` (one-hot actions, or weights);
        l2: the L2 penalty (>= 0).
    """
    ll, grad = loglik_grad_from_counts(F @ theta, F, 1.0, counts)
    return -ll + 0.5 * l2 * float(theta @ theta), -grad + l2 * theta


def fit_conditional_logit(F: np.ndarray, actions: np.ndarray, *, l2: float = 0.1,
                          weights: np.ndarray | None = None, max_iter: int = 1000) -> LogitFit:
    """Maximum-likelihood weights of the conditional logit (L-BFGS from theta = 0).

    Args:
        F: ``[N, A, K]`` features of each decision and action.
        actions: ``[N]`` the action taken at each decision (``0 .. A-1``).
        l2: L2 penalty ``l2/2 |theta|^2`` (>= 0; keeps weights finite on separable data).
        weights: ``[N]`` non-negative weight of each decision (None: 1 each).
        max_iter: L-BFGS iterations.

    Returns:
        :class:`LogitFit`; deterministic (no randomness).

    Raises:
        ConfigError: malformed ``F``, weights, or an ``l2`` that is negative or not finite.
        DemonstrationError: actions of the wrong shape or out of range.
    """
    if isinstance(l2, bool) or not isinstance(l2, (int, float)) or not (math.isfinite(l2) and l2 >= 0):
        raise ConfigError(f"l2 must be a finite number >= 0, got {l2!r}")
    F, actions, w = _check(F, actions, weights)
    counts = _counts(actions, F.shape[1], w)
    res = minimize(penalised_nll, np.zeros(F.shape[2]), args=(F, counts, float(l2)), jac=True,
                   method="L-BFGS-B", options={"maxiter": int(max_iter)})
    theta = np.asarray(res.x, dtype=np.float64)
    return LogitFit(theta, conditional_loglik(F, theta, actions), int(F.shape[0]), bool(res.success), str(res.message))


def fit_state_logit(F: np.ndarray, states: np.ndarray, actions: np.ndarray, *, l2: float,
                    x0: np.ndarray | None = None) -> np.ndarray:
    """Maximum-likelihood weights of the logit over a state table, ``pi(a | s) = softmax_a(F[s] theta)``:
    Q-Avg at gamma 0, minimising :func:`penalised_nll` of the decisions' ``[S, A]`` step counts
    (L-BFGS, scipy's default iteration limit). The penalty is this module's ``l2/2 |theta|^2``,
    whose convention Q-Avg's own L2 may not share.

    Args:
        F: ``[S, A, K]`` features of each state and action.
        states, actions: ``[N]`` the state and the action of each decision.
        l2: the L2 penalty (finite, >= 0).
        x0: ``[K]`` start (e.g. the weights of an earlier fit on fewer decisions); None: zeros.

    Returns:
        ``[K]`` float64 weights; deterministic.

    Raises:
        ConfigError: ``F`` not a non-empty finite ``[S, A, K]`` array, ``x0`` not ``[K]``, or a
            negative or non-finite ``l2``.
        DemonstrationError: ``states`` and ``actions`` not ``[N]`` integers of the same length,
            or out of range.
    """
    if isinstance(l2, bool) or not isinstance(l2, (int, float)) or not (math.isfinite(l2) and l2 >= 0):
        raise ConfigError(f"l2 must be a finite number >= 0, got {l2!r}")
    F = np.asarray(F, dtype=np.float64)
    if F.ndim != 3 or F.size == 0 or not np.all(np.isfinite(F)):
        raise ConfigError(f"features must be a non-empty finite [S, A, K] array, got shape {F.shape}")
    s, a = np.asarray(states), np.asarray(actions)
    if s.ndim != 1 or s.shape != a.shape or not (np.issubdtype(s.dtype, np.integer) and np.issubdtype(a.dtype, np.integer)):
        raise DemonstrationError(f"states and actions must be [N] integers of one length, got {s.shape} {s.dtype} "
                                 f"and {a.shape} {a.dtype}")
    if s.size and (s.min() < 0 or s.max() >= F.shape[0] or a.min() < 0 or a.max() >= F.shape[1]):
        raise DemonstrationError(f"states must lie in 0..{F.shape[0] - 1} and actions in 0..{F.shape[1] - 1}")
    theta0 = np.zeros(F.shape[2]) if x0 is None else np.asarray(x0, dtype=np.float64)
    if theta0.shape != (F.shape[2],):
        raise ConfigError(f"x0 must be [K] = [{F.shape[2]}], got shape {theta0.shape}")
    counts = step_counts(s, a, F.shape[0], F.shape[1])
    res = minimize(penalised_nll, theta0, args=(F, counts, float(l2)), jac=True, method="L-BFGS-B")
    return np.asarray(res.x, dtype=np.float64)


def conditional_log_policy(F: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """``[N, A]`` ``log pi(a | x_i)`` for features ``F [N, A, K]`` and weights ``theta [K]``."""
    return log_policy(np.asarray(F, dtype=np.float64) @ np.asarray(theta, dtype=np.float64), 1.0)


def conditional_loglik(F: np.ndarray, theta: np.ndarray, actions: np.ndarray) -> float:
    """Total ``sum_i log pi(a_i | x_i)`` (nats) of ``actions [N]`` under the logit."""
    lp = conditional_log_policy(F, theta)
    a = np.asarray(actions, dtype=np.int64)
    return float(lp[np.arange(a.size), a].sum())
