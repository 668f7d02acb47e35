"""Spacing RMSE of calibrated parameters beside SUMO's defaults, per pair and median."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from scenarios.calibration.models import SUMO_DEFAULTS, CFParams
from scenarios.calibration.objective import spacing_rmse
from scenarios.calibration.pairs import CarFollowingPair, PairBatch


@dataclass(frozen=True)
class PairScore:
    name: str
    rmse_m: float
    default_rmse_m: float


@dataclass(frozen=True)
class Evaluation:
    """Spacing RMSE (m) per pair with the given parameters and with SUMO's defaults.

    ``win_fraction``: share of pairs where the given parameters have the lower RMSE.
    """

    model: str
    params: CFParams
    defaults: CFParams
    pairs: tuple[PairScore, ...]
    median_rmse_m: float
    default_median_rmse_m: float
    mean_rmse_m: float
    default_mean_rmse_m: float
    win_fraction: float

    def to_json_dict(self) -> dict:
        return {
            "model": self.model,
            "n_pairs": len(self.pairs),
            "median_rmse_m": self.median_rmse_m,
            "default_median_rmse_m": self.default_median_rmse_m,
            "mean_rmse_m": self.mean_rmse_m,
            "default_mean_rmse_m": self.default_mean_rmse_m,
            "win_fraction": self.win_fraction,
            "params": self.params.as_dict(),
            "defaults": self.defaults.as_dict(),
            "pairs": [{"name": p.name, "rmse_m": p.rmse_m, "default_rmse_m": p.default_rmse_m} for p in self.pairs],
        }


def evaluate(
    params: CFParams, pairs: Sequence[CarFollowingPair], *, model: str = "idm",
    defaults: CFParams = SUMO_DEFAULTS,
) -> Evaluation:
    """Replay every pair's leader and score the follower simulated with ``params`` and ``defaults``."""
    batch = PairBatch.from_pairs(pairs)
    r = batch.unsort(spacing_rmse(model, batch, params.as_dict()))
    d = batch.unsort(spacing_rmse(model, batch, defaults.as_dict()))
    return Evaluation(
        model=model, params=params, defaults=defaults,
        pairs=tuple(PairScore(p.name, float(a), float(b)) for p, a, b in zip(pairs, r, d)),
        median_rmse_m=float(np.median(r)), default_median_rmse_m=float(np.median(d)),
        mean_rmse_m=float(np.mean(r)), default_mean_rmse_m=float(np.mean(d)),
        win_fraction=float(np.mean(r < d)),
    )
