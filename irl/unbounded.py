"""Unbounded likelihoods of the Boltzmann-backup methods (Q-SM, MLIRL): detection by recession direction.

Q-Avg's Q is linear in theta, and a linear programme decides whether its likelihood has a
finite maximiser (:func:`irl.ascent.recession_direction`). For the Boltzmann backup
``Q = R + gamma P V_beta(Q)`` the Q of ``c d`` grows like ``c Q_max(d)`` as ``c -> infinity``,
where ``Q_max(d)`` solves the hard-max Bellman equation ``Q = phi d + gamma P max_b Q(s', b)``
(``V_beta`` of a table scaled by ``c`` tends to its maximum). So along the ray ``c d`` the
policy tends to the uniform choice among the actions maximising ``Q_max(d)(s, .)``, and the
likelihood rises toward its supremum without reaching it when ``d`` is a *recession
direction*: at every demonstrated step the demonstrated action is among the maximisers of
``Q_max(d)(s, .)``, and at some step it beats some other action (the nonlinear analogue of
the LP's "never decreases, somewhere rises").

:func:`boltzmann_recession` tests candidate directions (where the fit went: theta itself, its
displacement from the start, the last gradient) with this criterion and confirms numerically
that the likelihood does not fall when moving further along the direction found.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable

import numpy as np

from irl.bellman.operators import solve_backup_system
from irl.transitions import SuccessorModel

#: Relative tolerance (of the Q scale ``max|R|/(1-gamma)``) below which two Q values tie.
TIE_TOL = 1e-9


def hardmax_q(r: np.ndarray, succ: SuccessorModel, gamma: float, max_iter: int = 200) -> np.ndarray:
    """``[S, A]`` solution of ``Q = R + gamma P max_b Q(s', b)`` (terminal pairs: ``Q = R``).

    Policy iteration: evaluate the greedy policy exactly (one sparse solve of
    ``(I - gamma P W) q = r``), improve it, until no state's greedy action changes by more than
    the tie tolerance. ``r`` is ``[S, A]``.

    Raises:
        RuntimeError: no stable policy within ``max_iter`` improvements (not expected for
            ``gamma < 1``), or a singular system.
    """
    S, A = r.shape
    r = np.asarray(r, dtype=np.float64)
    tol = TIE_TOL * max(1.0, float(np.max(np.abs(r))) / (1.0 - gamma))
    greedy = np.argmax(r, axis=1)
    rows = np.arange(S)
    for _ in range(max_iter):
        w = np.zeros((S, A))
        w[rows, greedy] = 1.0
        q = solve_backup_system(succ, w, gamma, r.ravel()).reshape(S, A)
        best = np.argmax(q, axis=1)
        improve = q[rows, best] > q[rows, greedy] + tol
        if not np.any(improve):
            return q
        greedy = np.where(improve, best, greedy)
    raise RuntimeError(f"hard-max policy iteration did not settle in {max_iter} improvements")


def is_recession_direction(d: np.ndarray, features: np.ndarray, succ: SuccessorModel, counts: np.ndarray,
                           gamma: float) -> bool:
    """Whether ``d [K]`` is a recession direction of the Boltzmann-backup likelihood (module doc).

    Args:
        features: ``[S, A, K]``; counts: ``[S, A]`` demonstrated steps per pair.
    """
    q = hardmax_q(features @ d, succ, gamma)
    tol = TIE_TOL * max(1.0, float(np.max(np.abs(features @ d))) / (1.0 - gamma))
    ss, aa = np.nonzero(counts > 0)
    if ss.size == 0:
        return False
    gaps = q[ss, aa][:, None] - q[ss]  # [n_obs, A]: demonstrated minus every action
    gaps[np.arange(ss.size), aa] = 0.0
    return bool(gaps.min() >= -tol and gaps.max() > tol)


def boltzmann_recession(
    theta: np.ndarray,
    candidates: Iterable[np.ndarray],
    features: np.ndarray,
    succ: SuccessorModel,
    counts: np.ndarray,
    gamma: float,
    loglik: Callable[[np.ndarray], float | None],
) -> tuple[np.ndarray, float] | None:
    """A candidate direction along which the likelihood rises above ``L(theta)`` without bound.

    Args:
        theta: ``[K]`` where the fit stopped; candidates: ``[K]`` directions (zero or non-finite
            ones are skipped; each is normalised). The feature axes ``+-e_k`` are tried after them.
        features, succ, counts, gamma: the problem (see :func:`is_recession_direction`).
        loglik: ``L`` at a theta, or None where it cannot be computed.

    Returns:
        ``(unit direction d [K], L at the best point tried along it)`` or None. A candidate
        passes when it is a recession direction and ``L`` at one of ``theta + t d`` or ``c d``
        (``t = 1 + |theta|``, ``c = t, 4t, 16t``) is not below ``L(theta)`` beyond round-off: the
        fit stopped where the likelihood is still rising toward a supremum at infinity.
    """
    theta = np.asarray(theta, dtype=np.float64)
    k = theta.size
    l0 = loglik(theta)
    if l0 is None:
        return None
    axes = np.concatenate([np.eye(k), -np.eye(k)]) if k <= 20 else np.empty((0, k))
    t = 1.0 + float(np.linalg.norm(theta))
    for cand in [*candidates, *axes]:
        c = np.asarray(cand, dtype=np.float64)
        norm = float(np.linalg.norm(c))
        if not np.isfinite(norm) or norm == 0.0:
            continue
        d = c / norm
        try:
            if not is_recession_direction(d, features, succ, counts, gamma):
                continue
        except RuntimeError:
            continue
        values = [v for v in (loglik(theta + t * d), *(loglik(m * t * d) for m in (1.0, 4.0, 16.0)))
                  if v is not None]
        if values and max(values) >= l0 - 1e-9 * max(1.0, abs(l0)):
            return d, max(values)
    return None
