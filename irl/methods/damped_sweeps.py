"""The paper-faithful damped in-place sweeps (Eq. 12/13 for Q-Avg, Eq. 15/16 for Q-SM).

One sweep, as in the authors' code (which sweeps only the observed transitions, in place, in
data order, and treats every other pair as terminal), with learning rate ``alpha``:

1. every **terminal** pair (no observed successor: never seen, or only as a trajectory's last
   step) is pulled toward its reward, ``x <- (1-alpha) x + alpha R`` (``dQ`` toward ``phi``);
2. every observed transition ``(s_t, a_t) -> s_{t+1}`` (every step but each trajectory's last),
   in data order, updates in place
   ``x[s_t,a_t] <- (1-alpha) x[s_t,a_t] + alpha (R[s_t,a_t] + gamma sum_b w_b x[s_{t+1}, b])``
   reading the values already updated earlier in the same sweep.

The order of step 1 vs step 2 is our choice (the reference leaves it implicit); it only changes
the transient, not the fixed point.

Speed without changing the arithmetic: for fixed weights ``w`` a sweep is an affine map of the
table, ``x' = G x + H r``. :func:`compose_sweep` builds ``G, H`` once by applying the same
elementary in-place updates to the rows of an identity matrix, so each sweep is one matrix
product, exactly equivalent to the sequential loop (up to rounding). This covers Q-Avg's Q and
dQ (``w = 1/A``) and Q-SM's dQ (``w`` = the Boltzmann-mean derivative weights at the current
Q, fixed while dQ is iterated). Q-SM's Q sweep is nonlinear and runs as a plain loop
(:func:`softmax_sweep`). Only pairs of states that occur in the demonstrations are in the
composed matrices; every other pair is terminal and pulled toward ``R`` by a vector operation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from irl.demonstrations import Demonstrations


@dataclass(frozen=True)
class SweepPlan:
    """The observed transitions of the demonstrations, in data order, on local pair indices.

    Attributes:
        n_states, n_actions: ``S``, ``A``.
        active: ``[n]`` flat pair indices (``s*A + a``) of every pair of every state seen.
        outside: flat pair indices of all other pairs (all terminal).
        local_terminal: ``[n_term]`` local indices of terminal pairs among ``active``.
        src: ``[M]`` local index of ``(s_t, a_t)`` of each observed transition.
        dst_state: ``[M]`` successor state ``s_{t+1}`` (global id).
        dst: ``[M, A]`` local indices of the successor's pairs ``(s_{t+1}, b)``.
    """

    n_states: int
    n_actions: int
    active: np.ndarray
    outside: np.ndarray
    local_terminal: np.ndarray
    src: np.ndarray
    dst_state: np.ndarray
    dst: np.ndarray

    @property
    def n_active(self) -> int:
        return int(self.active.size)


def make_plan(demos: Demonstrations) -> SweepPlan:
    """Index the demonstrations' transitions for sweeping."""
    S, A = demos.n_states, demos.n_actions
    states, _, _ = demos.flat()
    seen_states = np.unique(states)
    active = (seen_states[:, None] * A + np.arange(A)[None, :]).ravel()
    local = np.full(S * A, -1, dtype=np.int64)
    local[active] = np.arange(active.size)
    s, a, s2 = demos.transitions()
    has_succ = np.zeros(S * A, dtype=bool)
    has_succ[s * A + a] = True
    terminal_active = np.flatnonzero(~has_succ[active])
    outside = np.setdiff1d(np.arange(S * A), active)
    dst = local[(s2[:, None] * A + np.arange(A)[None, :])]
    return SweepPlan(S, A, active, outside, terminal_active, local[s * A + a], s2, dst)


def compose_sweep(plan: SweepPlan, weights: np.ndarray, alpha: float, gamma: float) -> np.ndarray:
    """The affine map of one sweep on the active pairs, ``[n, 2n]`` = ``[G | H]``.

    Args:
        weights: ``[S, A]`` successor weights ``w(b|s')`` (fixed during the sweep).
    Returns:
        ``GH`` with ``x_after = GH[:, :n] @ x_before + GH[:, n:] @ r`` (``x, r`` local ``[n, ...]``).
    """
    n = plan.n_active
    gh = np.zeros((n, 2 * n))
    gh[:, :n] = np.eye(n)
    t = plan.local_terminal
    gh[t, t] = 1.0 - alpha
    gh[t, n + t] = alpha
    w_all = weights[plan.dst_state] * (alpha * gamma)  # [M, A]
    for k in range(plan.src.size):
        i = plan.src[k]
        row = (1.0 - alpha) * gh[i] + w_all[k] @ gh[plan.dst[k]]
        row[n + i] += alpha
        gh[i] = row
    return gh


def iterate_affine(gh: np.ndarray, x: np.ndarray, r: np.ndarray, x_out: np.ndarray,
                   r_out: np.ndarray, alpha: float, max_sweeps: int, tol: float
                   ) -> tuple[np.ndarray, np.ndarray, int, bool]:
    """Run composed sweeps until the largest change of any entry is below ``tol``.

    Args:
        gh: ``[n, 2n]`` from :func:`compose_sweep`.
        x, r: ``[n, ...]`` active values and rewards (or ``dQ`` and ``phi``).
        x_out, r_out: ``[m, ...]`` the other (terminal) pairs and their targets.
    Returns:
        ``(x, x_out, sweeps, converged)``.
    """
    n = gh.shape[0]
    g, h = gh[:, :n], gh[:, n:]
    hr = h @ r
    for sweep in range(1, max_sweeps + 1):
        x_new = g @ x + hr
        out_new = (1.0 - alpha) * x_out + alpha * r_out
        change = max(float(np.max(np.abs(x_new - x), initial=0.0)),
                     float(np.max(np.abs(out_new - x_out), initial=0.0)))
        x, x_out = x_new, out_new
        if not math.isfinite(change):
            return x, x_out, sweep, False
        if change < tol:
            return x, x_out, sweep, True
    return x, x_out, max_sweeps, False


def softmax_sweep(plan: SweepPlan, x: np.ndarray, r: np.ndarray, beta: float, alpha: float,
                  gamma: float) -> tuple[np.ndarray, float]:
    """One in-place Q-SM sweep (Eq. 15) over the active pairs.

    Args:
        x: ``[n]`` local Q values before the sweep; r: ``[n]`` local rewards.
    Returns:
        ``(x after the sweep, largest change)``. Terminal pairs first (vectorised: they do not
        read each other), then the observed transitions in data order, each reading the values
        already updated in this sweep. The softmax uses max subtraction, so any ``beta Q`` is safe.
    """
    keep = 1.0 - alpha
    t = plan.local_terminal
    x = np.array(x, dtype=np.float64)
    new_t = keep * x[t] + alpha * r[t]
    change = float(np.max(np.abs(new_t - x[t]), initial=0.0))
    x[t] = new_t
    xs = x.tolist()
    rs = r.tolist()
    exp = math.exp
    for i, js in zip(plan.src.tolist(), plan.dst.tolist()):
        vals = [xs[j] for j in js]
        m = max(vals)
        z = 0.0
        acc = 0.0
        for v in vals:
            w = exp(beta * (v - m))
            z += w
            acc += w * v
        new = keep * xs[i] + alpha * (rs[i] + gamma * acc / z)
        d = abs(new - xs[i])
        if d > change or d != d:
            change = d
        xs[i] = new
    return np.array(xs), change
