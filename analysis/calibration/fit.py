"""Fitting SUMO car-following parameters to real leader-follower pairs (scipy.optimize and a
batched Levenberg-Marquardt).

* **Population fit** (:func:`fit_population`): one parameter set for all pairs. The residuals
  are the per-pair spacing RMSEs (m) under a robust loss (:data:`~analysis.calibration.objective.OBJECTIVES`; default ``log``,
  the geometric mean of the per-pair RMSEs), so a few pairs the model cannot follow at all do
  not dominate; ``scipy.optimize.least_squares`` (trust-region reflective, bounds), started
  from SUMO's defaults and from a congested-traffic guess, the better end point wins.
* **Per-pair fits** (:func:`fit_per_pair`): one parameter set per pair, minimising that pair's
  squared spacing errors: a Levenberg-Marquardt iteration per pair, all pairs advanced
  together (each pair's K x K normal equations solved in one batched ``numpy.linalg.solve``),
  started from the population fit.

Jacobians are forward differences computed in one vectorised simulation of the K+1 parameter
sets (base + one step per parameter) for every pair at once; one simulation gives a point's
residuals and its Jacobian.
The spread of the per-pair parameters is the spread of drivers
(:class:`~analysis.calibration.result.ParamSpread`). The objectives are in
:mod:`analysis.calibration.objective`, the result types in :mod:`analysis.calibration.result`.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import replace

import numpy as np
from scipy.optimize import least_squares

from analysis.calibration.models import CALIBRATION_MODELS, MODELS, SUMO_DEFAULTS, CFParams
from analysis.calibration.objective import DEFAULT_OBJECTIVE, OBJECTIVES, spacing_errors, spacing_rmse
from analysis.calibration.pairs import CarFollowingPair, PairBatch
from analysis.calibration.result import CalibrationResult, PairFit, followers_of, spread_of
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


def _check(model: str, fitted: Sequence[str]) -> None:
    if model not in MODELS:
        hint = (f"; {model!r} has no numpy replica, fit it through SUMO (analysis.calibration.sumo_fit)"
                if model in CALIBRATION_MODELS else "")
        raise SpecError(f"model: expected one of {sorted(MODELS)}, got {model!r}{hint}")
    check_fitted(fitted)


def check_fitted(fitted: Sequence[str]) -> None:
    """Raises:
        SpecError: a name without bounds (:data:`BOUNDS`), or no name at all."""
    bad = [f for f in fitted if f not in BOUNDS]
    if bad:
        raise SpecError(f"fitted: cannot fit {bad}; fittable: {sorted(BOUNDS)}")
    if not fitted:
        raise SpecError("fitted: at least one parameter must be fitted")


def bounds_of(fitted: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
    """(lower float64[K], upper float64[K]) :data:`BOUNDS` of the parameters ``fitted``."""
    return (np.array([BOUNDS[f][0] for f in fitted]), np.array([BOUNDS[f][1] for f in fitted]))


def _clip_start(p: CFParams, fitted: Sequence[str]) -> np.ndarray:
    lo, hi = bounds_of(fitted)
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
    base: CFParams = SUMO_DEFAULTS, starts: Sequence[CFParams] | None = None, max_nfev: int = 40,
    objective: str = DEFAULT_OBJECTIVE, tick: Callable[[], None] | None = None, action_steps: int = 1,
) -> tuple[CFParams, float]:
    """Population parameters and the median per-pair spacing RMSE (m) under them.

    ``scipy.optimize.least_squares`` (trust-region reflective, bounds) on the per-pair
    residuals of ``objective`` (see :data:`~analysis.calibration.objective.OBJECTIVES`) under its robust loss, from each start
    (default: ``base`` and :data:`CONGESTED_GUESS`); the lowest cost wins. Every evaluation
    simulates the point and its K forward-difference neighbours in one vectorised simulation
    (float64[P, K+1]), so the residuals and the Jacobian of a point cost one simulation.

    Args:
        pairs: the P training pairs.
        base: the values of the parameters not in ``fitted``.
        max_nfev: evaluations per start (``least_squares``' ``max_nfev``).
        objective: a key of :data:`~analysis.calibration.objective.OBJECTIVES`.
        tick: called once per simulation of the batch (progress reporting).
        action_steps: the drivers decide every that many 0.1 s steps (SUMO's ``actionStepLength``,
            :func:`~analysis.calibration.models.simulate_follower`); 1, SUMO's default, in the
            product (a longer one did not generalise better, ``studies/reaction_time_bound.py``).
    Returns:
        (population parameters, median over ``pairs`` of their spacing RMSE in m).

    Raises:
        SpecError: unknown model, parameter or objective names.
    """
    tick = tick or (lambda: None)
    _check(model, fitted)
    if objective not in OBJECTIVES:
        raise SpecError(f"objective: expected one of {sorted(OBJECTIVES)}, got {objective!r}")
    loss, f_scale, normalised = OBJECTIVES[objective]
    batch = PairBatch.from_pairs(pairs)
    fitted = tuple(fitted)
    lo, hi = bounds_of(fitted)
    fixed = base.as_dict()
    # per-pair scale of the residual: 1 m, or the pair's spacing RMSE under SUMO's defaults
    norm = spacing_rmse(model, batch, {**SUMO_DEFAULTS.as_dict(), "delta": fixed["delta"],
                                       "emergencyDecel": fixed["emergencyDecel"]}) if normalised else 1.0
    norm = np.maximum(norm, 0.1) if normalised else norm
    cache: dict[bytes, tuple[np.ndarray, np.ndarray]] = {}

    def params_of(x: np.ndarray) -> dict:
        return {**fixed, **dict(zip(fitted, map(float, x)))}

    def evaluate_at(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(residuals float64[P], Jacobian float64[P, K]) at x, one simulation, last point cached."""
        key = x.tobytes()
        if key not in cache:
            tick()
            cand, h = _fd_candidates(x[None, :], lo, hi)
            pc = {**fixed, **{f: cand[0, k] for k, f in enumerate(fitted)}}  # each float64[K+1]
            r = spacing_rmse(model, batch, pc, candidates=True, action_steps=action_steps) / np.reshape(norm, (-1, 1))
            cache.clear()
            cache[key] = (r[:, 0], (r[:, 1:] - r[:, :1]) / h[0][None, :])
        return cache[key]

    if starts is None:
        starts = (base, replace(CONGESTED_GUESS, delta=base.delta, emergencyDecel=base.emergencyDecel))
    best = None
    for start in starts:
        sol = least_squares(lambda x: evaluate_at(x)[0], _clip_start(start, fitted), jac=lambda x: evaluate_at(x)[1],
                            bounds=(lo, hi), method="trf", loss=loss, f_scale=f_scale, x_scale=hi - lo,
                            max_nfev=max_nfev)
        if best is None or sol.cost < best.cost:
            best = sol
    assert best is not None, "starts holds one or two start points"
    pop = CFParams(**params_of(best.x))
    return pop, float(np.median(spacing_rmse(model, batch, pop.as_dict(), action_steps=action_steps)))


def fit_per_pair(
    pairs: Sequence[CarFollowingPair], start: CFParams, *, model: str = "idm",
    fitted: Sequence[str] = FITTED, max_nfev: int = 40, tick: Callable[[], None] | None = None,
) -> tuple[PairFit, ...]:
    """Each pair's own parameters (started from ``start``): a Levenberg-Marquardt fit per pair,
    all pairs advanced together.

    Every pair's problem is its own least-squares fit of K parameters to its spacing errors, so
    the pairs are independent; one iteration simulates every pair's trial point and its K
    forward-difference neighbours in one vectorised simulation (``K + 1`` candidates per pair),
    then solves each pair's K x K damped normal equations
    ``(J^T J + lambda diag(J^T J)) dz = -J^T e`` in variables scaled by the bound range
    (Levenberg 1944; Marquardt 1963, *J. SIAM* 11(2)), projects the step onto the bounds (parameters
    at a bound with the gradient pointing out are held) and keeps it where the pair's squared
    error decreased (lambda / 3, else lambda x 4 and the old point). ``max_nfev`` is the
    number of iterations (simulations of the batch); a pair stops once its relative decrease
    falls below 1e-6 or its lambda exceeds 1e8.

    Args:
        pairs: P pairs.
        start: the start of every pair (usually the population fit); the parameters not in
            ``fitted`` stay at its values.
    Returns:
        P :class:`PairFit`, in the order of ``pairs``.

    Raises:
        SpecError: unknown model or parameter names.
    """
    tick = tick or (lambda: None)
    _check(model, fitted)
    batch = PairBatch.from_pairs(pairs)
    fitted = tuple(fitted)
    P, K = len(pairs), len(fitted)
    lo, hi = bounds_of(fitted)
    scale = hi - lo
    fixed = start.as_dict()

    def params_of(xs: np.ndarray) -> dict:
        return {**fixed, **{f: xs[:, k] for k, f in enumerate(fitted)}}

    def errors_and_jacobian(xs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """xs float64[P, K] -> (err float64[P, T], jac float64[P, T, K] in scaled variables)."""
        tick()
        cand, h = _fd_candidates(xs, lo, hi)
        err = spacing_errors(model, batch, params_of_cand(cand), candidates=True)  # [P, K+1, T]
        jac = (err[:, 1:, :] - err[:, :1, :]) / h[:, :, None] * scale[None, :, None]
        return err[:, 0, :], np.moveaxis(jac, 1, 2)

    def params_of_cand(cand: np.ndarray) -> dict:
        return {**fixed, **{f: cand[:, k, :] for k, f in enumerate(fitted)}}  # each float64[P, K+1]

    x = np.tile(_clip_start(start, fitted), (P, 1))
    err, jac = errors_and_jacobian(x)
    cost = 0.5 * (err * err).sum(axis=1)
    lam = np.full(P, 1e-3)
    active = np.ones(P, dtype=bool)
    eye = np.eye(K)
    for _ in range(max_nfev - 1):
        if not active.any():
            break
        a = np.einsum("ptk,ptl->pkl", jac, jac)  # [P, K, K]
        g = np.einsum("ptk,pt->pk", jac, err)  # [P, K]
        held = ((x <= lo) & (g > 0)) | ((x >= hi) & (g < 0))  # a step would leave the box
        d = np.einsum("pkk->pk", a)
        m = a + (lam[:, None] * np.maximum(d, 1e-12))[:, :, None] * eye
        free = ~held
        m = np.where(free[:, :, None] & free[:, None, :], m, 0.0) + np.where(held, 1.0, 0.0)[:, :, None] * eye
        dz = -np.linalg.solve(m, np.where(held, 0.0, g)[:, :, None])[:, :, 0]
        x_try = np.where(active[:, None], np.clip(x + dz * scale, lo, hi), x)
        err_try, jac_try = errors_and_jacobian(x_try)
        cost_try = 0.5 * (err_try * err_try).sum(axis=1)
        ok = active & (cost_try < cost)
        gain = np.where(ok, (cost - cost_try) / np.maximum(cost, 1e-300), 0.0)
        x[ok], err[ok], jac[ok], cost[ok] = x_try[ok], err_try[ok], jac_try[ok], cost_try[ok]
        lam = np.where(ok, np.maximum(lam / 3.0, 1e-9), lam * 4.0)
        active &= ~(ok & (gain < 1e-6)) & (lam < 1e8)
    rmse = np.sqrt(2.0 * cost / batch.mask.sum(axis=1))
    xs, rmse = batch.unsort(x), batch.unsort(rmse)
    out = []
    for i, p in enumerate(pairs):
        vals = {**fixed, **{f: float(xs[i, k]) for k, f in enumerate(fitted)}}
        out.append(PairFit(name=p.name, group=p.group, params=CFParams(**vals), rmse_m=float(rmse[i])))
    return tuple(out)


def calibrate(
    pairs: Sequence[CarFollowingPair], *, model: str = "idm", fitted: Sequence[str] = FITTED,
    per_pair: bool = True, base: CFParams = SUMO_DEFAULTS,
    max_nfev_population: int = 40, max_nfev_per_pair: int = 40, objective: str = DEFAULT_OBJECTIVE,
    progress: bool = False,
) -> CalibrationResult:
    """Population fit, then (optionally) per-pair fits started from it.

    With per-pair fits, the "median driver" (every fitted parameter at its median over the
    per-pair fits) is a second population candidate; the population parameters reported are
    whichever of the two has the lower median spacing RMSE over the training pairs (the
    median driver usually wins on the median, the least-squares fit on the mean).
    """
    from merge_irl.progress import progress_bar

    # upper bound on batch simulations: 2 starts x one per evaluation, one per per-pair iteration
    total = 2 * max_nfev_population + (max_nfev_per_pair if per_pair else 0)
    bar = progress_bar(total, desc=f"calibrate {model}", unit="sim", enabled=progress)
    tick = lambda: bar.update(1)  # noqa: E731
    try:
        t0 = time.perf_counter()
        pop, med = fit_population(pairs, model=model, fitted=fitted, base=base,
                                  max_nfev=max_nfev_population, objective=objective, tick=tick)
        t1 = time.perf_counter()
        fits = (fit_per_pair(pairs, pop, model=model, fitted=fitted, max_nfev=max_nfev_per_pair, tick=tick)
                if per_pair else ())
    finally:
        bar.close()
    return assemble_result(pairs, model=model, fitted=fitted, population=pop, median_rmse_m=med,
                           per_pair=fits, seconds_population=t1 - t0, seconds_per_pair=time.perf_counter() - t1,
                           objective=objective)


def assemble_result(
    pairs: Sequence[CarFollowingPair], *, model: str, fitted: Sequence[str], population: CFParams,
    median_rmse_m: float, per_pair: Sequence[PairFit], seconds_population: float, seconds_per_pair: float,
    objective: str = DEFAULT_OBJECTIVE,
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
        seconds_population=seconds_population, seconds_per_pair=seconds_per_pair, objective=objective,
        train_followers=followers_of(pairs),
    )


#: A per-pair parameter within this share of its bound range from a bound sits on it.
ON_BOUND_FRACTION = 1e-3


def fits_on_bounds(per_pair: Sequence[PairFit], fitted: Sequence[str]) -> list[tuple[str, str, int]]:
    """``(parameter, "lower" | "upper", count)`` of the per-pair fits whose parameter sits on a bound
    of :data:`BOUNDS` (within :data:`ON_BOUND_FRACTION` of the range): there the bound, not the
    pair, set the value. Empty when none does (or no per-pair fits)."""
    out = []
    for name in fitted:
        if name not in BOUNDS or not per_pair:
            continue
        lo, hi = BOUNDS[name]
        tol = ON_BOUND_FRACTION * (hi - lo)
        vals = np.array([getattr(f.params, name) for f in per_pair], dtype=np.float64)
        for side, n in (("lower", int(np.sum(vals <= lo + tol))), ("upper", int(np.sum(vals >= hi - tol)))):
            if n:
                out.append((name, side, n))
    return out


def bounds_warning(per_pair: Sequence[PairFit], fitted: Sequence[str]) -> str:
    """One line saying which per-pair fits sit on which bound (:func:`fits_on_bounds`), or ``""``."""
    hits = fits_on_bounds(per_pair, fitted)
    if not hits:
        return ""
    said = ", ".join(f"{name} at its {side} bound {BOUNDS[name][0 if side == 'lower' else 1]:g} in {n}"
                     for name, side, n in hits)
    return (f"{len(per_pair)} per-pair fits: {said}: there the bound, not the pair, sets the value (the pair does "
            "not inform it, or the model cannot follow it); read their spread with that in mind")
