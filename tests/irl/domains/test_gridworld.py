"""The 5x5 gridworld of the paper, laid out as the authors' code does: state ``5 * row + col``,
actions 0 = col-1, 1 = row+1, 2 = col+1, 3 = row-1 (off the grid: stay), features yellow = state 4,
green = 0, red = 20, pink = 24, blue = {1, 8, 11, 18, 21} (:mod:`irl.domains.gridworld`)."""


import numpy as np
import pytest

from irl.domains import gridworld as g


def test_layout_and_moves():
    assert g.move(0, 0) == 0 and g.move(0, 3) == 0  # off the grid: stay
    assert g.move(0, 2) == 1 and g.move(0, 1) == 5
    assert g.move(12, 0) == 11 and g.move(12, 1) == 17 and g.move(12, 2) == 13 and g.move(12, 3) == 7
    assert g.move(24, 1) == 24 and g.move(24, 2) == 24


def test_features():
    phi = g.features()
    assert phi.shape == (25, 4, 5)
    assert np.all(phi == phi[:, :1, :])  # state-only
    expected = {4: 0, 0: 1, 20: 2, 24: 3}
    for s in range(25):
        row = phi[s, 0]
        if s in expected:
            assert row[expected[s]] == 1 and row.sum() == 1
        elif s in (1, 8, 11, 18, 21):
            assert row[4] == 1 and row.sum() == 1
        else:
            assert row.sum() == 0


@pytest.mark.parametrize("noise", [0.0, 0.1, 0.3])
def test_transition_rows_are_distributions(noise):
    t = g.transition_model(noise)
    assert t.shape == (25, 4, 25)
    np.testing.assert_allclose(t.sum(axis=2), 1.0)
    assert np.all(t >= 0)


def test_noise_zero_is_deterministic_and_noise_slips_laterally():
    t0 = g.transition_model(0.0)
    assert np.all(np.isin(t0, (0.0, 1.0)))
    for s in range(25):
        for a in range(4):
            assert t0[s, a, g.move(s, a)] == 1.0
    t = g.transition_model(0.1)
    # centre cell moving right: 0.9 right, 0.05 up, 0.05 down, never left
    assert t[12, 2, 13] == pytest.approx(0.9)
    assert t[12, 2, 7] == pytest.approx(0.05) and t[12, 2, 17] == pytest.approx(0.05)
    assert t[12, 2, 11] == 0.0
    # top-left corner moving down: slip left is off the grid (stay), slip right goes to 1
    assert t[0, 1, 5] == pytest.approx(0.9) and t[0, 1, 0] == pytest.approx(0.05) and t[0, 1, 1] == pytest.approx(0.05)


@pytest.mark.parametrize("noise", [0.0, 0.1])
def test_experts_reach_a_corner_and_avoid_blue(noise):
    rng = np.random.default_rng(7)
    d = g.generate_experts(20, noise, rng)
    dist = g.corner_distances()
    for s, a in zip(d.states, d.actions):
        assert s[-1] in g.CORNERS and a[-1] == g.CORNER_ACTION[int(s[-1])]
        assert not np.any(np.isin(s[:-1], g.CORNERS))
        assert s[0] not in g.BLUE
        if noise == 0.0:
            assert not np.any(np.isin(s, list(g.BLUE)))
            assert len(s) == dist[s[0]] + 1  # shortest path, then the corner step
        for t in range(len(s) - 1):  # the intended action always heads to a corner
            assert a[t] in g.expert_actions(int(s[t]), dist)
    # duplicates removed
    keys = {(tuple(s), tuple(a)) for s, a in zip(d.states, d.actions)}
    assert len(keys) == d.n_trajectories <= 20


def test_experts_are_seeded():
    a = g.generate_experts(10, 0.1, np.random.default_rng(3))
    b = g.generate_experts(10, 0.1, np.random.default_rng(3))
    assert all(np.array_equal(x, y) for x, y in zip(a.states, b.states))


def test_baseline_fixed_length():
    d = g.generate_baseline(15, 5, 0.1, np.random.default_rng(0))
    assert d.n_trajectories == 15 and all(s.size == 5 for s in d.states)
    acts = np.concatenate(d.actions)
    assert set(acts.tolist()) <= {0, 1, 2, 3}


def test_authors_no_noise_experts_follow_our_expert_policy(railusm):
    d = g.load(railusm / "gridworld" / "noise_0.0_expert_trajs")
    dist = g.corner_distances()
    for s, a in zip(d.states, d.actions):
        assert s[-1] in g.CORNERS and a[-1] == g.CORNER_ACTION[int(s[-1])]
        for t in range(len(s) - 1):
            assert a[t] in g.expert_actions(int(s[t]), dist)
            assert g.move(s[t], a[t]) == s[t + 1]
