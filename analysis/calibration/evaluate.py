"""Spacing RMSE of calibrated parameters beside SUMO's defaults, per pair, median, mean and win
share, each with a bootstrap confidence interval over pairs (``scipy.stats.bootstrap``, percentile).

IDM and Krauss are simulated by the numpy replica, EIDM by real SUMO
(:class:`~analysis.calibration.sumo_fit.SumoRmse`); the replica equals SUMO on these pairs.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.stats import bootstrap

from analysis.calibration.classes import DriverClasses
from analysis.calibration.models import CALIBRATION_MODELS, MODELS, SUMO_DEFAULTS, CFParams
from analysis.calibration.objective import spacing_rmse
from analysis.calibration.pairs import CarFollowingPair, PairBatch
from analysis.calibration.sumo_fit import SumoRmse
from scenarios.errors import SpecError


@dataclass(frozen=True)
class PairScore:
    name: str
    rmse_m: float
    default_rmse_m: float


#: Confidence level and resamples of the bootstrap intervals.
CONFIDENCE = 0.95
N_RESAMPLES = 2000


@dataclass(frozen=True)
class Interval:
    """A statistic over pairs and its bootstrap confidence interval (same unit)."""

    value: float
    low: float
    high: float


def bootstrap_interval(stat, samples: tuple[np.ndarray, ...], seed: int) -> Interval:
    """``stat`` over paired per-pair samples (each float64[P]) with a percentile bootstrap interval
    (:data:`CONFIDENCE`, :data:`N_RESAMPLES` resamples, seeded by ``seed``)."""
    value = float(stat(*samples))
    if len(samples[0]) < 3 or np.all(samples[0] == samples[0][0]):
        return Interval(value, value, value)
    ci = bootstrap(samples, stat, paired=True, vectorized=False, n_resamples=N_RESAMPLES,
                   confidence_level=CONFIDENCE, method="percentile",
                   rng=np.random.default_rng(seed)).confidence_interval
    return Interval(value, float(ci.low), float(ci.high))


#: A statistic over pairs: ``(function, its per-pair samples)``.
Statistic = tuple[Callable[..., Any], tuple[np.ndarray, ...]]


def paired_statistics(r: np.ndarray, d: np.ndarray, *, win_fraction: bool = True) -> dict[str, Statistic]:
    """The statistics of per-pair RMSE ``r [P]`` beside the defaults' ``d [P]`` (m): medians,
    means, (with ``win_fraction``) the share of pairs where ``r < d``, and the ratios of the
    medians and of the means; in the order their bootstrap seeds follow."""
    stats: dict[str, Statistic] = {
        "median_rmse_m": (np.median, (r,)), "default_median_rmse_m": (np.median, (d,)),
        "mean_rmse_m": (np.mean, (r,)), "default_mean_rmse_m": (np.mean, (d,)),
    }
    if win_fraction:
        stats["win_fraction"] = (lambda a, b: np.mean(a < b), (r, d))
    stats["median_ratio"] = (lambda a, b: np.median(a) / np.median(b), (r, d))
    stats["mean_ratio"] = (lambda a, b: np.mean(a) / np.mean(b), (r, d))
    return stats


def bootstrap_intervals(stats: dict[str, Statistic], seed: int) -> tuple[tuple[str, Interval], ...]:
    """``(name, Interval)`` of every statistic, the ``i``-th bootstrapped with seed ``seed + i``."""
    return tuple((k, bootstrap_interval(f, x, seed + i)) for i, (k, (f, x)) in enumerate(stats.items()))


@dataclass(frozen=True)
class Evaluation:
    """Spacing RMSE (m) per pair with the given parameters and with SUMO's defaults.

    ``win_fraction``: share of pairs where the given parameters have the lower RMSE.
    ``intervals``: (statistic name, :class:`Interval`) for ``median_rmse_m``,
    ``default_median_rmse_m``, ``mean_rmse_m``, ``default_mean_rmse_m``, ``win_fraction`` and
    the ratios ``median_ratio`` / ``mean_ratio`` (calibrated over default), pairs resampled
    together (95 % percentile bootstrap, ``N_RESAMPLES`` resamples, seeded).
    ``n_classes``: driver classes the pairs were simulated with (1: ``params`` for every pair).
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
    intervals: tuple[tuple[str, Interval], ...] = ()
    n_classes: int = 1

    def interval(self, name: str) -> Interval:
        return dict(self.intervals)[name]

    def to_json_dict(self) -> dict:
        return {
            "model": self.model,
            "n_pairs": len(self.pairs),
            "n_classes": self.n_classes,
            "median_rmse_m": self.median_rmse_m,
            "default_median_rmse_m": self.default_median_rmse_m,
            "mean_rmse_m": self.mean_rmse_m,
            "default_mean_rmse_m": self.default_mean_rmse_m,
            "win_fraction": self.win_fraction,
            "intervals": {k: {"value": v.value, "low": v.low, "high": v.high} for k, v in self.intervals},
            "confidence": CONFIDENCE,
            "params": self.params.as_dict(),
            "defaults": self.defaults.as_dict(),
            "pairs": [{"name": p.name, "rmse_m": p.rmse_m, "default_rmse_m": p.default_rmse_m} for p in self.pairs],
        }


