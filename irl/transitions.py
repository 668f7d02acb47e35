"""Successor models: which next states each (s, a) pair bootstraps from.

Two sources, one representation (:class:`SuccessorModel`):

* **model-free** (Q-Avg, Q-SM): only the demonstrations' observed transitions. For every step
  but each trajectory's last, ``(s_t, a_t) -> s_{t+1}``; ``P_hat(s'|s,a)`` is the relative count
  over the pair's non-final occurrences. A pair with no observed successor (never seen, or only
  seen as a trajectory's final step) is **terminal**: its Q is its reward, ``Q(s,a) = R(s,a)``
  (the authors' code pulls every such pair, each trajectory's final step included, to ``R``,
  and ``dQ/dtheta`` to ``phi``, without a bootstrap), unless a fallback
  successor table is given (:mod:`irl.unobserved_successors`).
* **model-based** (MLIRL, REIRL): a full row-stochastic transition model (the true one, or
  :func:`estimate_transitions` with a domain-supplied fallback). No pair is terminal. Stored
  sparse: a model of the merge domain's ``driver`` encoding, ``[6250, 5, 6250]`` dense, is 1.5 GB
  of float64 but has a handful of non-zeros per row. Callers may hand a dense ``[S, A, S]``
  array, a ``[S*A, S]`` scipy sparse matrix or a :class:`SuccessorModel`
  (:data:`TransitionModel`); :func:`model_successors` turns any of them into the one
  representation every solver uses.

Pairs are flattened as ``i = s * A + a``.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import TypeAlias

import numpy as np
import scipy.sparse as sp

from irl.demonstrations import Demonstrations
from irl.errors import ConfigError, DemonstrationError


@dataclass(frozen=True)
class SuccessorModel:
    """Sparse successor distribution over flattened (s, a) pairs.

    Attributes:
        p: ``[S*A, S]`` CSR matrix; row ``s*A + a`` is ``P(s'|s,a)`` (sums to 1) or all zero for a
            terminal pair.
        terminal: ``[S*A]`` bool, pairs that do not bootstrap (``Q = R``).
        n_states, n_actions: ``S``, ``A``.
    """

    p: sp.csr_matrix
    terminal: np.ndarray
    n_states: int
    n_actions: int

    @property
    def n_pairs(self) -> int:
        return self.n_states * self.n_actions

    def to_dense(self) -> np.ndarray:
        """``[S, A, S]`` float64 array of ``p`` (``S * A * S * 8`` bytes: 1.5 GB for 6250 states)."""
        return self.p.toarray().reshape(self.n_states, self.n_actions, self.n_states)

    @cached_property
    def jacobian_pattern(self) -> JacobianPattern:
        """Precomputed sparsity of ``I - gamma P W(c)`` (see :func:`irl.bellman.operators.backup_jacobian`)."""
        return JacobianPattern.of(self)

    @cached_property
    def state_pattern(self) -> JacobianPattern:
        """Precomputed sparsity of the state system ``I - gamma W(c) P``, ``[S, S]`` (see
        :func:`irl.bellman.operators.solve_backup_system`)."""
        return JacobianPattern.state_system(self)


@dataclass(frozen=True)
class JacobianPattern:
    """CSC structure of ``I - gamma P W(c)`` (``[S*A, S*A]``, :meth:`of`) or of the state system
    ``I - gamma W(c) P`` (``[S, S]``, :meth:`state_system`) for one successor model, so that
    building the matrix for new weights ``c`` is one gather and one segmented sum.

    Entry ``e`` of ``P W`` is ``P[i, s'] * c[s', b]`` at ``(i, s'*A + b)``; entry ``e`` of ``W P``
    is ``c[s, b] * P[s*A + b, s']`` at ``(s, s')``. ``order`` sorts the diagonal entries followed
    by these into CSC order and ``starts`` marks where duplicates (same position) begin.
    """

    p_values: np.ndarray  # [E] P value of each P W (or W P) entry
    c_index: np.ndarray  # [E] flat index into c of the weight it is multiplied by
    order: np.ndarray  # [n + E] permutation into CSC order
    starts: np.ndarray  # [nnz] first sorted entry of each stored position
    indices: np.ndarray  # [nnz] CSC row indices
    indptr: np.ndarray  # [n + 1]
    n: int

    @classmethod
    def of(cls, succ: SuccessorModel) -> JacobianPattern:
        """The pattern of the pair matrix ``I - gamma P W(c)``, ``[S*A, S*A]``."""
        A, n = succ.n_actions, succ.n_pairs
        p = succ.p.tocoo()
        rows = np.repeat(p.row, A)
        cols = (p.col[:, None] * A + np.arange(A)[None, :]).ravel()
        return cls._build(np.repeat(p.data, A), cols, rows, cols, n)

    @classmethod
    def state_system(cls, succ: SuccessorModel) -> JacobianPattern:
        """The pattern of the state matrix ``I - gamma W(c) P``, ``[S, S]``: entry
        ``(s, s')`` sums ``c[s, b] P[s*A + b, s']`` over the actions ``b``."""
        p = succ.p.tocoo()
        return cls._build(p.data, p.row, p.row // succ.n_actions, p.col, succ.n_states)

    @classmethod
    def _build(cls, values: np.ndarray, c_index: np.ndarray, rows: np.ndarray, cols: np.ndarray,
               n: int) -> JacobianPattern:
        all_rows = np.concatenate([np.arange(n), rows])
        all_cols = np.concatenate([np.arange(n), cols])
        order = np.lexsort((all_rows, all_cols))
        r_sorted, c_sorted = all_rows[order], all_cols[order]
        new = np.ones(order.size, dtype=bool)
        new[1:] = (r_sorted[1:] != r_sorted[:-1]) | (c_sorted[1:] != c_sorted[:-1])
        starts = np.flatnonzero(new)
        indptr = np.searchsorted(c_sorted[starts], np.arange(n + 1))
        return cls(np.asarray(values, dtype=np.float64), np.asarray(c_index, dtype=np.int64), order, starts,
                   r_sorted[starts].astype(np.int32), indptr.astype(np.int32), n)

    def matrix(self, c: np.ndarray, gamma: float) -> sp.csc_matrix:
        """``I - gamma P W(c)`` (or ``I - gamma W(c) P``) as CSC, ``c`` of shape ``[S, A]``."""
        data = np.concatenate([np.ones(self.n), -gamma * self.p_values * c.ravel()[self.c_index]])
        summed = np.add.reduceat(data[self.order], self.starts)
        return sp.csc_matrix((summed, self.indices, self.indptr), shape=(self.n, self.n))


def model_free_successors(demos: Demonstrations, fallback_next: np.ndarray | None = None) -> SuccessorModel:
    """The demonstrations' empirical successor model.

    A pair with no observed successor is terminal, or, with ``fallback_next`` (``[S, A]`` int,
    see :mod:`irl.unobserved_successors`), moves to ``fallback_next[s, a]`` with probability 1 (then no
    pair is terminal). Observed pairs keep their relative counts either way.

    Raises:
        DemonstrationError: ``fallback_next`` is not ``[S, A]`` states in ``0 .. S-1``.
    """
    S, A = demos.n_states, demos.n_actions
    s, a, s2 = demos.transitions()
    rows = s * A + a
    m = sp.coo_matrix((np.ones(rows.size), (rows, s2)), shape=(S * A, S)).tocsr()
    m.sum_duplicates()
    totals = np.asarray(m.sum(axis=1)).ravel()
    terminal = totals == 0
    scale = np.where(terminal, 0.0, 1.0 / np.where(terminal, 1.0, totals))
    p = sp.diags(scale) @ m
    if fallback_next is not None:
        nxt = np.asarray(fallback_next)
        if nxt.shape != (S, A) or not np.issubdtype(nxt.dtype, np.integer) or nxt.min() < 0 or nxt.max() >= S:
            raise DemonstrationError(f"fallback successors: expected [{S}, {A}] states in 0..{S - 1}, "
                                     f"got shape {nxt.shape} dtype {nxt.dtype}")
        idx = np.flatnonzero(terminal)
        p = p + sp.csr_matrix((np.ones(idx.size), (idx, nxt.ravel()[idx])), shape=(S * A, S))
        terminal = np.zeros(S * A, dtype=bool)
    return SuccessorModel(p=sp.csr_matrix(p), terminal=terminal, n_states=S, n_actions=A)


#: What callers may pass as a transition model: dense ``[S, A, S]``, sparse ``[S*A, S]`` or a
#: :class:`SuccessorModel` without terminal pairs.
TransitionModel: TypeAlias = np.ndarray | sp.spmatrix | sp.sparray | SuccessorModel


def model_successors(transitions: TransitionModel, where: str = "transitions", *,
                     n_actions: int | None = None) -> SuccessorModel:
    """A full transition model as a :class:`SuccessorModel` (rows must be probability distributions).

    Args:
        transitions: dense ``T [S, A, S]``; a scipy sparse ``[S*A, S]`` matrix (row ``s*A + a``
            is ``T[s, a, :]``; ``n_actions`` required); or a :class:`SuccessorModel` (returned as
            it is once checked).
        where: names the model in error messages.
        n_actions: ``A`` of a sparse matrix.

    Raises:
        DemonstrationError: not ``[S, A, S]`` (or ``[S*A, S]``), negative or non-finite entries, a
            row that does not sum to 1, terminal pairs in a :class:`SuccessorModel`, or a sparse
            matrix without ``n_actions``.
    """
    if isinstance(transitions, SuccessorModel):
        if np.any(transitions.terminal):
            raise DemonstrationError(f"{where}: a transition model has no terminal pairs "
                                     f"({int(transitions.terminal.sum())} given)")
        S, A, p = transitions.n_states, transitions.n_actions, transitions.p
    elif sp.issparse(transitions):
        if n_actions is None or n_actions < 1:
            raise DemonstrationError(f"{where}: a sparse [S*A, S] model needs n_actions")
        A = int(n_actions)
        p = sp.csr_matrix(transitions, dtype=np.float64)
        S = p.shape[1]
        if p.shape[0] != S * A:
            raise DemonstrationError(f"{where}: expected shape [S*A, S] = [{S * A}, {S}], got {p.shape}")
    else:
        t = np.asarray(transitions, dtype=np.float64)
        if t.ndim != 3 or t.shape[0] != t.shape[2]:
            raise DemonstrationError(f"{where}: expected shape [S, A, S], got {t.shape}")
        S, A = t.shape[:2]
        p = sp.csr_matrix(t.reshape(S * A, S))
    if not np.all(np.isfinite(p.data)) or np.any(p.data < 0):
        raise DemonstrationError(f"{where}: entries must be finite and non-negative")
    sums = np.asarray(p.sum(axis=1)).ravel()
    bad = np.flatnonzero(np.abs(sums - 1.0) > 1e-8)
    if bad.size:
        s, a = divmod(int(bad[0]), A)
        raise DemonstrationError(f"{where}: row T[{s}, {a}, :] sums to {sums[bad[0]]:.6g}, expected 1")
    if isinstance(transitions, SuccessorModel):
        return transitions
    p.sum_duplicates()
    p.eliminate_zeros()
    p.sort_indices()
    return SuccessorModel(p=p, terminal=np.zeros(S * A, dtype=bool), n_states=S, n_actions=A)


def checked_model(transitions: TransitionModel, demos: Demonstrations, where: str = "transitions") -> SuccessorModel:
    """:func:`model_successors` of ``transitions``, checked to cover the states and actions of ``demos``.

    Raises:
        ConfigError: not ``[S, A, S]`` (dense), ``[S*A, S]`` (sparse) or a model over ``S`` states
            and ``A`` actions, for ``demos``' ``S`` and ``A``.
        DemonstrationError: not row-stochastic, or terminal pairs (see :func:`model_successors`).
    """
    S, A = demos.n_states, demos.n_actions
    if isinstance(transitions, SuccessorModel):
        got, ok = (transitions.n_states, transitions.n_actions, transitions.n_states), None
    elif sp.issparse(transitions):
        got, ok = tuple(transitions.shape), (S * A, S)
    else:
        got, ok = np.shape(transitions), None
    if got != (ok or (S, A, S)):
        raise ConfigError(f"{where} must have shape [S, A, S] = {(S, A, S)} (sparse: [S*A, S] = {(S * A, S)}) "
                          f"for these demonstrations, got {got}")
    return model_successors(transitions, where, n_actions=A)


def _relative_counts(demos: Demonstrations) -> tuple[sp.csr_matrix, np.ndarray]:
    """``([S*A, S] CSR of P_hat(s'|s,a) over observed successors, [S*A] bool seen)``; unseen rows empty."""
    S, A = demos.n_states, demos.n_actions
    s, a, s2 = demos.transitions()
    m = sp.csr_matrix((np.ones(s.size), (s * A + a, s2)), shape=(S * A, S))
    m.sum_duplicates()
    m.sort_indices()
    totals = np.diff(m.indptr)  # entries per row, replaced by the row's count total below
    row_total = np.asarray(m.sum(axis=1)).ravel()
    m.data = m.data / np.repeat(row_total, totals)
    return m, row_total > 0


def estimate_transitions(demos: Demonstrations, fallback: TransitionModel | None = None) -> SuccessorModel:
    """Relative-count transition model ``T [S, A, S]`` from the demonstrations, sparse.

    ``T[s, a, :]`` is the distribution of observed successors of ``(s, a)`` (every step but each
    trajectory's last). A pair never observed with a successor takes the fallback's row when
    ``fallback`` (``[S, A, S]`` row-stochastic, in any form :func:`model_successors` takes) is
    given, else stays in place (``T[s, a, s] = 1``, a self-loop). The result is row-stochastic;
    ``.to_dense()`` gives the ``[S, A, S]`` array.

    Raises:
        DemonstrationError: ``fallback`` is not a row-stochastic model over ``[S, A, S]``.
    """
    S, A = demos.n_states, demos.n_actions
    observed, seen = _relative_counts(demos)
    if fallback is None:
        fb = sp.csr_matrix((np.ones(S * A), (np.arange(S * A), np.repeat(np.arange(S), A))), shape=(S * A, S))
    else:
        fbm = model_successors(fallback, "fallback transitions", n_actions=A)
        if (fbm.n_states, fbm.n_actions) != (S, A):
            raise DemonstrationError(f"fallback transitions: expected shape {(S, A, S)}, "
                                     f"got {(fbm.n_states, fbm.n_actions, fbm.n_states)}")
        fb = fbm.p
    p = sp.csr_matrix(sp.diags(seen.astype(np.float64)) @ observed + sp.diags((~seen).astype(np.float64)) @ fb)
    p.eliminate_zeros()
    p.sort_indices()
    return SuccessorModel(p=p, terminal=np.zeros(S * A, dtype=bool), n_states=S, n_actions=A)


def reachable_states(succ: SuccessorModel, start: np.ndarray) -> np.ndarray:
    """Sorted states reachable from ``start`` (any action, any number of steps), ``start`` included.

    Q at these states depends only on Q at these states, so a fixed point can be solved on them
    alone (:meth:`restrict`).
    """
    S, A = succ.n_states, succ.n_actions
    seen = np.zeros(S, dtype=bool)
    frontier = np.unique(np.asarray(start, dtype=np.int64))
    seen[frontier] = True
    indptr, indices = succ.p.indptr, succ.p.indices
    while frontier.size:
        rows = (frontier[:, None] * A + np.arange(A)[None, :]).ravel()
        nxt = np.unique(np.concatenate([indices[indptr[i]:indptr[i + 1]] for i in rows]))
        frontier = nxt[~seen[nxt]]
        seen[frontier] = True
    return np.flatnonzero(seen)


def restrict(succ: SuccessorModel, states: np.ndarray) -> SuccessorModel:
    """The successor model on ``states`` only (closed: every successor must be among them).

    Raises:
        ValueError: the state set is not closed under the successor model.
    """
    states = np.asarray(states, dtype=np.int64)
    A = succ.n_actions
    rows = (states[:, None] * A + np.arange(A)[None, :]).ravel()
    sub = succ.p[rows]
    local = np.full(succ.n_states, -1, dtype=np.int64)
    local[states] = np.arange(states.size)
    cols = local[sub.indices]
    if np.any(cols < 0):
        raise ValueError("restrict: the state set is not closed under the successor model")
    p = sp.csr_matrix((sub.data, cols, sub.indptr), shape=(rows.size, states.size))
    return SuccessorModel(p=p, terminal=succ.terminal[rows], n_states=int(states.size), n_actions=A)
