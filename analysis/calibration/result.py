"""The result of a calibration: the per-pair fits, the spread of their parameters over drivers,
and the population (:class:`CalibrationResult`, written as TOML by :mod:`.params_file`; made by
:func:`~analysis.calibration.fit.calibrate` and :func:`~analysis.calibration.sumo_fit.calibrate_sumo`)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from analysis.calibration.classes import DriverClasses
from analysis.calibration.models import CFParams
from analysis.calibration.objective import DEFAULT_OBJECTIVE
from analysis.calibration.pairs import CarFollowingPair


@dataclass(frozen=True)
class ParamSpread:
    """Distribution of one parameter over the per-pair fits."""

    mean: float
    std: float
    median: float
    q10: float
    q90: float


@dataclass(frozen=True)
class PairFit:
    """One pair's own fit: its parameters and spacing RMSE (m) under them."""

    name: str
    group: str
    params: CFParams
    rmse_m: float


@dataclass(frozen=True)
class CalibrationResult:
    """Population fit + per-pair fits of one model.

    Attributes:
        model: "idm", "krauss" or "eidm" (a key of ``models.CALIBRATION_MODELS``).
        fitted: names of the fitted parameters (the others stay at ``population``'s values).
        population: the population parameters.
        population_median_rmse_m: median over training pairs of the spacing RMSE (m).
        per_pair: the per-pair fits (empty if not run).
        spread: (parameter name, :class:`ParamSpread` over ``per_pair``) pairs.
        n_pairs: training pairs used.
        seconds_population, seconds_per_pair: wall time of the two fits.
        objective: the population fit's objective (a key of :data:`~analysis.calibration.objective.OBJECTIVES`).
        classes: one population vector per class of the initial time headway
            (:class:`~analysis.calibration.classes.DriverClasses`), or None (one vector for all).
        train_followers: the training pairs' followers (``CarFollowingPair.group``), sorted, so
            that an evaluation can tell held-out drivers from the fit's own; empty if unknown
            (a file written before they were recorded, or a hand-written one).
    """

    model: str
    fitted: tuple[str, ...]
    population: CFParams
    population_median_rmse_m: float
    per_pair: tuple[PairFit, ...]
    spread: tuple[tuple[str, ParamSpread], ...]
    n_pairs: int
    seconds_population: float
    seconds_per_pair: float
    objective: str = DEFAULT_OBJECTIVE
    classes: DriverClasses | None = None
    train_followers: tuple[str, ...] = ()

    def spread_of(self, name: str) -> ParamSpread:
        return dict(self.spread)[name]


def spread_of(fits: Sequence[PairFit], names: Sequence[str]) -> tuple[tuple[str, ParamSpread], ...]:
    """Per-parameter mean, std, median and 10/90 % quantiles over per-pair fits."""
    out = []
    for n in names:
        v = np.array([getattr(f.params, n) for f in fits])
        out.append((n, ParamSpread(
            mean=float(v.mean()), std=float(v.std(ddof=1)) if len(v) > 1 else 0.0,
            median=float(np.median(v)), q10=float(np.quantile(v, 0.1)), q90=float(np.quantile(v, 0.9)),
        )))
    return tuple(out)


def followers_of(pairs: Sequence[CarFollowingPair]) -> tuple[str, ...]:
    """The sorted distinct followers (``group``) of ``pairs``."""
    return tuple(sorted({p.group for p in pairs}))
