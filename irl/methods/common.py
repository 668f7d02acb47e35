"""Pieces shared by the IRL solvers: theta initialisation, the model-free fits' common start
(:func:`start_model_free`, Q-Avg and Q-SM), the faithful solvers' ascent and assembling a FitResult."""

from __future__ import annotations

import time
from dataclasses import replace
from typing import NamedTuple

import numpy as np

from irl.ascent import AscentResult, feature_spread, scaled_start, unit_step_ascent
from irl.boltzmann import demo_counts
from irl.config import IRLConfig
from irl.demonstrations import Demonstrations
from irl.errors import ConfigError
from irl.result import FitResult
from irl.transitions import SuccessorModel
from irl.unobserved_successors import free_successors


def initial_theta(demos: Demonstrations, config: IRLConfig, rng: np.random.Generator,
                  theta0: np.ndarray | None) -> np.ndarray:
    """``theta0`` (checked to be ``[K]`` finite) or ``rng.uniform(init_low, init_high, K)``, divided
    by each feature's spread where that is outside :data:`irl.ascent.ORDINARY_SPREAD`
    (:func:`irl.ascent.scaled_start`; features in ordinary units: the draw as it is).

    Raises:
        ConfigError: ``theta0`` is not ``K`` finite numbers.
    """
    k = demos.n_features
    if theta0 is None:  # drawn in ordinary units, each at its feature's own scale (irl.ascent.scaled_start)
        return scaled_start(rng.uniform(config.init_low, config.init_high, size=k),
                            feature_spread(demos.features, demo_counts(demos)))
    t = np.asarray(theta0, dtype=np.float64)
    if t.shape != (k,) or not np.all(np.isfinite(t)):
        raise ConfigError(f"theta0 must be {k} finite numbers (one per feature), got shape {t.shape}")
    return t.copy()


class ModelFreeStart(NamedTuple):
    """What a model-free fit (Q-Avg, Q-SM) starts from (:func:`start_model_free`)."""

    #: ``time.perf_counter()`` when the fit started (its wall time is measured from it).
    start: float
    #: ``[K]`` initial weights (:func:`initial_theta`).
    theta: np.ndarray
    #: the model-free successors of the demonstrations under ``config.unobserved``.
    successors: SuccessorModel


def start_model_free(demos: Demonstrations, config: IRLConfig, rng: np.random.Generator,
                     theta0: np.ndarray | None, fallback_next: np.ndarray | None) -> ModelFreeStart:
    """The start of a model-free fit (Q-Avg, Q-SM): the clock, the initial weights
    (:func:`initial_theta`: ``theta0`` checked, else drawn from ``rng``) and the successors
    (:func:`irl.unobserved_successors.free_successors`; ``fallback_next``: ``[S, A]`` int next
    states of a domain model, for ``config.unobserved == "kinematic"``), in that order.

    Raises:
        ConfigError: ``theta0`` is not ``K`` finite numbers; ``fallback_next`` missing or given
            against ``config.unobserved``.
        DemonstrationError: ``fallback_next`` is not ``[S, A]`` valid states.
    """
    start = time.perf_counter()
    theta = initial_theta(demos, config, rng, theta0)
    return ModelFreeStart(start, theta, free_successors(demos, config, fallback_next))


def fit_faithful(method: str, solver, theta: np.ndarray, config: IRLConfig, progress: bool,
                 start: float) -> FitResult:
    """A faithful solver's fit (``config.solver == "faithful"``): fixed-length unit steps of
    ``solver.evaluate`` from ``theta`` (:func:`irl.ascent.unit_step_ascent`), then
    :func:`finish_faithful`."""
    asc = unit_step_ascent(solver.evaluate, theta, config, progress=progress, desc=f"{method} faithful")
    return finish_faithful(method, config, asc, solver, start)


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
