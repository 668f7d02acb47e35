"""Whether a fixed point of the Boltzmann backup attracts the damped iteration of the paper's
Eq. 15: the eigenvalues of the backup's Jacobian ``gamma P J`` (:func:`iteration_stability`).

The Boltzmann backup may have several fixed points, and some repel the damped iteration;
:func:`irl.bellman.fixed_point.boltzmann_fixed_point` uses this check to accept only attracting ones.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from irl.bellman.operators import mean_weights, weight_matrix
from irl.transitions import SuccessorModel


def _stability(q: np.ndarray, succ: SuccessorModel, beta: float, gamma: float,
               max_dense: int = 2000) -> tuple[bool | None, float, None]:
    """``(stable, x, None)``, see :func:`iteration_stability`."""
    _, _, c = mean_weights(np.asarray(q).reshape(succ.n_states, succ.n_actions), beta)
    jp = weight_matrix(c) @ succ.p  # [S, S]
    used = np.unique(succ.p.indices)
    if used.size == 0:
        return True, 0.0, None
    sub = jp[used][:, used]
    bound = gamma * float(np.max(np.abs(sub).sum(axis=1)))
    if bound < 1.0:
        return True, bound, None
    top = _top_real_eigenvalue(sp.csr_matrix(gamma * sub), max_dense)
    if top is None:
        return None, float("nan"), None
    return top < 1.0, top, None


def _top_real_eigenvalue(m: sp.csr_matrix, max_dense: int) -> float | None:
    """The largest real part of the eigenvalues of the square ``m``, or None when a strongly
    connected block of ``m`` has more than ``max_dense`` rows.

    Ordered by its strongly connected components ``m`` is block triangular, so its eigenvalues
    are those of its diagonal blocks: each block's dense eigenvalues (a 1x1 block's is its entry)
    instead of the whole matrix's (on the merge driver encoding the largest block has about a
    quarter of the 820 successor states: ~60x less work than one dense problem).
    """
    _, labels = connected_components(m, directed=True, connection="strong")
    sizes = np.bincount(labels)
    if int(sizes.max()) > max_dense:
        return None
    single = sizes[labels] == 1
    top = float(np.max(m.diagonal()[single])) if np.any(single) else -np.inf
    order = np.argsort(labels, kind="stable")
    bounds = np.concatenate([[0], np.cumsum(sizes)])
    for b in np.flatnonzero(sizes > 1):
        idx = order[bounds[b]:bounds[b + 1]]
        top = max(top, float(np.max(np.linalg.eigvals(m[idx][:, idx].toarray()).real)))
    return top


def iteration_stability(q: np.ndarray, succ: SuccessorModel, beta: float, gamma: float,
                        max_dense: int = 2000) -> tuple[bool | None, float]:
    """Does the fixed point ``q [S, A]`` attract the damped iteration ``Q <- (1-alpha) Q + alpha T(Q)``?

    For small ``alpha`` (synchronous or in-place sweeps alike) the iteration is locally
    ``dQ/dt = T(Q) - Q``, which is attracted to ``q`` iff every eigenvalue ``lambda`` of the
    backup's Jacobian ``gamma P J`` has ``Re lambda < 1``. The non-zero eigenvalues of ``P J`` are
    those of ``J P`` restricted to the successor states, a small dense matrix. Returns
    ``(stable, x)``: ``x`` is the row-sum bound ``gamma ||J P||_inf`` when that is < 1 (then
    every ``|lambda| < 1``), else the largest ``Re lambda`` (from the dense eigenvalues of each
    strongly connected block of ``J P``). ``stable`` is None when a block has more than
    ``max_dense`` successor states.
    """
    stable, x, _ = _stability(q, succ, beta, gamma, max_dense)
    return stable, x
