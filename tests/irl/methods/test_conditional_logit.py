"""irl/methods/conditional_logit.py: gradient, recovery of known weights, weights, errors; the same
logit over a state table (fit_state_logit)."""

from __future__ import annotations

import numpy as np
import pytest

from irl.errors import ConfigError, DemonstrationError
from irl.methods.conditional_logit import (
    conditional_log_policy,
    conditional_loglik,
    fit_conditional_logit,
    fit_state_logit,
    penalised_nll,
)


def _samples(rng: np.random.Generator, n: int, truth: np.ndarray, n_actions: int = 5):
    F = rng.normal(size=(n, n_actions, truth.size))
    p = np.exp(conditional_log_policy(F, truth))
    a = (p.cumsum(1) > rng.random(n)[:, None]).argmax(1)
    return F, a


def test_gradient_matches_finite_differences():
    rng = np.random.default_rng(0)
    F = rng.normal(size=(40, 5, 3))
    counts = rng.integers(0, 4, (40, 5)).astype(float)
    theta = rng.normal(size=3)
    _, g = penalised_nll(theta, F, counts, 0.7)
    h = 1e-6
    fd = [(penalised_nll(theta + h * e, F, counts, 0.7)[0] - penalised_nll(theta - h * e, F, counts, 0.7)[0]) / (2 * h)
          for e in np.eye(3)]
    np.testing.assert_allclose(g, fd, rtol=1e-6, atol=1e-6)


def test_fit_recovers_the_weights_of_its_own_samples():
    rng = np.random.default_rng(1)
    truth = np.array([1.5, -0.8, 0.3])
    F, a = _samples(rng, 20000, truth)
    fit = fit_conditional_logit(F, a, l2=0.0)
    assert fit.converged and fit.n_steps == 20000
    np.testing.assert_allclose(fit.theta, truth, atol=0.06)
    assert fit.loglik == pytest.approx(conditional_loglik(F, fit.theta, a))
    # the maximum: no nearby weights do better
    for e in np.eye(3):
        assert conditional_loglik(F, fit.theta + 0.05 * e, a) < fit.loglik


def test_a_weight_of_two_equals_a_duplicated_decision_and_fits_are_deterministic():
    rng = np.random.default_rng(2)
    F, a = _samples(rng, 300, np.array([0.7, -1.2]))
    w = np.ones(300)
    w[:50] = 2.0
    weighted = fit_conditional_logit(F, a, l2=0.1, weights=w)
    duplicated = fit_conditional_logit(np.concatenate([F, F[:50]]), np.concatenate([a, a[:50]]), l2=0.1)
    np.testing.assert_allclose(weighted.theta, duplicated.theta, atol=1e-5)
    np.testing.assert_array_equal(fit_conditional_logit(F, a, l2=0.1).theta, fit_conditional_logit(F, a, l2=0.1).theta)


def test_l2_keeps_separable_data_finite():
    F = np.zeros((20, 5, 1))
    F[:, 0, 0] = 1.0  # action 0 always taken and the only one with the feature: separable
    fit = fit_conditional_logit(F, np.zeros(20, dtype=np.int64), l2=1.0)
    assert np.isfinite(fit.theta).all() and 0 < fit.theta[0] < 10


def test_log_policy_rows_normalise():
    rng = np.random.default_rng(3)
    lp = conditional_log_policy(rng.normal(size=(7, 5, 4)) * 50, rng.normal(size=4))
    np.testing.assert_allclose(np.exp(lp).sum(1), 1.0)


@pytest.mark.parametrize("F, a, kwargs, err", [
    (np.zeros((3, 5)), np.zeros(3, dtype=int), {}, ConfigError),
    (np.zeros((0, 5, 2)), np.zeros(0, dtype=int), {}, ConfigError),
    (np.full((3, 5, 2), np.nan), np.zeros(3, dtype=int), {}, ConfigError),
    (np.zeros((3, 5, 2)), np.zeros(4, dtype=int), {}, DemonstrationError),
    (np.zeros((3, 5, 2)), np.array([0, 5, 1]), {}, DemonstrationError),
    (np.zeros((3, 5, 2)), np.array([0.0, 1.0, 1.0]), {}, DemonstrationError),
    (np.zeros((3, 5, 2)), np.zeros(3, dtype=int), {"l2": -1.0}, ConfigError),
    (np.zeros((3, 5, 2)), np.zeros(3, dtype=int), {"weights": np.array([1.0, -1.0, 1.0])}, ConfigError),
])
def test_bad_inputs_raise_named_errors(F, a, kwargs, err):
    with pytest.raises(err):
        fit_conditional_logit(F, a, **kwargs)


def _state_samples(rng: np.random.Generator, truth: np.ndarray, n: int = 20000):
    F = rng.normal(size=(50, 5, truth.size))
    s = rng.integers(0, 50, n)
    p = np.exp(conditional_log_policy(F[s], truth))
    a = (p.cumsum(1) > rng.random(n)[:, None]).argmax(1)
    return F, s, a


def test_fit_state_logit_recovers_the_weights_of_its_own_samples():
    rng = np.random.default_rng(1)
    truth = np.array([1.5, -0.8])
    F, s, a = _state_samples(rng, truth)
    np.testing.assert_allclose(fit_state_logit(F, s, a, l2=0.0), truth, atol=0.08)
    # the same as the per-decision logit on each decision's own rows F[s]
    np.testing.assert_allclose(fit_state_logit(F, s, a, l2=1.0),
                               fit_conditional_logit(F[s], a, l2=1.0).theta, atol=1e-4)
    # a warm start from the answer ends where a cold start does; a penalty far above the 20000 decisions shrinks the weights
    theta = fit_state_logit(F, s, a, l2=0.0)
    np.testing.assert_allclose(fit_state_logit(F, s, a, l2=0.0, x0=theta), theta, atol=1e-4)
    assert np.linalg.norm(fit_state_logit(F, s, a, l2=1e6)) < 0.1 * np.linalg.norm(truth)


def test_fit_state_logit_refuses_malformed_input():
    rng = np.random.default_rng(2)
    F, s, a = _state_samples(rng, np.array([1.0, 0.5]), n=100)
    with pytest.raises(ConfigError, match="l2"):
        fit_state_logit(F, s, a, l2=-1.0)
    with pytest.raises(ConfigError, match="x0"):
        fit_state_logit(F, s, a, l2=0.1, x0=np.zeros(3))
    with pytest.raises(ConfigError, match=r"\[S, A, K\]"):
        fit_state_logit(F[:, :, 0], s, a, l2=0.1)
    with pytest.raises(DemonstrationError, match="one length"):
        fit_state_logit(F, s, a[:-1], l2=0.1)
    with pytest.raises(DemonstrationError, match="lie in"):
        fit_state_logit(F, np.append(s, 50), np.append(a, 0), l2=0.1)
