"""The linear algebra of the Q backups: weights, backup operators, sparse solves, the exact
averaging fixed point, and derivatives of a Boltzmann fixed point by implicit differentiation.

Every backup here has the form (pairs flattened as ``i = s*A + a``, ``P`` a
:class:`~irl.transitions.SuccessorModel`, terminal pairs having an all-zero ``P`` row)::

    Q = R + gamma * P @ V(Q),       V(Q)(s') = sum_b w(b|s') Q(s', b)

* **averaging** (Q-Avg): ``w = 1/A``. Linear: ``(I - gamma M) q = r`` with
  ``M = P @ W``, ``W[s', s'*A+b] = 1/A``; one sparse LU factorisation serves every right-hand
  side, so ``D = (I - gamma M)^-1 Phi`` (``[S, A, K]``) gives ``Q = D theta`` for every theta.
* **Boltzmann** (Q-SM with the model-free ``P``; MLIRL with a full model ``T``):
  ``w = softmax(beta Q(s', .))``. Nonlinear; solved by Newton's method with a backtracking line
  search on the residual ``F(q) = q - r - gamma P V(q)``, whose Jacobian is
  ``I - gamma P J`` with ``J[s', s'*A+b] = pi(b|s') (1 + beta (Q(s',b) - V(s')))``. The same
  matrix gives ``dQ/dtheta``: ``(I - gamma P J) dQ = Phi`` (implicit differentiation).

The solvers of the nonlinear fixed point are :mod:`irl.bellman.fixed_point`; whether the damped
iteration is attracted to a fixed point, :mod:`irl.bellman.stability`.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from irl.transitions import SuccessorModel


def mean_weights(q: np.ndarray, beta: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Boltzmann mean of each state and its derivative weights.

    Args:
        q: ``[S, A]``.
    Returns:
        ``(V [S], pi [S, A], c [S, A])`` with ``V = sum_b pi_b q_b`` and
        ``c[s, b] = dV(s)/dq(s, b) = pi_b (1 + beta (q_b - V))``.
    """
    v, pit, ct = _soft_mean(np.asarray(q, dtype=np.float64).T, beta, True)
    return v, pit.T, ct.T


def _soft_mean(qt: np.ndarray, beta: float, with_c: bool):
    """``(V [S], pi^T [A, S], c^T [A, S] or None)`` of :func:`mean_weights` from ``qt = Q^T [A, S]``.

    Works action-major: reductions over the few actions of each state run along the long axis,
    several times faster than along a short last axis (this is the inner loop of every fixed point).
    """
    e = np.multiply(qt, beta, order="C")  # [A, S]
    e -= e.max(axis=0)
    np.exp(e, out=e)
    e /= e.sum(axis=0)
    v = (e * qt).sum(axis=0)
    if not with_c:
        return v, e, None
    ct = qt - v
    ct *= beta
    ct += 1.0
    ct *= e
    return v, e, ct


def weight_matrix(c: np.ndarray) -> sp.csr_matrix:
    """``[S, S*A]`` sparse matrix ``W`` with ``W[s, s*A+b] = c[s, b]`` (``c`` is ``[S, A]``)."""
    S, A = c.shape
    rows = np.repeat(np.arange(S), A)
    return sp.csr_matrix((c.ravel(), (rows, np.arange(S * A))), shape=(S, S * A))


def backup_operator(succ: SuccessorModel, c: np.ndarray, gamma: float) -> sp.csr_matrix:
    """``gamma P W(c)``, ``[S*A, S*A]`` sparse: the linear part of the backup with weights ``c``."""
    return sp.csr_matrix(gamma * (succ.p @ weight_matrix(c)))


def backup_jacobian(succ: SuccessorModel, c: np.ndarray, gamma: float) -> sp.csc_matrix:
    """``I - gamma P W(c)``, ``[S*A, S*A]`` sparse (CSC, ready for ``splu``)."""
    return succ.jacobian_pattern.matrix(np.asarray(c, dtype=np.float64), gamma)


def factorize(matrix: sp.csc_matrix):
    """Sparse LU of ``matrix``; raises ``RuntimeError`` when it is singular."""
    return spla.splu(matrix)


def solve_backup_system(succ: SuccessorModel, c: np.ndarray, gamma: float,
                        rhs: np.ndarray) -> np.ndarray:
    """Solve ``(I - gamma P W(c)) x = rhs`` (``rhs [S*A]`` or ``[S*A, K]``) by sparse LU.

    The pair system reduces to one over the states: with ``y = W x``,
    ``(I - gamma W P) y = W rhs`` and ``x = rhs + gamma P y`` (``W P`` is ``[S, S]``,
    ``det(I - gamma P W) = det(I - gamma W P)``), so the factorisation has ``A`` times fewer
    unknowns (on the merge driver encoding about 6x faster than the pair system). (SuperLU is
    single-threaded: unlike dense LAPACK it does not slow down when other processes share the
    cores.) Raises ``RuntimeError`` when the matrix is singular.
    """
    S, A = succ.n_states, succ.n_actions
    c = np.asarray(c, dtype=np.float64).reshape(S, A)
    rhs = np.asarray(rhs, dtype=np.float64)
    b = rhs.reshape(S * A, -1)
    wb = np.einsum("sa,sak->sk", c, b.reshape(S, A, -1))  # [S, K] = W rhs
    y = factorize(succ.state_pattern.matrix(c, gamma)).solve(np.ascontiguousarray(wb))
    return (b + gamma * (succ.p @ y)).reshape(rhs.shape)


def average_basis(succ: SuccessorModel, features: np.ndarray, gamma: float) -> np.ndarray:
    """``D = (I - gamma M)^-1 Phi`` for the averaging backup: ``[S, A, K]``, ``Q_avg = D @ theta``.

    ``I - gamma M`` is strictly diagonally dominant for ``gamma < 1`` (``M`` is sub-stochastic),
    so the factorisation always exists.
    """
    S, A, K = features.shape
    c = np.full((S, A), 1.0 / A)
    return solve_backup_system(succ, c, gamma, features.reshape(S * A, K)).reshape(S, A, K)


def boltzmann_dq(q: np.ndarray, succ: SuccessorModel, features: np.ndarray, beta: float,
                 gamma: float) -> np.ndarray:
    """``dQ/dtheta [S, A, K]`` at a Boltzmann fixed point ``q [S, A]`` (implicit differentiation).

    Raises ``RuntimeError`` if ``I - gamma P J`` is singular.
    """
    S, A, K = features.shape
    _, _, c = mean_weights(q, beta)
    return solve_backup_system(succ, c, gamma, features.reshape(S * A, K)).reshape(S, A, K)
