"""Q-SM and MLIRL: the Boltzmann fixed point, its multiplicity, and divergence detection."""

import math
import time

import numpy as np
import pytest
import scipy.sparse as sp
from irl_testdata import random_mdp

from irl.bellman.fixed_point import boltzmann_fixed_point
from irl.bellman.operators import mean_weights, weight_matrix
from irl.bellman.stability import _top_real_eigenvalue, iteration_stability
from irl.config import IRLConfig
from irl.demonstrations import Demonstrations
from irl.fit import fit
from irl.methods.mlirl import solve_q
from irl.methods.qsm import FaithfulQSM
from irl.transitions import model_free_successors


def one_step_demos(nxt: np.ndarray) -> Demonstrations:
    """Every pair (s, a) observed once, moving to ``nxt[s, a]``; one-hot features per pair."""
    S, A = nxt.shape
    states = tuple(np.array([s, nxt[s, a]]) for s in range(S) for a in range(A))
    actions = tuple(np.array([a, 0]) for s in range(S) for a in range(A))
    return Demonstrations(states, actions, np.eye(S * A).reshape(S, A, S * A), S, A)


# The paper's iteration (Eq. 15, alpha = 1, in place) cycles with period 2 on this MDP, though
# every pair has a single successor (Q-Avg converges on the same data).
CYCLE_NEXT = np.array([[2, 1], [0, 2], [1, 0]])
CYCLE_THETA = np.array([-1.3338677082123904, 2.5594504112559715, -0.911510120583853,
                        2.05856782736001, -2.72740865355435, 2.3309078967591628])
# Newton from R lands on a fixed point that repels the damped iteration; other ones attract.
REPEL_NEXT = np.array([[2, 0], [0, 0], [0, 2]])
REPEL_THETA = np.array([-2.017835036398486, 1.1377356011343958, -1.5037086576492538,
                        -2.606502380055971, -1.845080625511505, 1.06755805842268])


def boltzmann_residual(q, theta, demos, beta, gamma):
    """max |Q - R - gamma mean_{s'} V(s')| over observed pairs; Q - R elsewhere (test's own code)."""
    r = np.einsum("sak,k->sa", demos.features, theta)
    succ: dict = {}
    for states, actions in zip(demos.states, demos.actions):
        for t in range(len(states) - 1):
            succ.setdefault((int(states[t]), int(actions[t])), []).append(int(states[t + 1]))

    def v(s):
        z = [beta * x for x in q[s]]
        m = max(z)
        w = [math.exp(x - m) for x in z]
        return sum(wi * x for wi, x in zip(w, q[s])) / sum(w)

    res = 0.0
    for s in range(demos.n_states):
        for a in range(demos.n_actions):
            target = r[s, a]
            if (s, a) in succ:
                target += gamma * np.mean([v(s2) for s2 in succ[(s, a)]])
            res = max(res, abs(q[s, a] - target))
    return res


def test_paper_iteration_cycles_and_is_reported_in_bounded_time():
    demos = one_step_demos(CYCLE_NEXT)
    cfg = IRLConfig(beta=1.0, gamma=0.99, alpha=1.0, solver="faithful", max_inner=500, max_outer=3)
    start = time.perf_counter()
    res = fit("qsm", demos, cfg, np.random.default_rng(0), theta0=CYCLE_THETA)
    assert time.perf_counter() - start < 30
    assert not res.converged
    assert "max_inner" in res.message and "did not converge" in res.message
    assert res.extra["inner_cap_hits"] >= 1
    qavg = fit("qavg", demos, IRLConfig(**{**cfg.to_dict(), "max_inner": 5000}),
               np.random.default_rng(0), theta0=CYCLE_THETA)
    assert qavg.extra["inner_cap_hits"] == 0  # the averaging sweep converges on the same data


def test_exact_finds_the_attracting_fixed_point_the_damped_iteration_reaches():
    demos = one_step_demos(CYCLE_NEXT)
    succ = model_free_successors(demos)
    fp = boltzmann_fixed_point(demos.features @ CYCLE_THETA, succ, 1.0, 0.99)
    assert fp.converged
    assert iteration_stability(fp.q, succ, 1.0, 0.99)[0]
    assert boltzmann_residual(fp.q, CYCLE_THETA, demos, 1.0, 0.99) < 1e-9
    damped = FaithfulQSM(demos, IRLConfig(beta=1.0, gamma=0.99, alpha=0.5, solver="faithful",
                                          max_inner=100000, inner_tol=1e-10))
    damped.evaluate(CYCLE_THETA)
    assert damped.last_ok
    np.testing.assert_allclose(np.array(damped.x), fp.q.ravel(), atol=1e-6)


