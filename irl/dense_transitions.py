"""The dense transition estimate, ``[S, A, S]``: the construction the sparse one replaced.

:func:`irl.transitions.estimate_transitions` builds the same model as a sparse
:class:`~irl.transitions.SuccessorModel`. This dense form is kept as an independent reference:
the tests check the sparse estimate against it, and ``benchmarks/sparse_model_bench.py`` times
it against the sparse one. Only for small problems: the merge domain's ``driver`` encoding
(6250 states) makes one ``[S, A, S]`` float64 array 1.5 GB.
"""

from __future__ import annotations

import numpy as np

from irl.demonstrations import Demonstrations
from irl.errors import ConfigError


def dense_estimate(demos: Demonstrations, fallback: np.ndarray | None) -> np.ndarray:
    """``[S, A, S]`` float64 relative counts of the demonstrations' observed transitions
    (:meth:`irl.demonstrations.Demonstrations.transitions`: every step but each trajectory's
    last); where a pair ``(s, a)`` has no observed successor, the fallback's row
    ``fallback[s, a]``, or with ``fallback=None`` a self-loop ``P(s | s, a) = 1``. Every row
    sums to 1 when the fallback's rows do.

    Args:
        demos: the demonstrations (``S = demos.n_states``, ``A = demos.n_actions``).
        fallback: ``[S, A, S]`` rows for the unseen pairs, or None.

    Raises:
        ConfigError: ``fallback`` is not ``[S, A, S]``.
    """
    S, A = demos.n_states, demos.n_actions
    if fallback is not None and np.shape(fallback) != (S, A, S):
        raise ConfigError(f"the fallback must be [S, A, S] = [{S}, {A}, {S}], got {list(np.shape(fallback))}")
    s, a, s2 = demos.transitions()
    counts = np.zeros((S, A, S))
    np.add.at(counts, (s, a, s2), 1.0)
    totals = counts.sum(axis=2, keepdims=True)
    seen = totals[..., 0] > 0
    t = np.divide(counts, totals, out=np.zeros_like(counts), where=totals > 0)
    if fallback is not None:
        t[~seen] = fallback[~seen]
    else:
        ss, aa = np.nonzero(~seen)
        t[ss, aa, ss] = 1.0
    return t
