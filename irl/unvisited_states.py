"""The policy in states never seen in training.

A model-free method's Q in a state no demonstration visited is its reward alone (terminal
pairs, :mod:`irl.transitions`), whatever the state's neighbours did. :func:`apply_unvisited_rule`
gives those states a defined value, one of :data:`UNVISITED_RULES`:

* ``"none"``: keep the method's own Q (the paper's behaviour).
* ``"nearest"``: copy the Q row of the nearest visited state, distance = L1 over the state's
  parts (``truck, x1..x4`` bin indices, and A's previous action for the driver encoding), with a
  different truck flag or previous action counting 10 bins (so they match first); ties go to
  the lower state index. Deterministic.

Which rule a model uses is chosen by held-out likelihood (``studies/driver_loo.py``) and
recorded in ``model.json`` as ``unvisited_rule``.
"""

from __future__ import annotations

import numpy as np

from irl.domains.merge.actions import N_ACTIONS
from irl.domains.merge.states import N_STATES, state_parts
from irl.errors import ConfigError

UNVISITED_RULES = ("none", "nearest")
_MISMATCH = 10


def _coords(n_states: int) -> np.ndarray:
    """``[S, D]`` coordinates of each merge state (paper: 5 parts; driver: + previous action)."""
    s = np.arange(n_states)
    if n_states == N_STATES:
        p = state_parts(s).astype(np.float64)
        p[:, 0] *= _MISMATCH
        return p
    if n_states == N_STATES * N_ACTIONS:
        p = state_parts(s // N_ACTIONS).astype(np.float64)
        p[:, 0] *= _MISMATCH
        return np.concatenate([p, _MISMATCH * np.eye(N_ACTIONS)[s % N_ACTIONS] / 2.0], axis=1)
    raise ConfigError(f"unvisited rule: {n_states} states is neither merge encoding (1250, 6250)")


def apply_unvisited_rule(q: np.ndarray, visited: np.ndarray, rule: str) -> np.ndarray:
    """``[S, A]`` Q with the rows of unvisited states set by ``rule`` (module doc).

    Args:
        q: ``[S, A]`` Q table of a merge model (S = 1250 or 6250).
        visited: ``[S]`` bool, states seen in the training demonstrations.
        rule: one of :data:`UNVISITED_RULES`.

    Raises:
        ConfigError: unknown rule, or shapes that do not match.
    """
    if rule not in UNVISITED_RULES:
        raise ConfigError(f"unvisited rule must be one of {UNVISITED_RULES}, got {rule!r}")
    q = np.asarray(q, dtype=np.float64)
    visited = np.asarray(visited, dtype=bool)
    if visited.shape != (q.shape[0],):
        raise ConfigError(f"visited mask {visited.shape} does not match Q {q.shape}")
    if rule == "none" or visited.all() or not visited.any():
        return q.copy()
    c = _coords(q.shape[0])
    vis = np.flatnonzero(visited)
    out = q.copy()
    for start in range(0, q.shape[0], 1024):
        rows = np.arange(start, min(start + 1024, q.shape[0]))
        rows = rows[~visited[rows]]
        if rows.size:
            d = np.abs(c[rows][:, None, :] - c[vis][None, :, :]).sum(axis=2)  # [r, V]
            out[rows] = q[vis[np.argmin(d, axis=1)]]
    return out


def visited_states(demos) -> np.ndarray:
    """``[S]`` bool: states that occur in ``demos`` (a :class:`~irl.demonstrations.Demonstrations`)."""
    mask = np.zeros(demos.n_states, dtype=bool)
    for s in demos.states:
        mask[s] = True
    return mask
