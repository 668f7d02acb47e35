"""Sparse transition models: the same numbers as the dense [S, A, S] arrays they replace.

The reference here is the dense construction the project used before (relative counts in an
[S, A, S] array, fallback rows copied in: ``irl.dense_transitions.dense_estimate``, which
``benchmarks/sparse_model_bench.py`` times; cumulative sums over full rows for sampling, written
out here), so that the sparse code is checked against an independent computation.
"""

import numpy as np
import pytest
import scipy.sparse as sp
from irl_testdata import gridworld_demos, random_mdp

from irl.config import IRLConfig
from irl.demonstrations import Demonstrations
from irl.dense_transitions import dense_estimate
from irl.domains import gridworld
from irl.domains.merge import mdp as merge_mdp
from irl.domains.merge.actions import N_ACTIONS
from irl.domains.merge.bins import MergeBins
from irl.domains.merge.features import feature_set, features
from irl.domains.merge.states import N_STATES
from irl.errors import ConfigError, DemonstrationError
from irl.fit import fit
from irl.methods.reirl import uniform_baseline
from irl.transitions import SuccessorModel, estimate_transitions, model_successors


def dense_baseline(demos: Demonstrations, t: np.ndarray, n: int, length: int, rng: np.random.Generator):
    """The former dense sampler of uniform-random baseline trajectories."""
    starts = np.array([s[0] for s in demos.states])
    cum = np.cumsum(t, axis=2)
    out = []
    for _ in range(n):
        s = int(rng.choice(starts))
        ss = np.empty(length, dtype=np.int64)
        aa = rng.integers(demos.n_actions, size=length)
        for k in range(length):
            ss[k] = s
            row = cum[s, aa[k]]
            s = int(min(np.searchsorted(row, rng.random() * row[-1], side="right"), demos.n_states - 1))
        out.append((ss, aa))
    return out


def merge_demos(seed: int, encoding: str = "paper", n_traj: int = 12, length: int = 40) -> Demonstrations:
    """Synthetic merge demonstrations: kinematic moves at 0.3 s, one in four steps to a random state
    of a small pool (so that observed pairs have several successors), random actions."""
    rng = np.random.default_rng(seed)
    bins = MergeBins.assumed_authors()
    pool = rng.integers(N_STATES, size=30)
    states, actions = [], []
    for _ in range(n_traj):
        s, ss, aa = int(rng.choice(pool)), [], []
        for _ in range(length):
            a = int(rng.integers(N_ACTIONS))
            ss.append(s)
            aa.append(a)
            nxt = int(merge_mdp.kinematic_next_state(np.array([s]), np.array([a]), bins, 0.3)[0])
            s = nxt if rng.random() < 0.75 else int(rng.choice(pool))
        states.append(np.array(ss))
        actions.append(np.array(aa))
    demos = Demonstrations(tuple(states), tuple(actions), features(), N_STATES, N_ACTIONS, source="synthetic")
    if encoding == "driver":
        demos = merge_mdp.driver_encoded(demos, feature_set("driver", bins, "driver", decision_step_s=0.3).array)
    return demos


def test_the_dense_reference_counts_loops_unseen_pairs_and_refuses_a_misshapen_fallback():
    _, d = random_mdp(0, n_states=7)
    t = dense_estimate(d, None)
    assert t.shape == (7, d.n_actions, 7)
    np.testing.assert_allclose(t.sum(axis=2), 1.0)
    s, a, s2 = d.transitions()
    seen = np.zeros((7, d.n_actions), dtype=bool)
    seen[s, a] = True
    ss, aa = np.nonzero(~seen)
    assert len(ss) > 0 and np.all(t[ss, aa, ss] == 1.0)  # unseen pairs: self-loops
    i = 0
    mask = (s == s[i]) & (a == a[i])
    assert t[s[i], a[i], s2[i]] == pytest.approx(np.mean(s2[mask] == s2[i]))  # a relative count
    with pytest.raises(ConfigError, match=r"\[S, A, S\]"):
        dense_estimate(d, np.ones((7, d.n_actions, 6)))


