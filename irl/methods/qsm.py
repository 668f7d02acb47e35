"""Q-SM: model-free maximum-likelihood IRL with the Boltzmann-weighted backup (paper Eq. 15/16).

Same model-free successors and terminal pairs as Q-Avg (:mod:`irl.transitions`), or
``config.unobserved``'s successors (:mod:`irl.unobserved_successors`, exact solver); the backup
bootstraps from ``sum_b pi(b|s') Q(s', b)`` with ``pi = softmax(beta Q)``. Not a
non-expansion: the iteration may fail to converge, and both solvers report it.

* ``exact``: Newton fixed point + implicit gradient + L-BFGS (:mod:`irl.methods.boltzmann_fit`);
  ``converged=False`` with a message when no fixed point is found, or when the one found repels
  the damped iteration of Eq. 15.
* ``faithful``: the authors' in-place damped sweeps (:func:`irl.methods.damped_sweeps.softmax_sweep`), Q first
  to ``max change < inner_tol`` or ``max_inner`` sweeps, then dQ with the gradient term
  ``pi dQ + Q dpi`` (Eq. 16 with ``dpi`` from the current sweep, not the previous outer step, and
  without the reference code's ``z^2`` factor), warm-started, fixed-length outer steps.
  ``converged`` is False when the last outer step's inner loops hit ``max_inner`` or values
  became non-finite.
"""

from __future__ import annotations

import numpy as np

from irl.ascent import Evaluation
from irl.bellman.operators import mean_weights
from irl.config import IRLConfig
from irl.demonstrations import Demonstrations
from irl.methods.boltzmann_fit import fit_exact
from irl.methods.common import fit_faithful, start_model_free
from irl.methods.damped_sweeps import compose_sweep, iterate_affine, softmax_sweep
from irl.methods.faithful import PlannedSweeps
from irl.result import FitResult


class FaithfulQSM(PlannedSweeps):
    """The reference code's Q-SM inner loops (minus the ``z^2`` bug), warm-started."""

    def iterate_q(self, theta: np.ndarray) -> tuple[int, bool]:
        c = self.config
        r_in = self.phi_in @ theta
        r_out = self.phi_out @ theta
        for sweep in range(1, c.max_inner + 1):
            self.x, change = softmax_sweep(self.plan, self.x, r_in, c.beta, c.alpha, c.gamma)
            new_out = (1.0 - c.alpha) * self.x_out + c.alpha * r_out
            change = max(change, float(np.max(np.abs(new_out - self.x_out), initial=0.0)))
            self.x_out = new_out
            if not np.isfinite(change):
                return sweep, False
            if change < c.inner_tol:
                return sweep, True
        return c.max_inner, False

    def evaluate(self, theta: np.ndarray) -> Evaluation:
        c = self.config
        n1, ok_q = self.iterate_q(theta)
        q = self.assemble(self.x, self.x_out)
        if not np.all(np.isfinite(q)):
            self.last_ok = False
            return Evaluation(float("nan"), np.full(theta.shape, np.nan), q, ok=False,
                              message="Q-SM sweep produced non-finite Q values")
        _, _, w = mean_weights(q, c.beta)  # dV(s')/dQ(s', b): the pi dQ + Q dpi weights
        gh = compose_sweep(self.plan, w, c.alpha, c.gamma)
        self.dx, self.dx_out, n2, ok_d = iterate_affine(gh, self.dx, self.phi_in, self.dx_out,
                                                        self.phi_out, c.alpha, c.max_inner,
                                                        c.inner_tol)
        return self.conclude(q, self.assemble(self.dx, self.dx_out), n1 + n2, (ok_q, ok_d))


def fit_qsm(demos: Demonstrations, config: IRLConfig, rng: np.random.Generator, *,
            theta0: np.ndarray | None = None, progress: bool = False,
            fallback_next: np.ndarray | None = None) -> FitResult:
    """Fit Q-SM weights (``config.solver`` ``"exact"`` or ``"faithful"``); see the module doc.

    ``fallback_next``: ``[S, A]`` int next states of a domain model, for
    ``config.unobserved == "kinematic"`` (:mod:`irl.unobserved_successors`).

    Raises:
        ConfigError: ``fallback_next`` missing or given against ``config.unobserved``.
    """
    start, theta, succ = start_model_free(demos, config, rng, theta0, fallback_next)
    if config.solver == "exact":
        return fit_exact("qsm", demos, succ, config, theta, progress, start, from_zero=True)
    return fit_faithful("qsm", FaithfulQSM(demos, config), theta, config, progress, start)
