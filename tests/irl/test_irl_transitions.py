"""Successor models: model-free counts, terminal pairs, estimated transition models."""

import numpy as np
import pytest

from irl.demonstrations import Demonstrations
from irl.errors import DemonstrationError
from irl.transitions import estimate_transitions, model_free_successors, model_successors


def demos():
    # (0,1)->1 three times, (0,1)->2 once, (1,0)->0 twice; (1,1), (2,0) only ever final steps
    states = (np.array([0, 1, 0, 2]), np.array([0, 1]), np.array([1, 0, 1]))
    actions = (np.array([1, 0, 1, 0]), np.array([1, 1]), np.array([0, 1, 1]))
    return Demonstrations(states, actions, np.ones((3, 2, 1)), 3, 2)


def test_model_free_successors_are_relative_counts_with_terminals():
    succ = model_free_successors(demos())
    p = succ.p.toarray().reshape(3, 2, 3)
    np.testing.assert_allclose(p[0, 1], [0, 3 / 4, 1 / 4])
    np.testing.assert_allclose(p[1, 0], [1, 0, 0])
    terminal = succ.terminal.reshape(3, 2)
    # (1,1) only final steps; (2,0) only final; (0,0), (2,1) never seen
    assert terminal.tolist() == [[True, False], [False, True], [True, True]]
    assert np.all(p[terminal] == 0)


def test_estimate_transitions_self_loop_and_fallback():
    t = estimate_transitions(demos()).to_dense()
    np.testing.assert_allclose(t.sum(axis=2), 1.0)
    np.testing.assert_allclose(t[0, 1], [0, 3 / 4, 1 / 4])
    np.testing.assert_allclose(t[2, 1], [0, 0, 1])  # unseen: stays in place
    np.testing.assert_allclose(t[1, 1], [0, 1, 0])  # seen only as a final step: no successor
    fallback = np.full((3, 2, 3), 1 / 3)
    tf = estimate_transitions(demos(), fallback).to_dense()
    np.testing.assert_allclose(tf[2, 1], 1 / 3)
    np.testing.assert_allclose(tf[0, 1], [0, 3 / 4, 1 / 4])  # observed rows keep their counts
    with pytest.raises(DemonstrationError, match="fallback"):
        estimate_transitions(demos(), np.ones((3, 2, 2)))


def test_model_successors_rejects_non_stochastic_rows():
    t = np.full((2, 2, 2), 0.5)
    model_successors(t)
    t[1, 0] = [0.7, 0.7]
    with pytest.raises(DemonstrationError, match=r"T\[1, 0, :\] sums to 1.4"):
        model_successors(t)
    with pytest.raises(DemonstrationError, match="shape"):
        model_successors(np.ones((2, 2, 3)))


def test_jacobian_pattern_builds_the_backup_matrix():
    import scipy.sparse as sp
    from irl_testdata import random_mdp

    from irl.bellman.operators import backup_operator

    for seed in range(3):
        t, d = random_mdp(seed)
        for succ in (model_successors(t), model_free_successors(d)):
            c = np.random.default_rng(seed).normal(size=(d.n_states, d.n_actions))
            built = succ.jacobian_pattern.matrix(c, 0.9).toarray()
            direct = (sp.identity(succ.n_pairs) - backup_operator(succ, c, 0.9)).toarray()
            np.testing.assert_allclose(built, direct, atol=1e-15)


def test_state_system_solves_the_pair_system():
    """The backup system over the pairs, ``(I - gamma P W) x = b``, is solved through the state
    system ``(I - gamma W P) y = W b``, ``x = b + gamma P y``: same solution as a dense solve of
    the pair system, terminal pairs (Q = R) included, for one and for K right-hand sides."""
    from irl_testdata import random_mdp

    from irl.bellman.operators import solve_backup_system, weight_matrix

    for seed in range(3):
        t, d = random_mdp(seed)
        rng = np.random.default_rng(seed)
        for succ in (model_successors(t), model_free_successors(d)):
            c = rng.normal(size=(d.n_states, d.n_actions))
            w, p = weight_matrix(c).toarray(), succ.p.toarray()
            reduced = succ.state_pattern.matrix(c, 0.9).toarray()
            np.testing.assert_allclose(reduced, np.eye(d.n_states) - 0.9 * w @ p, atol=1e-15)
            pair = np.eye(succ.n_pairs) - 0.9 * p @ w
            for rhs in (rng.normal(size=succ.n_pairs), rng.normal(size=(succ.n_pairs, 4))):
                x = solve_backup_system(succ, c, 0.9, rhs)
                assert x.shape == rhs.shape
                np.testing.assert_allclose(x, np.linalg.solve(pair, rhs), rtol=1e-10, atol=1e-10)
            assert succ.state_pattern.matrix(c, 0.9).format == "csc"