def test_estimated_models_equal_the_dense_construction():
    bins = MergeBins.assumed_authors()
    for seed in range(3):
        t, d = random_mdp(seed, n_states=7)
        np.testing.assert_array_equal(estimate_transitions(d).to_dense(), dense_estimate(d, None))
        np.testing.assert_array_equal(estimate_transitions(d, t).to_dense(), dense_estimate(d, t))
        np.testing.assert_array_equal(estimate_transitions(d, sp.csr_matrix(t.reshape(-1, 7)))
                                      .to_dense(), dense_estimate(d, t))
    d = merge_demos(0)
    kin = merge_mdp.kinematic_model(bins, 0.3)
    assert isinstance(kin, SuccessorModel) and kin.p.nnz == N_STATES * N_ACTIONS
    est = merge_mdp.estimated_transitions(d, bins, 0.3)
    np.testing.assert_array_equal(est.to_dense(), dense_estimate(d, kin.to_dense()))
    assert est.p.has_sorted_indices and np.all(est.p.data > 0)


def test_driver_model_rows_follow_the_counts_and_the_kinematic_rule():
    # 6250 states: compared row by row (the dense array would be 1.5 GB)
    bins = MergeBins.assumed_authors()
    d = merge_demos(1, "driver")
    est = merge_mdp.estimated_transitions(d, bins, 0.3)
    assert (est.n_states, est.n_actions) == (6250, 5) and est.p.nnz < 40_000
    np.testing.assert_allclose(np.asarray(est.p.sum(axis=1)).ravel(), 1.0, atol=1e-12)
    s, a, s2 = d.transitions()
    counts = {}
    for x, y, z in zip(s.tolist(), a.tolist(), s2.tolist()):
        counts.setdefault((x, y), []).append(z)
    for (x, y), succ in list(counts.items())[:50]:
        row = est.p[x * 5 + y].toarray().ravel()
        want = np.bincount(succ, minlength=6250) / len(succ)
        np.testing.assert_array_equal(row, want)
    unseen = [i for i in range(0, 31250, 997) if (i // 5, i % 5) not in counts]
    nxt = merge_mdp.kinematic_next_state(np.array(unseen) // 5, np.array(unseen) % 5, bins, 0.3, encoding="driver")
    for i, n in zip(unseen, nxt):
        assert est.p[i].nonzero()[1].tolist() == [n]


@pytest.mark.parametrize("where", ["gridworld 0.0", "gridworld 0.1", "merge paper"])
def test_mlirl_dense_and_sparse_models_give_the_same_fit(where):
    if where.startswith("gridworld"):
        noise = where.split()[1]
        demos, t_dense = gridworld_demos(noise), gridworld.transition_model(float(noise))
        t_sparse = model_successors(t_dense)
        config = IRLConfig(beta=1.0, gamma=0.9, max_outer=60)
    else:
        demos = merge_demos(2)
        t_sparse = merge_mdp.estimated_transitions(demos, MergeBins.assumed_authors(), 0.3)
        t_dense = dense_estimate(demos, merge_mdp.kinematic_model(MergeBins.assumed_authors(), 0.3).to_dense())
        config = IRLConfig(beta=1.0, gamma=0.99, max_outer=60)
    a = fit("mlirl", demos, config, np.random.default_rng(5), transitions=t_dense)
    b = fit("mlirl", demos, config, np.random.default_rng(5), transitions=t_sparse)
    c = fit("mlirl", demos, config, np.random.default_rng(5), transitions=t_sparse.p, )
    assert a.converged and b.converged
    for other in (b, c):
        np.testing.assert_allclose(other.theta, a.theta, rtol=0, atol=1e-10)
        np.testing.assert_allclose(other.q, a.q, rtol=0, atol=1e-10)
        assert abs(other.loglik - a.loglik) < 1e-10
    assert a.loglik > demos.n_steps * np.log(1.0 / demos.n_actions)  # learned something


@pytest.mark.parametrize("where", ["gridworld 0.1", "merge paper"])
def test_reirl_dense_and_sparse_models_give_the_same_fit(where):
    if where.startswith("gridworld"):
        demos = gridworld_demos("0.1")
        t_dense = gridworld.transition_model(0.1)
        t_sparse = model_successors(t_dense)
    else:
        demos = merge_demos(3)
        bins = MergeBins.assumed_authors()
        t_sparse = merge_mdp.estimated_transitions(demos, bins, 0.3)
        t_dense = t_sparse.to_dense()
    config = IRLConfig(beta=1.0, gamma=0.9)
    a = fit("reirl", demos, config, np.random.default_rng(7), transitions=t_dense, epsilon=0.01)
    b = fit("reirl", demos, config, np.random.default_rng(7), transitions=t_sparse, epsilon=0.01)
    np.testing.assert_allclose(b.theta, a.theta, rtol=0, atol=1e-10)
    np.testing.assert_allclose(b.q, a.q, rtol=0, atol=1e-10)
    assert abs(b.loglik - a.loglik) < 1e-10 and np.any(a.theta != 0)


def test_uniform_baseline_samples_as_the_dense_sampler():
    for seed in range(3):
        t, d = random_mdp(seed, n_states=9)
        want = dense_baseline(d, t, 20, 15, np.random.default_rng(seed))
        for model in (t, model_successors(t)):
            got = uniform_baseline(d, model, 20, 15, np.random.default_rng(seed))
            for (ws, wa), gs, ga in zip(want, got.states, got.actions):
                np.testing.assert_array_equal(gs, ws)
                np.testing.assert_array_equal(ga, wa)


def test_mlirl_fits_on_the_driver_encoding():
    demos = merge_demos(4, "driver", n_traj=6, length=25)
    bins = MergeBins.assumed_authors()
    model = merge_mdp.estimated_transitions(demos, bins, 0.3)
    res = fit("mlirl", demos, IRLConfig(beta=1.0, gamma=0.9, max_outer=40, l2=0.1), np.random.default_rng(0),
              transitions=model)
    assert res.q.shape == (6250, 5) and np.all(np.isfinite(res.q))
    assert res.loglik > demos.n_steps * np.log(1.0 / 5) + 5  # beats uniform
    # the Bellman equation holds on every state, not only the reachable ones
    r = demos.features @ res.theta
    z = res.q - res.q.max(axis=1, keepdims=True)
    pi = np.exp(z) / np.exp(z).sum(axis=1, keepdims=True)
    v = (pi * res.q).sum(axis=1)
    np.testing.assert_allclose(res.q.ravel(), r.ravel() + 0.9 * (model.p @ v), atol=1e-8)


def test_bad_models_are_named():
    t, d = random_mdp(0)
    bad = t.copy()
    bad[2, 1, 0] += 0.5
    with pytest.raises(DemonstrationError, match=r"T\[2, 1, :\] sums to"):
        model_successors(sp.csr_matrix(bad.reshape(-1, t.shape[0])), n_actions=3)
    with pytest.raises(DemonstrationError, match="needs n_actions"):
        model_successors(sp.csr_matrix(t.reshape(-1, t.shape[0])))
    from irl.transitions import model_free_successors

    with pytest.raises(DemonstrationError, match="no terminal pairs"):
        model_successors(model_free_successors(d))
    with pytest.raises(ConfigError, match=r"sparse: \[S\*A, S\]"):
        fit("mlirl", d, IRLConfig(), np.random.default_rng(0), transitions=sp.csr_matrix(t.reshape(-1, 6))[:12])


def test_mlirl_on_the_authors_merge_data_dense_equals_sparse(railusm):
    from irl.problems import load_problem

    p = load_problem("merge", railusm / "merge_ngsim")
    assert p.bins is not None
    dense = dense_estimate(p.demos, merge_mdp.kinematic_model(p.bins, p.decision_step_s).to_dense())
    np.testing.assert_array_equal(p.transitions.to_dense(), dense)
    config = IRLConfig.paper(beta=1.0, gamma=0.99, l2=0.01)
    a = fit("mlirl", p.demos, config, np.random.default_rng(0), transitions=dense)
    b = fit("mlirl", p.demos, config, np.random.default_rng(0), transitions=p.transitions)
    assert a.converged and abs(a.loglik - b.loglik) < 1e-10
    np.testing.assert_allclose(b.theta, a.theta, rtol=0, atol=1e-10)