def test_repelling_fixed_points_are_detected_and_avoided():
    demos = one_step_demos(REPEL_NEXT)
    succ = model_free_successors(demos)
    r = demos.features @ REPEL_THETA
    newton_only = boltzmann_fixed_point(r, succ, 1.0, 0.99, attracting=False)
    assert newton_only.converged
    stable, lam = iteration_stability(newton_only.q, succ, 1.0, 0.99)
    assert stable is False and lam > 1.0
    preferred = boltzmann_fixed_point(r, succ, 1.0, 0.99)
    assert preferred.converged and iteration_stability(preferred.q, succ, 1.0, 0.99)[0]
    assert np.max(np.abs(preferred.q - newton_only.q)) > 1e-3  # a different fixed point
    for q in (newton_only.q, preferred.q):
        assert boltzmann_residual(q, REPEL_THETA, demos, 1.0, 0.99) < 1e-9


def test_exact_reports_an_inner_failure_under_a_tight_cap():
    demos = one_step_demos(REPEL_NEXT)
    cfg = IRLConfig(beta=1.0, gamma=0.99, max_inner=5, max_outer=50)
    start = time.perf_counter()
    res = fit("qsm", demos, cfg, np.random.default_rng(0), theta0=REPEL_THETA)
    assert time.perf_counter() - start < 30
    assert not res.converged
    assert "fixed point" in res.message


@pytest.mark.parametrize("seed", [0, 1])
def test_qsm_q_is_a_fixed_point_and_loglik_is_direct_sum(seed):
    _, demos = random_mdp(seed)
    cfg = IRLConfig(beta=0.5, gamma=0.9, max_outer=50)
    res = fit("qsm", demos, cfg, np.random.default_rng(seed))
    assert boltzmann_residual(res.q, res.theta, demos, cfg.beta, cfg.gamma) < 1e-9
    direct = 0.0
    for states, actions in zip(demos.states, demos.actions):
        for s, a in zip(states, actions):
            z = cfg.beta * res.q[s]
            direct += z[a] - z.max() - math.log(np.exp(z - z.max()).sum())
    assert res.loglik == pytest.approx(direct, rel=1e-12)


def test_mlirl_solve_q_satisfies_the_bellman_equation():
    t, demos = random_mdp(3)
    cfg = IRLConfig(beta=0.5, gamma=0.9)
    theta = np.array([1.0, -0.5, 0.25])
    q = solve_q(theta, demos.features, t, cfg)
    r = demos.features @ theta
    pi = np.exp(cfg.beta * q - cfg.beta * q.max(axis=1, keepdims=True))
    pi /= pi.sum(axis=1, keepdims=True)
    v = (pi * q).sum(axis=1)
    np.testing.assert_allclose(q, r + cfg.gamma * t @ v, atol=1e-9)
    res = fit("mlirl", demos, IRLConfig(beta=0.5, gamma=0.9, max_outer=100),
              np.random.default_rng(0), transitions=t)
    np.testing.assert_allclose(res.q, solve_q(res.theta, demos.features, t, cfg), atol=1e-8)


def test_stability_eigenvalue_equals_the_dense_one():
    """The stability check takes the largest real part of the eigenvalues of ``gamma J P`` block
    by block (strongly connected components); it equals the dense eigenvalue problem's."""
    for seed in range(4):
        t, d = random_mdp(seed, n_states=12, n_actions=3, single_successor=True)
        succ = model_free_successors(d)
        q = np.random.default_rng(seed).normal(scale=3.0, size=(d.n_states, d.n_actions))
        stable, lam = iteration_stability(q, succ, 1.0, 0.99)
        _, _, c = mean_weights(q, 1.0)
        used = np.unique(succ.p.indices)
        jp = sp.csr_matrix(weight_matrix(c) @ succ.p)[used][:, used].toarray()
        bound = 0.99 * np.max(np.abs(jp).sum(axis=1))
        expected = bound if bound < 1.0 else float(np.max(np.linalg.eigvals(0.99 * jp).real))
        assert lam == pytest.approx(expected, abs=1e-12)
        assert stable == (expected < 1.0)
    rng = np.random.default_rng(7)
    for _ in range(5):  # block-triangular matrices with several strongly connected blocks
        m = sp.random(40, 40, density=0.06, random_state=rng) * 3.0
        top = _top_real_eigenvalue(sp.csr_matrix(m), 2000)
        assert top == pytest.approx(float(np.max(np.linalg.eigvals(m.toarray()).real)), abs=1e-10)
        assert _top_real_eigenvalue(sp.csr_matrix(m + sp.eye(40, k=1) + sp.eye(40, k=-1)), 10) is None
