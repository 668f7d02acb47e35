"""Analytic dL/dtheta of Q-Avg, Q-SM and MLIRL against central finite differences.

Both solvers, on small random MDPs (several seeds). The faithful solvers are evaluated at their
converged inner fixed point (tight inner tolerance, generous cap, no warm start). Faithful Q-SM
uses single-successor data, where the in-place sweep's fixed point is the Boltzmann fixed point
(with several successors per pair the in-place sweep's fixed point depends on alpha and order).
"""

import numpy as np
import pytest
from irl_testdata import random_mdp

from irl.boltzmann import demo_counts, loglik_grad_from_counts
from irl.config import IRLConfig
from irl.methods.boltzmann_fit import DampedBoltzmann, ExactBoltzmann
from irl.methods.qavg import FaithfulQAvg, qavg_basis
from irl.methods.qsm import FaithfulQSM
from irl.transitions import model_free_successors, model_successors

EXACT = IRLConfig(beta=0.5, gamma=0.9)
FAITHFUL = IRLConfig(beta=0.5, gamma=0.9, alpha=0.5, solver="faithful", inner_tol=1e-13,
                     max_inner=200000)


def evaluator(method: str, solver: str, demos, t):
    """A fresh-state ``theta -> (L, grad)`` for one method and solver."""
    if solver == "exact":
        if method == "qavg":
            basis, counts = qavg_basis(demos, EXACT.gamma), demo_counts(demos)
            return lambda th: loglik_grad_from_counts(basis @ th, basis, EXACT.beta, counts)
        succ = model_free_successors(demos) if method == "qsm" else model_successors(t)
        ev = ExactBoltzmann(demos, succ, EXACT)
        return lambda th: (lambda e: (e.loglik, e.grad))(ev.evaluate(th))
    cls = {"qavg": FaithfulQAvg, "qsm": FaithfulQSM}.get(method)

    def run(th):
        inner = cls(demos, FAITHFUL) if cls else DampedBoltzmann(demos, model_successors(t), FAITHFUL)
        e = inner.evaluate(th)
        assert inner.inner_caps == 0, "inner loop did not converge; raise max_inner"
        return e.loglik, e.grad

    return run


def central_difference(f, theta, h=1e-4):
    g = np.zeros_like(theta)
    for k in range(theta.size):
        e = np.zeros_like(theta)
        e[k] = h
        g[k] = (f(theta + e)[0] - f(theta - e)[0]) / (2 * h)
    return g


@pytest.mark.parametrize("method", ["qavg", "qsm", "mlirl"])
@pytest.mark.parametrize("solver", ["exact", "faithful"])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_gradient_matches_finite_differences(method, solver, seed):
    single = solver == "faithful" and method == "qsm"
    t, demos = random_mdp(seed, single_successor=single)
    f = evaluator(method, solver, demos, t)
    theta = np.random.default_rng(100 + seed).uniform(-1, 1, demos.n_features)
    ll, grad = f(theta)
    assert np.isfinite(ll) and ll < 0
    fd = central_difference(f, theta)
    scale = max(1.0, float(np.max(np.abs(fd))))
    np.testing.assert_allclose(grad, fd, atol=2e-6 * scale, rtol=0)
    assert np.max(np.abs(grad)) > 1e-3  # a non-trivial gradient was checked
