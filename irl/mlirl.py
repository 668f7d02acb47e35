"""MLIRL (Babes-Vroman et al. 2011; paper Eq. 7): maximum likelihood with a transition model.

``Q = R + gamma T (sum_b pi(b|s') Q(s', b))`` over every (s, a) with a full row-stochastic
``T [S, A, S]``: the true model (gridworld), or :func:`irl.transitions.estimate_transitions`
with a domain-supplied fallback for unseen pairs (merge). The fixed-point code is shared with
Q-SM (:mod:`irl.boltzmann_fit`); only the successor model differs (no terminal pairs).

* ``exact``: Newton fixed point, implicit gradient, L-BFGS.
* ``faithful``: the damped synchronous Boltzmann backup ``Q <- (1-alpha) Q + alpha (R + gamma T V(Q))``
  (and its dQ) over all pairs, to ``inner_tol`` or ``max_inner`` sweeps, warm-started, with the
  fixed-length unit-gradient outer steps of the other faithful solvers.
"""

from __future__ import annotations

import time

import numpy as np

from irl.ascent import unit_step_ascent
from irl.bellman import boltzmann_fixed_point
from irl.boltzmann_fit import DampedBoltzmann, fit_exact
from irl.config import IRLConfig
from irl.demonstrations import Demonstrations
from irl.errors import ConfigError, ConvergenceError
from irl.fit_common import finish_faithful, initial_theta
from irl.result import FitResult
from irl.transitions import model_successors


def solve_q(theta: np.ndarray, features: np.ndarray, transitions: np.ndarray,
            config: IRLConfig) -> np.ndarray:
    """``[S, A]`` Q of the Boltzmann backup under ``transitions [S, A, S]`` for ``R = features @ theta``.

    ``features`` is ``[S, A, K]``. Raises :class:`~irl.errors.ConvergenceError` when the fixed
    point cannot be found.

    Raises:
        ConvergenceError: the Boltzmann fixed point was not reached.
    """
    succ = model_successors(transitions)
    r = np.asarray(features, dtype=np.float64) @ np.asarray(theta, dtype=np.float64)
    fp = boltzmann_fixed_point(r, succ, config.beta, config.gamma)
    if not fp.converged:
        raise ConvergenceError(f"MLIRL Boltzmann fixed point: {fp.message}")
    return fp.q


def fit_mlirl(demos: Demonstrations, config: IRLConfig, rng: np.random.Generator, *,
              theta0: np.ndarray | None = None, progress: bool = False,
              transitions: np.ndarray | None = None) -> FitResult:
    """Fit MLIRL weights under ``transitions [S, A, S]`` (required); see the module doc.

    Raises:
        ConfigError: no ``transitions``, or ``transitions`` not of shape ``[S, A, S]``.
        ConvergenceError: the inner fixed point fails.
    """
    start = time.perf_counter()
    if transitions is None:
        raise ConfigError("MLIRL needs a transition model: pass transitions [S, A, S] "
                          "(the true one, or irl.transitions.estimate_transitions(demos, fallback))")
    t = np.asarray(transitions, dtype=np.float64)
    if t.shape != (demos.n_states, demos.n_actions, demos.n_states):
        raise ConfigError(f"transitions must have shape {(demos.n_states, demos.n_actions, demos.n_states)}"
                          f" for these demonstrations, got {t.shape}")
    succ = model_successors(t)
    theta = initial_theta(demos, config, rng, theta0)
    if config.solver == "exact":
        return fit_exact("mlirl", demos, succ, config, theta, progress, start)
    solver = DampedBoltzmann(demos, succ, config)
    asc = unit_step_ascent(solver.evaluate, theta, config, progress=progress, desc="mlirl faithful")
    return finish_faithful("mlirl", config, asc, solver, start)
