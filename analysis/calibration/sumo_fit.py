"""Calibration through real SUMO (libsumo): the route for models without a numpy replica (EIDM).

SUMO's EIDM (``MSCFModel_EIDM``; Salles, Kaufmann & Reuss, "Extending the Intelligent Driver
Model in SUMO and Verifying the Drive Off Trajectories with Aerial Measurements", SUMO User
Conference 2020) keeps state between steps (decisions only at action points up to ``treaction``
apart, a jerk limit, a drive-off curve), so instead of replicating it the pairs are replayed in
SUMO itself (:func:`analysis.calibration.sumo_replay.run_sumo_pairs`): every parameter set is
one SUMO run over the pairs, split over worker processes (:class:`SumoRmse`).

* :class:`SumoRmse`: per-pair spacing RMSE (m) of parameter sets, float64[P, C].
* :func:`fit_population_sumo`: one parameter set for all pairs, derivative free
  (``scipy.optimize.minimize``, Nelder-Mead within the bounds; Nelder & Mead 1965, *Comput. J.*
  7(4)), on the same robust objectives as the replica's fit (:data:`~.objective.OBJECTIVES`); each
  evaluation is one SUMO run, capped by ``max_evals``. EIDM's response to its parameters is not
  smooth (action points, thresholds), hence no finite-difference Jacobian.
* :func:`calibrate_sumo`: the population fit as a :class:`~.result.CalibrationResult` (no per-pair
  fits: at one SUMO run per evaluation they would take hours).

The spacing RMSE is scored as in :mod:`.objective`: bumper gap over the steps ``1 .. len-1`` of
each pair, here SUMO's gap (its leader replays the recorded speeds from the recorded initial
gap; the replica's leader takes the recorded positions, which differ by centimetres).
"""

from __future__ import annotations

import multiprocessing
import os
import pickle
import tempfile
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import replace

import numpy as np
from scipy.optimize import minimize

from analysis.calibration.fit import CONGESTED_GUESS, FITTED, bounds_of, check_fitted
from analysis.calibration.models import CALIBRATION_MODELS, SUMO_DEFAULTS, CFParams
from analysis.calibration.objective import DEFAULT_OBJECTIVE, OBJECTIVES
from analysis.calibration.pairs import CarFollowingPair
from analysis.calibration.result import CalibrationResult, followers_of
from analysis.calibration.sumo_replay import ReplayCase, run_sumo_pairs
from merge_irl.spawn_guard import GUARD_HINT, importing_main_in_worker
from scenarios.errors import ScenarioError, SpecError

#: SUMO runs (parameter sets simulated over all training pairs) of a population fit by default.
DEFAULT_MAX_EVALS = 60
#: Fewest SUMO runs of a default population fit: its 2 starts + one simplex vertex per fitted parameter.
MIN_MAX_EVALS = 2 + len(FITTED)
#: Edge of the initial Nelder-Mead simplex, as a fraction of each parameter's bound range.
SIMPLEX_STEP = 0.1
#: Where the recorded leader starts on the replay edge (m).
_X0 = 100.0


def replay_case(pair: CarFollowingPair) -> ReplayCase:
    """The pair as a SUMO replay: recorded leader speeds, follower from its recorded gap and speed."""
    return ReplayCase(v_leader=pair.v_leader, x_leader0=_X0,
                      x_follower0=_X0 - float(pair.x_leader[0] - pair.x_follower[0]),
                      v_follower0=float(pair.v_follower[0]), leader_length=float(pair.leader_length))


_WORKER: dict = {}


def _init_worker(pairs_file: str) -> None:
    with open(pairs_file, "rb") as f:
        _WORKER["pairs"] = pickle.load(f)


def _rmse_task(idx: Sequence[int], params: Sequence[dict], model: str) -> np.ndarray:
    """Worker: per-pair spacing RMSE (m) of pairs ``idx`` under each parameter set: float64[n, C]."""
    pairs = [_WORKER["pairs"][i] for i in idx]
    n, C = len(pairs), len(params)
    cases = [replay_case(p) for p in pairs] * C
    plist = [CFParams(**d) for d in params for _ in pairs]
    try:
        r = run_sumo_pairs(cases, plist, model=model)
    except Exception as e:  # libsumo's errors do not pickle back to the parent
        raise ScenarioError(f"SUMO replay of {n} pairs x {C} parameter sets ({model}): {type(e).__name__}: {e}") from None
    out = np.empty((n, C))
    for c in range(C):
        for i, p in enumerate(pairs):
            k = c * n + i
            m = len(p)
            gap = r.x_leader[k, :m] - p.leader_length - r.x_follower[k, :m]
            out[i, c] = np.sqrt(np.mean((gap[1:] - p.spacing[1:]) ** 2))
    return out


