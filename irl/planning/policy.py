"""Backups, the log policy over the fine first actions and the paper actions, and the exact
gradient of the log-likelihood.

Path returns ``R = Phi theta + penalty Col`` (``[N, G, C, (C)]``,
:mod:`irl.planning.model`) are backed up to the first action over each later
action axis in turn (last first):

* ``avg``: the plain mean (Q-Avg's backup, MacGlashan & Littman 2015, "Between imitation and
  intention learning", IJCAI);
* ``boltzmann``: ``sum_a softmax(X)_a X_a`` (the Boltzmann expectation of Q-SM / MLIRL,
  Babes-Vroman et al. 2011, ICML);
* ``softmax``: ``logsumexp_a X_a`` (the soft value of maximum-entropy IRL, Ziebart et al. 2008).

**Policy** over fine first actions ``g``: ``pi(g | x) = softmax_g Q(x, g)``. The scoring unit is
the paper action: ``P(b | x) = sum_{g in b} pi(g | x)`` (``b`` the bin of ``g``'s acceleration).
The gradient of ``log P(b | x)`` w.r.t. ``theta`` is exact:
``sum_g (pi(g | x, b) - pi(g | x)) dQ(g)/dtheta`` with ``dQ(g)/dR(leaf)`` the product of each
level's derivative (avg ``1/C``; softmax ``p_a``; boltzmann ``p_a (1 + X_a - V)``).

**Actuation lag** (:attr:`~irl.planning.model.PlannerConfig.lag` ``< 1``): a fine
choice ``g`` applies ``(1 - k) a_prev + k g``, so its bin depends on the decision (``bins [N, G]``)
and a paper action may be out of reach of every choice; then
``P(b | x) = (1 - eps) sum_{g: bin_n(g) = b} pi(g | x) + eps / 5`` (:data:`LAG_FLOOR` ``eps``),
whose gradient is the above times ``(1 - eps) P_model(b) / P(b)``.
"""

from __future__ import annotations

import numpy as np

from irl.domains.merge.actions import N_ACTIONS
from irl.errors import ConfigError
from irl.planning.model import PathTensors

#: ``eps`` of the uniform floor of the paper-action probabilities under an actuation lag.
LAG_FLOOR = 1e-4


def backup(X: np.ndarray, kind: str) -> tuple[np.ndarray, np.ndarray]:
    """``(V [...], w [..., C])``: the backup ``kind`` of ``X [..., C]`` over its last axis and
    ``w = dV/dX``.

    Raises:
        ConfigError: an unknown ``kind``.
    """
    if kind == "avg":
        return X.mean(axis=-1), np.full(X.shape, 1.0 / X.shape[-1])
    if kind not in ("boltzmann", "softmax"):
        raise ConfigError(f"unknown backup {kind!r}")
    m = X.max(axis=-1, keepdims=True)
    e = np.exp(X - m)
    z = e.sum(axis=-1, keepdims=True)
    p = e / z
    if kind == "softmax":
        return (m + np.log(z))[..., 0], p
    V = (p * X).sum(axis=-1)
    return V, p * (1.0 + X - V[..., None])