def evaluate(
    params: CFParams, pairs: Sequence[CarFollowingPair], *, model: str = "idm",
    defaults: CFParams = SUMO_DEFAULTS, seed: int = 0, workers: int | None = None,
    classes: DriverClasses | None = None,
) -> Evaluation:
    """Replay every pair's leader and score the follower simulated with ``params`` and ``defaults``.

    Every pair weighs the same in every statistic. ``seed`` seeds the bootstrap. ``model`` is a
    key of :data:`~analysis.calibration.models.CALIBRATION_MODELS`; a model without a replica
    (EIDM) is simulated by SUMO in ``workers`` processes (default one per core), both parameter
    sets in one run. With ``classes`` (replica models only), each pair is simulated with its
    class's parameters instead of ``params`` (one batch per class).

    Raises:
        SpecError: ``pairs`` is empty, an unknown ``model``, or ``classes`` for a model without a replica.
        ScenarioError: SUMO failed (EIDM).
    """
    if model not in CALIBRATION_MODELS:
        raise SpecError(f"model: expected one of {sorted(CALIBRATION_MODELS)}, got {model!r}")
    if classes is not None and model not in MODELS:
        raise SpecError(f"classes: driver classes need a model with a numpy replica ({', '.join(sorted(MODELS))}), "
                        f"got {model!r}")
    if model in MODELS:
        batch = PairBatch.from_pairs(pairs)
        d = batch.unsort(spacing_rmse(model, batch, defaults.as_dict()))
        if classes is None:
            r = batch.unsort(spacing_rmse(model, batch, params.as_dict()))
        else:
            of = np.array([classes.class_of(p) for p in pairs])
            r = np.empty(len(pairs))
            for c in np.unique(of):
                idx = np.flatnonzero(of == c)
                sub = PairBatch.from_pairs([pairs[int(i)] for i in idx])
                r[idx] = sub.unsort(spacing_rmse(model, sub, classes.params[c].as_dict()))
    else:
        with SumoRmse(pairs, model, workers) as sim:
            r, d = sim([params, defaults]).T
    intervals = bootstrap_intervals(paired_statistics(r, d), seed)
    return Evaluation(
        model=model, params=params, defaults=defaults,
        pairs=tuple(PairScore(p.name, float(a), float(b)) for p, a, b in zip(pairs, r, d)),
        median_rmse_m=float(np.median(r)), default_median_rmse_m=float(np.median(d)),
        mean_rmse_m=float(np.mean(r)), default_mean_rmse_m=float(np.mean(d)),
        win_fraction=float(np.mean(r < d)), intervals=intervals,
        n_classes=1 if classes is None else classes.n_classes,
    )
