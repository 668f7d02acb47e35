"""MLIRL (Babes-Vroman et al. 2011; paper Eq. 7): maximum likelihood with a transition model.

``Q = R + gamma T (sum_b pi(b|s') Q(s', b))`` over every (s, a) with a full row-stochastic
``T [S, A, S]``: the true model (gridworld), or :func:`irl.transitions.estimate_transitions`
with a domain-supplied fallback for unseen pairs (merge). ``T`` may be dense ``[S, A, S]``, a
sparse ``[S*A, S]`` matrix or a :class:`~irl.transitions.SuccessorModel`
(:data:`~irl.transitions.TransitionModel`); every form becomes the same sparse successor model,
so the fit is one code path and a dense and a sparse ``T`` give the same numbers. The fixed-point
code is shared with Q-SM (:mod:`irl.methods.boltzmann_fit`); only the successor model differs (no
terminal pairs).

* ``exact``: Newton fixed point, implicit gradient, L-BFGS.
* ``faithful``: the damped synchronous Boltzmann backup ``Q <- (1-alpha) Q + alpha (R + gamma T V(Q))``
  (and its dQ) over all pairs, to ``inner_tol`` or ``max_inner`` sweeps, warm-started, with the
  fixed-length unit-gradient outer steps of the other faithful solvers.
"""

from __future__ import annotations

import time

import numpy as np

from irl.ascent import unit_step_ascent
from irl.bellman.fixed_point import boltzmann_fixed_point
from irl.config import IRLConfig
from irl.demonstrations import Demonstrations
from irl.errors import ConfigError, ConvergenceError
from irl.methods.boltzmann_fit import DampedBoltzmann, fit_exact
from irl.methods.common import finish_faithful, initial_theta
from irl.result import FitResult
from irl.transitions import TransitionModel, checked_model, model_successors


def solve_q(theta: np.ndarray, features: np.ndarray, transitions: TransitionModel,
            config: IRLConfig) -> np.ndarray:
    """``[S, A]`` Q of the Boltzmann backup under ``transitions [S, A, S]`` (any
    :data:`~irl.transitions.TransitionModel` form) for ``R = features @ theta``.

    ``features`` is ``[S, A, K]``.

    Raises:
        ConvergenceError: the Boltzmann fixed point was not reached.
        DemonstrationError: ``transitions`` is not a row-stochastic model.
    """
    features = np.asarray(features, dtype=np.float64)
    succ = model_successors(transitions, n_actions=features.shape[1])
    r = features @ np.asarray(theta, dtype=np.float64)
    fp = boltzmann_fixed_point(r, succ, config.beta, config.gamma)
    if not fp.converged:
        raise ConvergenceError(f"MLIRL Boltzmann fixed point: {fp.message}")
    return fp.q


def fit_mlirl(demos: Demonstrations, config: IRLConfig, rng: np.random.Generator, *,
              theta0: np.ndarray | None = None, progress: bool = False,
              transitions: TransitionModel | None = None) -> FitResult:
    """Fit MLIRL weights under ``transitions [S, A, S]`` (required; dense, sparse ``[S*A, S]`` or a
    :class:`~irl.transitions.SuccessorModel`); see the module doc.

    Raises:
        ConfigError: no ``transitions``, or ``transitions`` not of shape ``[S, A, S]`` for these
            demonstrations.
        DemonstrationError: ``transitions`` is not row-stochastic.
        ConvergenceError: the inner fixed point fails.
    """
    start = time.perf_counter()
    if transitions is None:
        raise ConfigError("MLIRL needs a transition model: pass transitions [S, A, S] "
                          "(the true one, or irl.transitions.estimate_transitions(demos, fallback))")
    succ = checked_model(transitions, demos)
    theta = initial_theta(demos, config, rng, theta0)
    if config.solver == "exact":
        return fit_exact("mlirl", demos, succ, config, theta, progress, start)
    solver = DampedBoltzmann(demos, succ, config)
    asc = unit_step_ascent(solver.evaluate, theta, config, progress=progress, desc="mlirl faithful")
    return finish_faithful("mlirl", config, asc, solver, start)
