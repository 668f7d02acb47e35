"""Numerical hostility for the IRL methods (``irl.fit.fit``): huge or tiny beta, theta0 up to
1e4, identical trajectories, single-step trajectories, states never visited, huge features.
Every fit ends with finite theta, Q and log-likelihood, or raises an ``IRLError``."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from irl.config import IRLConfig
from irl.demonstrations import Demonstrations
from irl.errors import IRLError
from irl.fit import fit
from irl.result import FitResult

pytestmark = pytest.mark.hostile

S, A, K = 6, 3, 3
SETTINGS = settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def _problem(seed: int, kind: str, feature_scale: float):
    """Transitions ``[S, A, S]`` and demonstrations of one hostile ``kind``."""
    rng = np.random.default_rng(seed)
    t = rng.dirichlet(np.full(S, 0.5), size=(S, A))
    phi = rng.normal(size=(S, A, K)) * feature_scale
    if kind == "identical":  # the same trajectory five times
        s = rng.integers(0, S, 6)
        a = rng.integers(0, A, 6)
        states, actions = [s] * 5, [a] * 5
    elif kind == "single-step":  # every trajectory one step long: no observed transition
        states = [rng.integers(0, S, 1) for _ in range(4)]
        actions = [rng.integers(0, A, 1) for _ in range(4)]
    elif kind == "unvisited":  # only states 0 and 1 ever visited, one action
        states = [np.array([0, 1, 0, 1, 0]), np.array([1, 0, 1])]
        actions = [np.zeros(5, int), np.zeros(3, int)]
    elif kind == "one-state":  # a single (state, action) repeated
        states, actions = [np.zeros(7, int)], [np.ones(7, int)]
    else:  # ordinary random demonstrations
        states = [rng.integers(0, S, 5) for _ in range(4)]
        actions = [rng.integers(0, A, 5) for _ in range(4)]
    demos = Demonstrations(tuple(states), tuple(actions), phi, S, A, source=f"hostile {kind}")
    return t, demos


def _check_fit(method, demos, config, t, theta0, seed):
    try:
        res = fit(method, demos, config, np.random.default_rng(seed), transitions=t, theta0=theta0)
    except IRLError as e:
        assert str(e)
        return None
    assert isinstance(res, FitResult)
    assert res.theta.shape == (K,) and np.all(np.isfinite(res.theta)), res.theta
    assert res.q.shape == (S, A) and np.all(np.isfinite(res.q)), "non-finite Q"
    if not res.converged and res.message.startswith("inner fixed point failed"):
        # no fixed point at theta0 (lbfgs_ascent): reported, not converged, no likelihood to give
        assert res.theta.shape == (K,) and res.extra["outer_steps"] >= 1
        return res
    assert math.isfinite(res.loglik), (res.loglik, res.message)
    assert res.loglik <= 1e-9  # a log-likelihood of discrete choices
    lp = res.log_policy()
    assert np.all(np.isfinite(lp)) and np.allclose(np.exp(lp).sum(axis=1), 1.0)
    return res


methods = st.sampled_from(["qavg", "qsm", "mlirl", "reirl"])
kinds = st.sampled_from(["identical", "single-step", "unvisited", "one-state", "random"])
betas = st.sampled_from([1e-12, 1e-6, 0.01, 1.0, 50.0, 1e4, 1e8])
theta_scales = st.sampled_from([0.0, 1.0, 100.0, 1e4])


@SETTINGS
@given(methods, kinds, betas, theta_scales, st.sampled_from([1e-8, 1.0, 1e4]), st.integers(0, 3))
@example("qsm", "identical", 1e-6, 100.0, 1e4, 1)  # no fixed point at theta0: reported
def test_exact_solver(method, kind, beta, theta_scale, feature_scale, seed):
    t, demos = _problem(seed, kind, feature_scale)
    config = IRLConfig(beta=beta, gamma=0.9, max_outer=60, max_inner=300)
    theta0 = np.random.default_rng(seed).uniform(-1, 1, K) * theta_scale
    _check_fit(method, demos, config, t, theta0, seed)


@SETTINGS
@given(methods, kinds, betas, theta_scales, st.integers(0, 3))
def test_faithful_solver(method, kind, beta, theta_scale, seed):
    t, demos = _problem(seed, kind, 1.0)
    config = IRLConfig(beta=beta, gamma=0.9, alpha=0.1, solver="faithful", max_outer=30, max_inner=200)
    theta0 = np.random.default_rng(seed).uniform(-1, 1, K) * theta_scale
    _check_fit(method, demos, config, t, theta0, seed)


@pytest.mark.parametrize("method", ["qavg", "qsm", "mlirl", "reirl"])
def test_nonfinite_theta0_is_a_clear_error(method):
    t, demos = _problem(0, "random", 1.0)
    for bad in (np.array([np.nan, 0.0, 0.0]), np.array([np.inf, 1.0, 1.0]), np.zeros(K + 1)):
        if method == "reirl":  # REIRL solves a convex dual and does not use theta0: a finite result
            _check_fit(method, demos, IRLConfig(max_outer=5), t, bad, 0)
            continue
        with pytest.raises(IRLError, match="theta0"):
            fit(method, demos, IRLConfig(max_outer=5), np.random.default_rng(0), transitions=t, theta0=bad)


def test_extreme_configs_are_rejected_up_front():
    for kw in ({"beta": 0.0}, {"beta": float("inf")}, {"beta": float("nan")}, {"gamma": 1.0},
               {"gamma": float("nan")}, {"alpha": 0.0}, {"max_outer": 0}, {"tol": float("nan")}):
        with pytest.raises(IRLError):
            IRLConfig(**kw)

