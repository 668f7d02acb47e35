"""Boltzmann policies and the demonstration log-likelihood, all in log space.

``pi(a|s) = softmax_a(beta Q(s, a))``; ``L = sum_traj sum_t log pi(a_t | s_t)`` (paper Eq. 5
without the ``log Pr(s_1)`` term, which does not depend on theta). Every function here uses
log-sum-exp with max subtraction, so large ``beta`` or large ``Q`` never overflows.
"""

from __future__ import annotations

import numpy as np

from irl.demonstrations import Demonstrations


def log_policy(q: np.ndarray, beta: float) -> np.ndarray:
    """``log pi(a|s)`` for ``q`` of shape ``[S, A]``; returns ``[S, A]``."""
    z = beta * np.asarray(q, dtype=np.float64)
    z = z - np.max(z, axis=1, keepdims=True)  # max subtraction: the largest term is exp(0)
    return z - np.log(np.sum(np.exp(z), axis=1, keepdims=True))


def policy(q: np.ndarray, beta: float) -> np.ndarray:
    """``pi(a|s)`` for ``q`` of shape ``[S, A]``; returns ``[S, A]``, rows sum to 1."""
    return np.exp(log_policy(q, beta))


def step_counts(states: np.ndarray, actions: np.ndarray, n_states: int, n_actions: int) -> np.ndarray:
    """How often each (s, a) occurs among the steps: ``[S, A]`` float64."""
    counts = np.zeros((n_states, n_actions))
    np.add.at(counts, (states, actions), 1.0)
    return counts


def demo_counts(demos: Demonstrations) -> np.ndarray:
    """``[S, A]`` step counts of every step of ``demos`` (the final ones too)."""
    states, actions, _ = demos.flat()
    return step_counts(states, actions, demos.n_states, demos.n_actions)


def loglik_from_counts(q: np.ndarray, beta: float, counts: np.ndarray) -> float:
    """``sum_{s,a} counts[s,a] log pi(a|s)``; ``q, counts`` are ``[S, A]``."""
    lp = log_policy(q, beta)
    mask = counts > 0
    return float(np.sum(counts[mask] * lp[mask]))


def loglik_grad_from_counts(
    q: np.ndarray, dq: np.ndarray, beta: float, counts: np.ndarray
) -> tuple[float, np.ndarray]:
    """Log-likelihood and its gradient with respect to theta.

    Args:
        q: ``[S, A]`` Q values at theta.
        dq: ``[S, A, K]``, ``dQ(s, a) / dtheta``.
        beta: inverse temperature.
        counts: ``[S, A]`` step counts of the demonstrations.

    Returns:
        ``(L, dL/dtheta [K])`` with ``d log pi(a|s) = beta (dQ(s,a) - sum_b pi(b|s) dQ(s,b))``.
    """
    lp = log_policy(q, beta)
    pi = np.exp(lp)
    mask = counts > 0
    ll = float(np.sum(counts[mask] * lp[mask]))
    n_s = counts.sum(axis=1)  # [S] steps per state
    expected_dq = np.einsum("sa,sak->sk", pi, dq)  # [S, K]
    grad = beta * (np.einsum("sa,sak->k", counts, dq) - n_s @ expected_dq)
    return ll, grad


def heldout_loglik(log_pi: np.ndarray, states: np.ndarray, actions: np.ndarray) -> tuple[float, float]:
    """Log-likelihood of demonstration steps under a policy.

    Args:
        log_pi: ``[S, A]`` log pi(a|s).
        states, actions: ``[N]`` int steps (all trajectories concatenated).

    Returns:
        ``(sum, mean per step)`` of ``log pi(a_t|s_t)`` (Eq. 5 without ``log Pr(s_1)``).
    """
    s = np.asarray(states, dtype=np.int64)
    a = np.asarray(actions, dtype=np.int64)
    if s.size == 0:
        return float("nan"), float("nan")
    total = float(np.sum(np.asarray(log_pi)[s, a]))
    return total, total / s.size
