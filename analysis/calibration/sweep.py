"""Per-pair car-following fits on every core, through the project's sweep runner.

:func:`analysis.calibration.fit_per_pair` solves all pairs as one block-diagonal problem; the
blocks are independent, so chunks of pairs are fitted as separate sweep tasks (one process
each) and joined. The population fit stays in the parent (one vectorised problem).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from pathlib import Path

from analysis.calibration import (
    CarFollowingPair,
    CFParams,
    PairFit,
    fit_per_pair,
    read_pair,
)
from analysis.calibration.fit import FITTED, assemble_result, fit_population
from analysis.calibration.models import MODELS
from analysis.calibration.objective import DEFAULT_OBJECTIVE
from analysis.calibration.result import CalibrationResult
from analysis.calibration.sumo_fit import DEFAULT_MAX_EVALS, calibrate_sumo
from analysis.sweep import Task, run_sweep
from analysis.sweep.executors import default_workers


def fit_chunk_task(config: dict, seed: int) -> dict:
    """Sweep task: per-pair fits of the pair files ``config["files"]`` (deterministic; ``seed`` unused).

    ``config``: files (list of CSV paths), model, fitted (list of names), start (CFParams as a
    dict), max_nfev. Returns ``{"fits": [{"name", "group", "params", "rmse_m"}, ...]}``.
    """
    pairs = [read_pair(f) for f in config["files"]]
    fits = fit_per_pair(pairs, CFParams(**config["start"]), model=config["model"],
                        fitted=tuple(config["fitted"]), max_nfev=config["max_nfev"])
    return {"fits": [{"name": f.name, "group": f.group, "params": f.params.as_dict(), "rmse_m": f.rmse_m}
                     for f in fits]}


def calibrate_parallel(
    pairs: Sequence[CarFollowingPair], files: Sequence[Path], *, model: str = "idm",
    fitted: Sequence[str] = FITTED, per_pair: bool = True, max_nfev_population: int = 40,
    max_nfev_per_pair: int = 40, objective: str = DEFAULT_OBJECTIVE, workers: int | None = None,
    progress: bool = False, max_evals_sumo: int | None = None, tick: Callable[[], None] | None = None,
) -> CalibrationResult:
    """Population fit in this process, then per-pair fits in ``workers`` processes.

    A model without a numpy replica (EIDM) is fitted through SUMO instead
    (:func:`analysis.calibration.sumo_fit.calibrate_sumo`: population only, ``max_evals_sumo``
    SUMO runs at most, default ``sumo_fit.DEFAULT_MAX_EVALS``, each split over ``workers``
    processes; ``per_pair`` is ignored, ``tick`` is called once per run). With a replica, ``tick``
    is called once per simulation of the population fit.

    Args:
        pairs: the training pairs; ``files[i]`` is the CSV ``pairs[i]`` was read from.
        objective: the population fit's objective (:data:`analysis.calibration.objective.OBJECTIVES`).
        workers: processes (default: one per core); the pairs are split in ``workers`` chunks
            of similar total length.

    Raises:
        SpecError: bad model or fitted names (from the fits).
        ScenarioError: SUMO failed (EIDM).
        RuntimeError: a chunk failed in every attempt (its error named).
    """
    if model not in MODELS:  # no numpy replica (EIDM): population fit through SUMO, no per-pair fits
        return calibrate_sumo(pairs, model=model, fitted=fitted, objective=objective, workers=workers,
                              max_evals=max_evals_sumo if max_evals_sumo is not None else DEFAULT_MAX_EVALS,
                              tick=tick)
    t0 = time.perf_counter()
    pop, med = fit_population(pairs, model=model, fitted=fitted, max_nfev=max_nfev_population, objective=objective,
                              tick=tick)
    t1 = time.perf_counter()
    fits: list[PairFit] = []
    if per_pair:
        # one chunk per process: a chunk's cost is its simulations, which barely grow with its size
        n_chunks = max(1, min(len(pairs), workers or default_workers()))
        order = sorted(range(len(pairs)), key=lambda i: -len(pairs[i]))
        chunks = [order[c::n_chunks] for c in range(n_chunks)]  # round-robin: similar lengths
        tasks = [Task(key=f"chunk{c:03d}", func=fit_chunk_task, config={
            "files": [str(files[i]) for i in idx], "model": model, "fitted": list(fitted),
            "start": pop.as_dict(), "max_nfev": max_nfev_per_pair}) for c, idx in enumerate(chunks)]
        executor = f"process:{workers}" if workers else "process"
        rep = run_sweep(tasks, executor=executor, progress=progress, desc=f"per-pair {model}")
        if rep.failures:
            f = rep.failures[0]
            raise RuntimeError(f"per-pair fit {f.key} failed: {f.error}")
        by_name = {d["name"]: d for t in tasks for d in rep.results[t.key]["fits"]}
        fits = [PairFit(name=p.name, group=p.group, params=CFParams(**by_name[p.name]["params"]),
                        rmse_m=float(by_name[p.name]["rmse_m"])) for p in pairs]
    return assemble_result(pairs, model=model, fitted=fitted, population=pop, median_rmse_m=med,
                           per_pair=fits, seconds_population=t1 - t0, seconds_per_pair=time.perf_counter() - t1,
                           objective=objective)
