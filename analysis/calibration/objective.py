"""Spacing error of a car-following model on a batch of replayed pairs, and the population fit's
objectives over the per-pair errors (:data:`OBJECTIVES`).

All functions work in the batch's row order (pairs sorted by decreasing length, see
:class:`~analysis.calibration.pairs.PairBatch`); per-pair parameter arrays must be in that
order too. A trailing candidate axis ``C`` (parameters shaped ``(P, C)`` or ``(C,)``) evaluates
several parameter sets in one vectorised simulation.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from analysis.calibration.models import simulate_follower
from analysis.calibration.pairs import PairBatch

#: Population objectives: name -> (``least_squares`` loss, its scale, residual normalised).
#: The residual of pair i is its spacing RMSE (m), or, normalised, that RMSE divided by the
#: pair's RMSE under SUMO's defaults (every pair's residual is then 1 at the defaults, so a
#: pair that no single driver can follow weighs no more than an easy one).
#: ``log``: Cauchy loss with scale 0.3 m, ``log(1 + (r/0.3)^2)``, which for the RMSEs of real
#: pairs (1-20 m) is within a few percent of ``2 log(r/0.3)``: the fit minimises the geometric
#: mean of the per-pair RMSEs, a smooth estimate of their median (per-pair RMSEs are roughly
#: log-normal), and a pair's weight falls as 1/r.
OBJECTIVES: dict[str, tuple[str, float, bool]] = {
    "rmse": ("cauchy", 1.0, False),
    "log": ("cauchy", 0.3, False),
    "ratio": ("cauchy", 0.5, True),
}
DEFAULT_OBJECTIVE = "log"


def simulated_spacing(
    model: str, batch: PairBatch, params: Mapping[str, np.ndarray | float], *, candidates: bool = False,
    action_steps: int = 1,
) -> np.ndarray:
    """Simulated bumper gap (m): float64[P, T], or float64[P, C, T] with ``candidates=True``
    (then every parameter is a float, a float64[C] or a float64[P, C] array). ``action_steps``:
    decisions every that many 0.1 s steps (SUMO's ``actionStepLength``, see
    :func:`~analysis.calibration.models.simulate_follower`)."""
    if candidates:
        x, _ = simulate_follower(
            model, batch.x_leader[:, None, :], batch.v_leader[:, None, :],
            batch.leader_length[:, None], batch.x0[:, None], batch.v0[:, None], params,
            lengths=batch.lengths, action_steps=action_steps,
        )
        return batch.x_leader[:, None, :] - batch.leader_length[:, None, None] - x
    x, _ = simulate_follower(
        model, batch.x_leader, batch.v_leader, batch.leader_length, batch.x0, batch.v0, params,
        lengths=batch.lengths, action_steps=action_steps,
    )
    return batch.x_leader - batch.leader_length[:, None] - x


def spacing_errors(
    model: str, batch: PairBatch, params: Mapping[str, np.ndarray | float], *, candidates: bool = False,
    action_steps: int = 1,
) -> np.ndarray:
    """Simulated minus observed gap (m), 0 outside the scored steps; shape as :func:`simulated_spacing`."""
    s = simulated_spacing(model, batch, params, candidates=candidates, action_steps=action_steps)
    obs = batch.spacing_obs[:, None, :] if candidates else batch.spacing_obs
    mask = batch.mask[:, None, :] if candidates else batch.mask
    return np.where(mask, s - obs, 0.0)


def spacing_rmse(
    model: str, batch: PairBatch, params: Mapping[str, np.ndarray | float], *, candidates: bool = False,
    action_steps: int = 1,
) -> np.ndarray:
    """Per-pair root-mean-square spacing error (m): float64[P] (or float64[P, C]), batch order."""
    err = spacing_errors(model, batch, params, candidates=candidates, action_steps=action_steps)
    n = batch.mask.sum(axis=1)
    n = n[:, None] if candidates else n
    return np.sqrt((err * err).sum(axis=-1) / n)


def spacing_rmspe(
    model: str, batch: PairBatch, params: Mapping[str, np.ndarray | float], *, min_gap_m: float = 2.0,
) -> np.ndarray:
    """Per-pair root-mean-square *percentage* spacing error: float64[P], batch order (1 = 100 %).

    Each step's error is divided by the observed gap (floored at ``min_gap_m`` metres so that
    near-standstill steps do not explode), so a pair at 10 m spacing and one at 60 m weigh alike
    (Punzo, Montanino & Ciuffo, *Transp. Res. Rec.* 2012, "Do we really need to calibrate all
    the parameters?"; Punzo et al. 2021, "Calibration of car-following models", the RMSPE of
    spacing as a robust measure of performance).
    """
    err = spacing_errors(model, batch, params)
    rel = err / np.maximum(np.where(batch.mask, batch.spacing_obs, min_gap_m), min_gap_m)
    return np.sqrt((rel * rel).sum(axis=-1) / batch.mask.sum(axis=1))


def theil_u(model: str, batch: PairBatch, params: Mapping[str, np.ndarray | float]) -> np.ndarray:
    """Per-pair Theil's inequality coefficient of the spacing: float64[P] in [0, 1], batch order.

    ``U = RMSE / (sqrt(mean(s_sim^2)) + sqrt(mean(s_obs^2)))`` over the scored steps (Theil 1966;
    used for car following by Punzo et al. 2012 and Treiber & Kesting 2013, ch. 16): 0 is a
    perfect fit, scale free, so every pair weighs the same whatever its spacing.
    """
    s = simulated_spacing(model, batch, params)
    n = batch.mask.sum(axis=1)
    e = np.where(batch.mask, s - batch.spacing_obs, 0.0)
    rmse = np.sqrt((e * e).sum(axis=-1) / n)
    s_rms = np.sqrt((np.where(batch.mask, s, 0.0) ** 2).sum(axis=-1) / n)
    o_rms = np.sqrt((np.where(batch.mask, batch.spacing_obs, 0.0) ** 2).sum(axis=-1) / n)
    return rmse / (s_rms + o_rms)
