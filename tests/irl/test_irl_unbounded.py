"""Unbounded likelihoods (field case irl-separable-demos) and Q-SM's branch rule.

The three ``.npz`` inputs are made-up demonstrations (copied from ``shared/cases``): one action
everywhere, a deterministic absorbing loop, single-step trajectories.
"""

from pathlib import Path

import numpy as np
import pytest
from irl_testdata import random_mdp

from analysis.experiments.learn import fit_problem
from irl.bellman.fixed_point import iteration_fixed_point
from irl.boltzmann import demo_counts, log_policy, loglik_from_counts
from irl.config import IRLConfig
from irl.problems import load_problem
from irl.transitions import model_free_successors, model_successors
from irl.unbounded import hardmax_q, is_recession_direction

CASES = Path(__file__).parents[1] / "data" / "cases" / "irl-separable-demos"
METHODS = ("qavg", "qsm", "mlirl")


def _fit(case, method, **cfg):
    return fit_problem(load_problem("npz", CASES / f"{case}.npz"), method, IRLConfig.paper(**cfg), 0)


@pytest.mark.parametrize("beta", [0.01, 1.0])
@pytest.mark.parametrize("method", METHODS)
def test_one_action_everywhere_is_unbounded_for_every_method(method, beta):
    r = _fit("one_action", method, beta=beta)
    assert r.unbounded and "weights unbounded" in r.message
    assert r.loglik > -1e-3  # the supremum 0 is approached
    penalised = _fit("one_action", method, beta=beta, l2=0.1)
    assert not penalised.unbounded and "finite only thanks to l2" in penalised.message


@pytest.mark.parametrize("method", ["qsm", "mlirl"])
def test_absorbing_loop_is_unbounded_for_the_boltzmann_methods(method):
    # with the max backup, actions 1 and 2 tie everywhere once act0 is penalised: L rises to
    # 51 log(1/2) as theta_act0 -> -infinity
    for beta in (0.01, 1.0):
        r = _fit("absorbing", method, beta=beta)
        assert r.unbounded, r.message
        assert r.loglik <= 51 * np.log(0.5) + 1e-9


def test_absorbing_loop_has_a_finite_q_avg_maximiser():
    # Q-Avg averages over next actions, so act0's penalty also lowers the demonstrated action's Q:
    # L has an interior maximum, lower than the Boltzmann methods' supremum
    r = _fit("absorbing", "qavg", beta=1.0)
    assert not r.unbounded and r.converged
    p = load_problem("npz", CASES / "absorbing.npz")
    from irl.methods.qavg import qavg_q

    cfg = IRLConfig.paper(beta=1.0)
    for t0 in (-5.0, -50.0, 5.0):
        q = qavg_q(np.array([t0, r.theta[1]]), p.demos, cfg)
        assert loglik_from_counts(q, 1.0, demo_counts(p.demos)) < r.loglik
    assert r.loglik < 51 * np.log(0.5)


@pytest.mark.parametrize("method", METHODS)
def test_single_step_trajectories_have_a_finite_maximiser(method):
    # no transitions: Q = R, and act0 is chosen in 1 of 5 steps: pi(act0) = 1/5 at the optimum
    r = _fit("single_step", method, beta=1.0)
    assert not r.unbounded and r.converged
    assert r.loglik == pytest.approx(np.log(0.2) + 4 * np.log(0.4), abs=1e-8)
    assert r.theta[0] == pytest.approx(np.log(0.5), abs=1e-5)


def test_hardmax_q_solves_the_max_bellman_equation():
    t, d = random_mdp(4, n_states=7, n_actions=3)
    succ = model_successors(t)
    r = d.features @ np.array([1.0, -0.5, 0.3])
    q = hardmax_q(r, succ, 0.9)
    assert np.allclose(q, r + 0.9 * np.einsum("sat,t->sa", t, q.max(axis=1)), atol=1e-10)
    free = model_free_successors(d)
    q2 = hardmax_q(r, free, 0.9)
    v = q2.max(axis=1)
    expect = r.ravel() + 0.9 * (free.p @ v)
    assert np.allclose(q2.ravel(), expect, atol=1e-10)


def test_recession_direction_needs_a_strict_rise_somewhere():
    t, d = random_mdp(6, n_states=5, n_actions=2)
    succ = model_successors(t)
    counts = demo_counts(d)
    k = d.n_features
    assert not is_recession_direction(np.zeros(k), d.features, succ, counts, 0.9)
    # features that make the demonstrated action strictly best in every demonstrated state
    feats = np.zeros((5, 2, 1))
    s, a, _ = d.flat()
    best = np.zeros(5, dtype=int)
    for state in range(5):
        acts = a[s == state]
        best[state] = acts[0] if acts.size else 0
    feats[np.arange(5), best, 0] = 1.0
    consistent = all(np.all(a[s == st] == best[st]) for st in range(5))
    assert is_recession_direction(np.array([1.0]), feats, succ, counts, 0.9) == consistent
    assert not is_recession_direction(np.array([-1.0]), feats, succ, counts, 0.9)


def test_iteration_fixed_point_is_the_damped_iteration_limit_from_zero():
    _, d = random_mdp(2, n_states=6, n_actions=3)
    succ = model_free_successors(d)
    r = d.features @ np.array([3.0, -2.0, 1.0])
    fp = iteration_fixed_point(r, succ, 1.0, 0.9)
    assert fp.converged
    q = np.zeros(r.size)  # plain damped iteration Q <- (1-a) Q + a T(Q) from zero
    for _ in range(20000):
        v = np.einsum("sa,sa->s", np.exp(log_policy(q.reshape(r.shape), 1.0)), q.reshape(r.shape))
        q = 0.7 * q + 0.3 * (r.ravel() + 0.9 * (succ.p @ v))
    assert np.allclose(fp.q.ravel(), q, atol=1e-8)


def test_qsm_reports_the_fixed_point_from_zero_on_ngsim(railusm):
    """At gamma 0.9 the optimised branch (L -1094.16) is not the fixed point the
    Eq. 15 iteration reaches from Q = 0 (L -1101.45); the fit reports the latter and says so."""
    p = load_problem("merge", railusm / "merge_ngsim")
    cfg = IRLConfig.reference()
    r = fit_problem(p, "qsm", cfg, 0)
    fz = iteration_fixed_point(p.demos.features @ r.theta, model_free_successors(p.demos), cfg.beta, cfg.gamma)
    assert fz.converged
    assert r.loglik == pytest.approx(loglik_from_counts(fz.q, cfg.beta, demo_counts(p.demos)), abs=1e-6)
    assert r.loglik == pytest.approx(-1101.45, abs=0.01)
    assert r.extra["loglik_branch"] == pytest.approx(-1094.16, abs=0.01)
    assert not r.converged and "Eq. 15 iteration reaches from Q = 0" in r.message
