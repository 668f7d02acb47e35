"""Pieces shared by the IRL solvers: theta initialisation and assembling a FitResult."""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np

from irl.ascent import AscentResult
from irl.config import IRLConfig
from irl.demonstrations import Demonstrations
from irl.errors import ConfigError
from irl.result import FitResult


def initial_theta(demos: Demonstrations, config: IRLConfig, rng: np.random.Generator,
                  theta0: np.ndarray | None) -> np.ndarray:
    """``theta0`` (checked to be ``[K]`` finite) or ``rng.uniform(init_low, init_high, K)``.

    Raises:
        ConfigError: ``theta0`` is not ``K`` finite numbers.
    """
    k = demos.n_features
    if theta0 is None:
        return rng.uniform(config.init_low, config.init_high, size=k)
    t = np.asarray(theta0, dtype=np.float64)
    if t.shape != (k,) or not np.all(np.isfinite(t)):
        raise ConfigError(f"theta0 must be {k} finite numbers (one per feature), got shape {t.shape}")
    return t.copy()


def result_from_ascent(method: str, config: IRLConfig, asc: AscentResult, wall_time_s: float, *,
                       unbounded: bool = False, message: str | None = None,
                       extra: dict[str, float] | None = None) -> FitResult:
    """Wrap an :class:`~irl.ascent.AscentResult` as the public :class:`~irl.result.FitResult`."""
    ev = asc.evaluation
    info = dict(asc.extra)
    theta = np.asarray(asc.theta, dtype=np.float64)
    info["objective"] = float(ev.loglik - 0.5 * config.l2 * float(theta @ theta))
    info.update(extra or {})
    return FitResult(
        method=method, theta=theta, loglik=float(ev.loglik), q=np.asarray(ev.q, dtype=np.float64),
        config=config, loglik_trace=np.asarray(asc.loglik_trace, dtype=np.float64),
        theta_trace=np.asarray(asc.theta_trace, dtype=np.float64), converged=bool(asc.converged),
        message=asc.message if message is None else message, wall_time_s=float(wall_time_s),
        unbounded=bool(unbounded), extra={k: float(v) for k, v in info.items()},
    )


def finish_faithful(method: str, config: IRLConfig, asc, solver, start: float) -> FitResult:
    """FitResult of a faithful fit: not converged if the last inner loops hit their cap."""
    msg, converged = asc.message, asc.converged
    if solver.inner_caps:
        msg += f"; {solver.inner_caps} inner loops hit max_inner = {config.max_inner}"
    if not solver.last_ok:
        converged = False
        msg += " (the last outer step's inner iteration did not converge)"
    asc = replace(asc, converged=converged, message=msg)
    return result_from_ascent(method, config, asc, time.perf_counter() - start,
                              extra={"inner_sweeps": solver.sweeps,
                                     "inner_cap_hits": solver.inner_caps})