def q_values(R: np.ndarray, kind: str, *, need_weights: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
    """``(Q [N, G], W)`` of path returns ``R [N, G, C, (C)]``: the nested backup over the later
    axes and ``W = dQ[n, g] / dR[n, g, ...]`` (shape of ``R``; None unless ``need_weights``)."""
    X = R
    W: np.ndarray | None = None
    while X.ndim > 2:
        X, w = backup(X, kind)
        if need_weights:
            W = w if W is None else w.reshape(w.shape + (1,) * (W.ndim - w.ndim)) * W
    return X, W


def log_softmax(Q: np.ndarray) -> np.ndarray:
    """Row-wise log-softmax of ``Q [N, G]``."""
    m = Q.max(axis=1, keepdims=True)
    return Q - m - np.log(np.exp(Q - m).sum(axis=1, keepdims=True))


def bin_log_policy_of_fine(lp_fine: np.ndarray, bins: np.ndarray) -> np.ndarray:
    """``[N, 5]`` ``log P(b | x)`` from ``lp_fine [N, G]`` and the bins ``[G]`` of the fine
    actions (``-inf`` for a paper action without a fine action), or ``[N, G]`` under an actuation
    lag (with the floor :data:`LAG_FLOOR`, module docstring)."""
    out = np.full((lp_fine.shape[0], N_ACTIONS), -np.inf)
    if bins.ndim == 2:
        p = np.exp(lp_fine)  # a normalised log policy: no overflow
        for b in range(N_ACTIONS):
            out[:, b] = np.log((1.0 - LAG_FLOOR) * np.where(bins == b, p, 0.0).sum(axis=1) + LAG_FLOOR / N_ACTIONS)
        return out
    for b in range(N_ACTIONS):
        sel = bins == b
        if sel.any():
            x = lp_fine[:, sel]
            m = x.max(axis=1, keepdims=True)
            out[:, b] = (m + np.log(np.exp(x - m).sum(axis=1, keepdims=True)))[:, 0]
    return out


def path_returns(T: PathTensors, theta: np.ndarray, penalty: float) -> np.ndarray:
    """``R = Phi theta + penalty Col``, the shape of ``T.Col``."""
    return T.Phi @ np.asarray(theta, dtype=np.float64) + penalty * T.Col


def fine_log_policy(T: PathTensors, theta: np.ndarray, kind: str, penalty: float,
                    temperature: float = 1.0) -> np.ndarray:
    """``[N, G]`` ``log pi(g | x) = log softmax(Q / temperature)`` of precomputed paths."""
    Q, _ = q_values(path_returns(T, theta, penalty), kind, need_weights=False)
    return log_softmax(Q / temperature)


def bin_log_policy(T: PathTensors, theta: np.ndarray, kind: str, penalty: float,
                   temperature: float = 1.0) -> np.ndarray:
    """``[N, 5]`` ``log P(b | x)`` of precomputed paths."""
    return bin_log_policy_of_fine(fine_log_policy(T, theta, kind, penalty, temperature), T.bins)


def loglik_grad(theta: np.ndarray, T: PathTensors, actions: np.ndarray, kind: str, penalty: float,
                weights: np.ndarray | None = None) -> tuple[float, np.ndarray]:
    """``(sum_n w_n log P(b_n | x_n), its [K] gradient)`` (nats; module docstring), exact.

    Args:
        theta: ``[K]``; T: path tensors of ``N`` decisions; actions: ``[N]`` paper actions;
        kind: the backup; penalty: the collision penalty; weights: ``[N]`` or None (ones).

    Raises:
        ConfigError: an observed paper action has no fine action (its probability is 0).
    """
    theta = np.asarray(theta, dtype=np.float64)
    actions = np.asarray(actions, dtype=np.int64)
    w = np.ones(T.n) if weights is None else np.asarray(weights, dtype=np.float64)
    Q, W = q_values(path_returns(T, theta, penalty), kind)
    lp = log_softmax(Q)  # [N, G]
    if T.bins.ndim == 2:  # an actuation lag: per-decision bins and the floor
        in_bin = T.bins == actions[:, None]
        pg = np.where(in_bin, np.exp(lp), 0.0)
        pm = pg.sum(axis=1)  # P_model(b_n)
        P = (1.0 - LAG_FLOOR) * pm + LAG_FLOOR / N_ACTIONS
        ll = float((w * np.log(P)).sum())
        # d log P = (1 - eps) / P * sum_{g in b} p_g (dQ_g - E dQ)
        r = (1.0 - LAG_FLOOR) / P
        coef = r[:, None] * (pg - pm[:, None] * np.exp(lp))
    else:
        in_bin = T.bins[None, :] == actions[:, None]  # [N, G]
        if not in_bin.any(axis=1).all():
            raise ConfigError(f"paper actions {sorted(set(actions.tolist()) - set(T.bins.tolist()))} have no fine "
                              f"action")
        lpb = np.where(in_bin, lp, -np.inf)
        m = lpb.max(axis=1, keepdims=True)
        lse = m + np.log(np.exp(lpb - m).sum(axis=1, keepdims=True))  # [N, 1] log P(b_n)
        ll = float((w * lse[:, 0]).sum())
        coef = np.where(in_bin, np.exp(lpb - lse), 0.0) - np.exp(lp)
    coef *= w[:, None]
    K = T.Phi.shape[-1]
    M = coef if W is None else coef.reshape(coef.shape + (1,) * (W.ndim - 2)) * W
    grad = M.reshape(-1) @ T.Phi.reshape(-1, K)
    return ll, grad
