"""How far closed-loop behaviour is from the demonstrations: the Jensen-Shannon divergence of
action distributions and Wasserstein-1 distances (a policy's held-out log-likelihood is its own
:meth:`sim.drivers.policy.Policy.heldout_loglik`).

* ``js_divergence``: Jensen-Shannon divergence (base 2, in [0, 1]) between A's action
  distribution at the decisions (``action_counts``, :mod:`analysis.evaluation.metrics`) and the
  demonstrations' action distribution.
* ``w1_speed_A_ft_s``, ``w1_acc_A_ft_s2``, ``w1_d_AC_ft``, ``w1_ttc_s``: Wasserstein-1
  distances (``scipy.stats.wasserstein_distance``) between the closed-loop values at A's
  decisions (speed, applied acceleration, d_AC, TTC to C) and the held-out demonstration
  frames (``v_A`` when the table has it, ``acc_A``, ``d_AC``, TTC). TTC to C is front-to-front
  ``d_AC / v_AC`` over the closing steps (``v_AC > 0``), capped at ``TTC_CAP_S``. The SUMO
  driver's distances are the floor the learned drivers are compared to.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from scipy.stats import wasserstein_distance

#: TTC values above this (s) are set to it before the Wasserstein distance.
TTC_CAP_S = 30.0


def js_divergence(p: np.ndarray, q: np.ndarray) -> float:
    """Jensen-Shannon divergence (base 2, in [0, 1]) of two histograms ``[A]`` (normalised here).

    NaN if either is all zero.
    """
    p = np.asarray(p, dtype=np.float64)
    q = np.asarray(q, dtype=np.float64)
    if p.sum() <= 0 or q.sum() <= 0:
        return float("nan")
    p, q = p / p.sum(), q / q.sum()
    m = 0.5 * (p + q)

    def kl(x, y):
        nz = x > 0
        return float(np.sum(x[nz] * np.log2(x[nz] / y[nz])))

    return max(0.0, 0.5 * kl(p, m) + 0.5 * kl(q, m))


def ttc_to_c(d_ac: np.ndarray, v_ac: np.ndarray) -> np.ndarray:
    """``[M]`` front-to-front TTC to C (s), ``d_AC / v_AC`` over the closing steps of ``d_ac,
    v_ac [N]`` (``v_AC > 0``, finite), capped at ``TTC_CAP_S``."""
    d = np.asarray(d_ac, dtype=np.float64)
    v = np.asarray(v_ac, dtype=np.float64)
    ok = np.isfinite(d) & np.isfinite(v) & (v > 1e-6)
    return np.minimum(np.maximum(d[ok], 0.0) / v[ok], TTC_CAP_S)


def wasserstein(x, y) -> float:
    """Wasserstein-1 distance of two samples (finite values only; NaN if either is empty)."""
    a = np.asarray(x, dtype=np.float64)
    b = np.asarray(y, dtype=np.float64)
    a, b = a[np.isfinite(a)], b[np.isfinite(b)]
    if a.size == 0 or b.size == 0:
        return float("nan")
    return float(wasserstein_distance(a, b))


def w1_to_demos(decisions: pd.DataFrame, demos: pd.DataFrame) -> dict[str, float]:
    """Wasserstein-1 distances of the closed-loop decisions (``Controller.decision_table()``
    rows, all episodes) to held-out encounter frames: keys ``w1_speed_A_ft_s`` (needs a
    ``v_A`` column in ``demos``, else NaN), ``w1_acc_A_ft_s2``, ``w1_d_AC_ft``, ``w1_ttc_s``."""
    speed = demos["v_A"] if "v_A" in demos else pd.Series(dtype="float64")
    return {
        "w1_speed_A_ft_s": wasserstein(decisions["speed_A"], speed),
        "w1_acc_A_ft_s2": wasserstein(decisions["acc_cmd"], demos["acc_A"]),
        "w1_d_AC_ft": wasserstein(decisions["d_AC"], demos["d_AC"]),
        "w1_ttc_s": wasserstein(ttc_to_c(decisions["d_AC"], decisions["v_AC"]), ttc_to_c(demos["d_AC"], demos["v_AC"])),
    }
