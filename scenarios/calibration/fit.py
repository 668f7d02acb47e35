"""Fitting SUMO car-following parameters to real leader-follower pairs (scipy.optimize).

* **Population fit** (:func:`fit_population`): one parameter set for all pairs. The residuals
  are the per-pair spacing RMSEs (m) under a robust Cauchy loss (scale 1 m), so a few pairs
  the model cannot follow at all do not dominate; ``scipy.optimize.least_squares``
  (trust-region reflective, bounds), started from SUMO's defaults and from a congested-traffic
  guess, the better end point wins.
* **Per-pair fits** (:func:`fit_per_pair`): one parameter set per pair, minimising that pair's
  squared spacing errors. All pairs are solved as one ``least_squares`` problem whose Jacobian
  is block-diagonal (pair i's residuals depend only on pair i's parameters), started from the
  population fit.

Jacobians are forward differences computed in one vectorised simulation of the K+1 parameter
sets (base + one step per parameter) for every pair at once.
The spread of the per-pair parameters is the spread of drivers (:class:`ParamSpread`).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import least_squares
from scipy.sparse import csr_matrix

from scenarios.calibration.models import MODELS, SUMO_DEFAULTS, CFParams
from scenarios.calibration.objective import spacing_errors, spacing_rmse
from scenarios.calibration.pairs import CarFollowingPair, PairBatch
from scenarios.errors import SpecError

#: Parameters fitted by default, and their bounds (SI units). The bounds keep the values
#: physical for passenger cars in freeway traffic (ranges reported for IDM calibrations on
#: NGSIM-like data, Treiber & Kesting, *Traffic Flow Dynamics*, 2013, Table 11.2 and ch. 16):
#: comfortable deceleration at least 1 m/s^2 (a fit at 0.7 m/s^2 is a symptom of pairs the
#: model cannot follow, not of a driver), time headway 0.3 .. 3 s, desired speed 10 .. 40 m/s.
FITTED: tuple[str, ...] = ("accel", "decel", "tau", "minGap", "maxSpeed")
BOUNDS: dict[str, tuple[float, float]] = {
    "accel": (0.3, 4.0),
    "decel": (1.0, 6.0),
    "tau": (0.3, 3.0),
    "minGap": (0.5, 6.0),
    "maxSpeed": (10.0, 40.0),
    "delta": (1.0, 10.0),
}
#: Second start of the population fit: a guess for congested freeway traffic.
CONGESTED_GUESS = CFParams(accel=1.0, decel=2.0, tau=1.2, minGap=2.0, maxSpeed=20.0)
#: Forward-difference step, as a fraction of each parameter's bound range.
DIFF_STEP = 1e-4


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
        model: "idm" or "krauss".
        fitted: names of the fitted parameters (the others stay at ``population``'s values).
        population: the population parameters.
        population_median_rmse_m: median over training pairs of the spacing RMSE (m).
        per_pair: the per-pair fits (empty if not run).
        spread: (parameter name, :class:`ParamSpread` over ``per_pair``) pairs.
        n_pairs: training pairs used.
        seconds_population, seconds_per_pair: wall time of the two fits.
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

    def spread_of(self, name: str) -> ParamSpread:
        return dict(self.spread)[name]


def _check(model: str, fitted: Sequence[str]) -> None:
    if model not in MODELS:
        raise SpecError(f"model: expected one of {sorted(MODELS)}, got {model!r}")
    bad = [f for f in fitted if f not in BOUNDS]
    if bad:
        raise SpecError(f"fitted: cannot fit {bad}; fittable: {sorted(BOUNDS)}")
    if not fitted:
        raise SpecError("fitted: at least one parameter must be fitted")


def _bounds(fitted: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
    return (np.array([BOUNDS[f][0] for f in fitted]), np.array([BOUNDS[f][1] for f in fitted]))


def _clip_start(p: CFParams, fitted: Sequence[str]) -> np.ndarray:
    lo, hi = _bounds(fitted)
    x = np.array([getattr(p, f) for f in fitted], dtype=np.float64)
    return np.clip(x, lo + 1e-6 * (hi - lo), hi - 1e-6 * (hi - lo))


def _fd_candidates(xs: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """xs: float64[P, K] -> (cand float64[P, K, K+1] base + forward steps, h float64[P, K])."""
    P, K = xs.shape
    h = DIFF_STEP * (hi - lo) * np.ones((P, K))
    h = np.where(xs + h > hi, -h, h)  # step backwards at the upper bound
    cand = np.repeat(xs[:, :, None], K + 1, axis=2)
    for k in range(K):
        cand[:, k, k + 1] += h[:, k]
    return cand, h


def fit_population(
    pairs: Sequence[CarFollowingPair], *, model: str = "idm", fitted: Sequence[str] = FITTED,
    base: CFParams = SUMO_DEFAULTS, starts: Sequence[CFParams] | None = None, max_nfev: int = 60,
    tick: Callable[[], None] | None = None,
) -> tuple[CFParams, float]:
    """Population parameters and the median per-pair spacing RMSE (m) under them.

    ``tick`` (optional) is called once per simulation of the batch (progress reporting)."""
    tick = tick or (lambda: None)
    _check(model, fitted)
    batch = PairBatch.from_pairs(pairs)
    fitted = tuple(fitted)
    lo, hi = _bounds(fitted)
    fixed = base.as_dict()

    def params_of(x: np.ndarray) -> dict:
        return {**fixed, **dict(zip(fitted, map(float, x)))}

    def res(x: np.ndarray) -> np.ndarray:
        tick()
        return spacing_rmse(model, batch, params_of(x))

    def jac(x: np.ndarray) -> np.ndarray:
        tick()
        cand, h = _fd_candidates(x[None, :], lo, hi)
        pc = {**fixed, **{f: cand[0, k] for k, f in enumerate(fitted)}}  # each float64[K+1]
        r = spacing_rmse(model, batch, pc, candidates=True)  # [P, K+1]
        return (r[:, 1:] - r[:, :1]) / h[0][None, :]

    if starts is None:
        starts = (base, replace(CONGESTED_GUESS, delta=base.delta, emergencyDecel=base.emergencyDecel))
    best = None
    for start in starts:
        sol = least_squares(res, _clip_start(start, fitted), jac=jac, bounds=(lo, hi), method="trf",
                            loss="cauchy", f_scale=1.0, x_scale=hi - lo, max_nfev=max_nfev)
        if best is None or sol.cost < best.cost:
            best = sol
    assert best is not None, "starts holds one or two start points"
    pop = CFParams(**params_of(best.x))
    return pop, float(np.median(spacing_rmse(model, batch, pop.as_dict())))


def fit_per_pair(
    pairs: Sequence[CarFollowingPair], start: CFParams, *, model: str = "idm",
    fitted: Sequence[str] = FITTED, max_nfev: int = 40, tick: Callable[[], None] | None = None,
) -> tuple[PairFit, ...]:
    """Each pair's own parameters (started from ``start``), solved jointly (block-diagonal)."""
    tick = tick or (lambda: None)
    _check(model, fitted)
    batch = PairBatch.from_pairs(pairs)
    fitted = tuple(fitted)
    P, K = len(pairs), len(fitted)
    lo, hi = _bounds(fitted)
    fixed = start.as_dict()
    w = 1.0 / np.sqrt(batch.mask.sum(axis=1))  # per-pair weight: sum of squares = sum of MSEs
    rows_of_pair = np.nonzero(batch.mask)[0]  # pair index of every residual
    n_res = len(rows_of_pair)

    def params_of(xs: np.ndarray) -> dict:
        return {**fixed, **{f: xs[:, k] for k, f in enumerate(fitted)}}

    def res(x: np.ndarray) -> np.ndarray:
        tick()
        err = spacing_errors(model, batch, params_of(x.reshape(P, K)))
        return (err * w[:, None])[batch.mask]

    def jac(x: np.ndarray) -> csr_matrix:
        tick()
        cand, h = _fd_candidates(x.reshape(P, K), lo, hi)
        pc: dict[str, np.ndarray | float] = {**fixed, **{f: cand[:, k, :] for k, f in enumerate(fitted)}}  # each float64[P, K+1]
        err = spacing_errors(model, batch, pc, candidates=True)  # [P, K+1, T]
        d = (err[:, 1:, :] - err[:, :1, :]) / h[:, :, None] * w[:, None, None]  # [P, K, T]
        vals = np.moveaxis(d, 1, 2)[batch.mask]  # [n_res, K]
        cols = rows_of_pair[:, None] * K + np.arange(K)[None, :]
        return csr_matrix((vals.ravel(), (np.repeat(np.arange(n_res), K), cols.ravel())),
                          shape=(n_res, P * K))

    x0 = np.tile(_clip_start(start, fitted), P)
    sol = least_squares(res, x0, jac=jac, bounds=(np.tile(lo, P), np.tile(hi, P)), method="trf",
                        x_scale=np.tile(hi - lo, P), tr_solver="lsmr", max_nfev=max_nfev)
    xs = sol.x.reshape(P, K)
    rmse = spacing_rmse(model, batch, params_of(xs))
    xs, rmse = batch.unsort(xs), batch.unsort(rmse)
    out = []
    for i, p in enumerate(pairs):
        vals = {**fixed, **{f: float(xs[i, k]) for k, f in enumerate(fitted)}}
        out.append(PairFit(name=p.name, group=p.group, params=CFParams(**vals), rmse_m=float(rmse[i])))
    return tuple(out)


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