class SumoRmse:
    """Per-pair spacing RMSE of parameter sets, simulated by SUMO in worker processes.

    The pairs are split into ``workers`` chunks of similar total length; each call runs, in
    every worker, one SUMO simulation of its chunk x all the parameter sets given (each pair
    on its own edge, so nothing interacts). Workers are started once (``spawn``) and reused
    (libsumo restarts in the same process). Use as a context manager or call :meth:`close`.

    Args:
        pairs: the P pairs.
        model: a key of :data:`~analysis.calibration.models.CALIBRATION_MODELS`.
        workers: processes (default: one per core, at most P).

    Raises:
        SpecError: unknown ``model`` or no pairs.
        ScenarioError: created while a ``spawn`` worker imports the main script (a script that
            calls the SUMO fit at module level, without ``if __name__ == "__main__":``); without
            this check the worker would start workers of its own and the fit would hang.
    """

    def __init__(self, pairs: Sequence[CarFollowingPair], model: str, workers: int | None = None) -> None:
        # otherwise the worker would start workers of its own (multiprocessing's bootstrapping
        # error then leaves it waiting on its pool's threads, and the parent waiting on it)
        if importing_main_in_worker():
            raise ScenarioError(
                f"the SUMO calibration was started while a worker process imported the main script: {GUARD_HINT}")
        if model not in CALIBRATION_MODELS:
            raise SpecError(f"model: expected one of {sorted(CALIBRATION_MODELS)}, got {model!r}")
        if not pairs:
            raise SpecError("no pairs given")
        self.model = model
        self.n_pairs = len(pairs)
        w = max(1, min(len(pairs), workers or os.cpu_count() or 1))
        order = sorted(range(len(pairs)), key=lambda i: -len(pairs[i]))
        self._chunks = [order[c::w] for c in range(w)]  # round robin: similar total lengths
        # The pairs go to the workers through a file: a large initializer argument is written to
        # each new worker's pipe, and a worker that dies before reading it blocks that write forever.
        self._scratch = tempfile.TemporaryDirectory(prefix="merge-irl-pairs-")
        pairs_file = os.path.join(self._scratch.name, "pairs.pickle")
        with open(pairs_file, "wb") as f:
            pickle.dump(list(pairs), f, protocol=pickle.HIGHEST_PROTOCOL)
        self._pool = ProcessPoolExecutor(w, mp_context=multiprocessing.get_context("spawn"),
                                         initializer=_init_worker, initargs=(pairs_file,))
        self.runs = 0

    def __call__(self, params: Sequence[CFParams]) -> np.ndarray:
        """float64[P, C]: RMSE (m) of pair p (order given) under ``params[c]``.

        Raises:
            ScenarioError: SUMO failed (from :func:`run_sumo_pairs`).
        """
        dicts = [p.as_dict() for p in params]
        futures = [self._pool.submit(_rmse_task, idx, dicts, self.model) for idx in self._chunks]
        out = np.empty((self.n_pairs, len(dicts)))
        try:
            for idx, f in zip(self._chunks, futures):
                out[idx] = f.result()
        except BrokenProcessPool:
            raise ScenarioError(
                f"a SUMO worker process died before returning (see its traceback above; from a script: {GUARD_HINT})"
            ) from None
        self.runs += len(dicts)
        return out

    def close(self) -> None:
        self._pool.shutdown(cancel_futures=True)
        self._scratch.cleanup()

    def __enter__(self) -> SumoRmse:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def fit_population_sumo(
    pairs: Sequence[CarFollowingPair], *, model: str = "eidm", fitted: Sequence[str] = FITTED,
    base: CFParams = SUMO_DEFAULTS, starts: Sequence[CFParams] | None = None,
    max_evals: int = DEFAULT_MAX_EVALS, objective: str = DEFAULT_OBJECTIVE, workers: int | None = None,
    tick: Callable[[], None] | None = None,
) -> tuple[CFParams, float, int]:
    """Population parameters fitted through SUMO, the median per-pair spacing RMSE (m) under them,
    and the number of parameter sets simulated.

    The cost is the population objective of :func:`~.fit.fit_population` (``objective``, a key
    of :data:`~.objective.OBJECTIVES`: ``0.5 * sum_i s^2 log(1 + (r_i / s)^2)`` over the pairs' RMSEs
    ``r_i``, or their ratios to the defaults' RMSE), minimised by Nelder-Mead in the fitted
    parameters scaled to [0, 1] within :data:`~.fit.BOUNDS`. The starts (default: ``base`` and
    :data:`~.fit.CONGESTED_GUESS`) are simulated together; the best one is the first vertex,
    the others step :data:`SIMPLEX_STEP` of the range along each parameter (inwards at an upper
    bound) and are simulated together too; then every Nelder-Mead evaluation is one SUMO run
    over the pairs, until ``max_evals`` parameter sets have been simulated in all.

    Args:
        pairs: the P training pairs.
        model: a key of :data:`~analysis.calibration.models.CALIBRATION_MODELS`.
        base: the values of the parameters not in ``fitted``.
        max_evals: cap on the parameter sets simulated (starts and simplex included).
        workers: processes for the SUMO runs (default: one per core).
        tick: called once per SUMO evaluation (progress reporting).
    Returns:
        (population parameters, median over ``pairs`` of their spacing RMSE in m, SUMO runs).

    Raises:
        SpecError: unknown model, parameter or objective names, ``max_evals`` too small for the
            starts and the simplex, or no pairs.
        ScenarioError: SUMO failed.
    """
    tick = tick or (lambda: None)
    fitted = tuple(fitted)
    check_fitted(fitted)
    if objective not in OBJECTIVES:
        raise SpecError(f"objective: expected one of {sorted(OBJECTIVES)}, got {objective!r}")
    if starts is None:
        starts = (base, replace(CONGESTED_GUESS, delta=base.delta, emergencyDecel=base.emergencyDecel))
    K = len(fitted)
    if max_evals < len(starts) + K:
        raise SpecError(f"max_evals: {max_evals} is below the {len(starts)} starts + {K} simplex vertices")
    loss, f_scale, normalised = OBJECTIVES[objective]
    assert loss == "cauchy", "every objective uses the Cauchy loss"
    lo, hi = bounds_of(fitted)
    fixed = base.as_dict()

    def params_at(z: np.ndarray) -> CFParams:
        return CFParams(**{**fixed, **dict(zip(fitted, map(float, lo + np.clip(z, 0.0, 1.0) * (hi - lo))))})

    def scaled(p: CFParams) -> np.ndarray:
        return np.clip((np.array([getattr(p, f) for f in fitted]) - lo) / (hi - lo), 0.0, 1.0)

    rmse_of: dict[bytes, np.ndarray] = {}
    with SumoRmse(pairs, model, workers) as sim:
        norm = 1.0
        if normalised:
            d = {**SUMO_DEFAULTS.as_dict(), "delta": fixed["delta"], "emergencyDecel": fixed["emergencyDecel"]}
            norm = np.maximum(sim([CFParams(**d)])[:, 0], 0.1)

        def simulate(zs: Sequence[np.ndarray]) -> None:
            new = [z for z in zs if z.tobytes() not in rmse_of]
            if new:
                r = sim([params_at(z) for z in new])
                for c, z in enumerate(new):
                    tick()
                    rmse_of[z.tobytes()] = r[:, c]

        def cost(z: np.ndarray) -> float:
            z = np.clip(np.asarray(z, dtype=np.float64), 0.0, 1.0)
            if z.tobytes() not in rmse_of:
                if sim.runs >= max_evals:
                    return np.inf  # over budget: Nelder-Mead stops by maxfev right after
                simulate([z])
            u = rmse_of[z.tobytes()] / norm / f_scale
            return float(0.5 * f_scale**2 * np.sum(np.log1p(u * u)))

        zs = [scaled(s) for s in starts]
        simulate(zs)
        z0 = min(zs, key=cost)
        simplex = [z0] + [z0 + np.where(np.arange(K) == k, SIMPLEX_STEP if z0[k] + SIMPLEX_STEP <= 1 else -SIMPLEX_STEP,
                                        0.0) for k in range(K)]
        simulate(simplex[1:])
        budget = max_evals - sim.runs + (K + 1)  # Nelder-Mead counts the simplex's K + 1 (cached) evaluations
        minimize(cost, z0, method="Nelder-Mead", bounds=[(0.0, 1.0)] * K,
                 options={"initial_simplex": np.array(simplex), "maxfev": budget, "xatol": 1e-3, "fatol": 1e-3})
        runs = sim.runs
    best = min(rmse_of, key=lambda k: cost(np.frombuffer(k)))
    z_best = np.frombuffer(best)
    return params_at(z_best), float(np.median(rmse_of[best])), runs


def calibrate_sumo(
    pairs: Sequence[CarFollowingPair], *, model: str = "eidm", fitted: Sequence[str] = FITTED,
    base: CFParams = SUMO_DEFAULTS, max_evals: int = DEFAULT_MAX_EVALS, objective: str = DEFAULT_OBJECTIVE,
    workers: int | None = None, tick: Callable[[], None] | None = None,
) -> CalibrationResult:
    """:func:`fit_population_sumo` as a :class:`~.result.CalibrationResult` (no per-pair fits).

    Raises:
        SpecError, ScenarioError: as :func:`fit_population_sumo`.
    """
    t0 = time.perf_counter()
    pop, med, _ = fit_population_sumo(pairs, model=model, fitted=fitted, base=base, max_evals=max_evals,
                                      objective=objective, workers=workers, tick=tick)
    return CalibrationResult(
        model=model, fitted=tuple(fitted), population=pop, population_median_rmse_m=med, per_pair=(),
        spread=(), n_pairs=len(pairs), seconds_population=time.perf_counter() - t0, seconds_per_pair=0.0,
        objective=objective, train_followers=followers_of(pairs),
    )