def calibrate(
    pairs: Sequence[CarFollowingPair], *, model: str = "idm", fitted: Sequence[str] = FITTED,
    per_pair: bool = True, base: CFParams = SUMO_DEFAULTS,
    max_nfev_population: int = 60, max_nfev_per_pair: int = 40, progress: bool = False,
) -> CalibrationResult:
    """Population fit, then (optionally) per-pair fits started from it.

    With per-pair fits, the "median driver" (every fitted parameter at its median over the
    per-pair fits) is a second population candidate; the population parameters reported are
    whichever of the two has the lower median spacing RMSE over the training pairs (the
    median driver usually wins on the median, the least-squares fit on the mean).
    """
    import sys

    from tqdm import tqdm

    # upper bound on batch simulations: 2 starts x (residual + Jacobian) per evaluation
    total = 4 * max_nfev_population + (2 * max_nfev_per_pair if per_pair else 0)
    bar = tqdm(total=total, desc=f"calibrate {model}", unit="sim", file=sys.stderr,
               disable=not (progress and sys.stderr.isatty()))
    tick = lambda: bar.update(1)  # noqa: E731
    try:
        t0 = time.perf_counter()
        pop, med = fit_population(pairs, model=model, fitted=fitted, base=base,
                                  max_nfev=max_nfev_population, tick=tick)
        t1 = time.perf_counter()
        fits = (fit_per_pair(pairs, pop, model=model, fitted=fitted, max_nfev=max_nfev_per_pair, tick=tick)
                if per_pair else ())
    finally:
        bar.close()
    return assemble_result(pairs, model=model, fitted=fitted, population=pop, median_rmse_m=med,
                           per_pair=fits, seconds_population=t1 - t0, seconds_per_pair=time.perf_counter() - t1)


def assemble_result(
    pairs: Sequence[CarFollowingPair], *, model: str, fitted: Sequence[str], population: CFParams,
    median_rmse_m: float, per_pair: Sequence[PairFit], seconds_population: float, seconds_per_pair: float,
) -> CalibrationResult:
    """The :class:`CalibrationResult` of a population fit and per-pair fits (however they were run).

    With per-pair fits, the "median driver" (every fitted parameter at its median over the
    per-pair fits) replaces the population parameters if its median spacing RMSE over ``pairs``
    is lower.
    """
    pop, med, fits = population, median_rmse_m, tuple(per_pair)
    if fits:
        median_driver = replace(pop, **{f: float(np.median([getattr(x.params, f) for x in fits])) for f in fitted})
        batch = PairBatch.from_pairs(pairs)
        med2 = float(np.median(spacing_rmse(model, batch, median_driver.as_dict())))
        if med2 < med:
            pop, med = median_driver, med2
    return CalibrationResult(
        model=model, fitted=tuple(fitted), population=pop, population_median_rmse_m=med,
        per_pair=fits, spread=spread_of(fits, fitted) if fits else (), n_pairs=len(pairs),
        seconds_population=seconds_population, seconds_per_pair=seconds_per_pair,
    )
