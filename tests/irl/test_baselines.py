"""Baselines (uniform, marginal, markov, bc), leave-one-trajectory-out and the paired test."""

import numpy as np
import pytest
from irl_testdata import random_mdp

from irl.baselines import (
    TABULAR_BASELINES,
    TabularPolicy,
    baseline_leave_one_out,
    fit_baseline,
    leave_one_out,
    paired_test,
)
from irl.demonstrations import Demonstrations
from irl.errors import ConfigError, DemonstrationError
from irl.problems import load_problem


def _tiny() -> Demonstrations:
    # 3 states, 2 actions; actions 0 0 1 | 1 1
    return Demonstrations((np.array([0, 1, 2]), np.array([2, 2])), (np.array([0, 0, 1]), np.array([1, 1])),
                          np.zeros((3, 2, 1)), 3, 2)


def test_hand_computed_probabilities():
    d = _tiny()
    # marginal: n = (2, 3), N = 5 -> (3/7, 4/7)
    m = fit_baseline("marginal", d)
    assert np.allclose(np.exp(m.log_first), [[3 / 7, 4 / 7]] * 3)
    # markov: transitions 0->0, 0->1, 1->1: rows (1+1, 1+1)/4 and (0+1, 1+1)/3; first step marginal
    k = fit_baseline("markov", d)
    assert np.allclose(np.exp(k.log_next), [[0.5, 0.5], [1 / 3, 2 / 3]])
    ll = k.trajectory_logliks(d)
    assert ll[0] == pytest.approx(np.log(3 / 7) + np.log(0.5) + np.log(0.5))
    assert ll[1] == pytest.approx(np.log(4 / 7) + np.log(2 / 3))
    # bc: state 2 saw action 1 three times -> (1, 4)/5; state 0 saw 0 once -> (2, 1)/3
    b = fit_baseline("bc", d)
    assert np.allclose(np.exp(b.log_first[2]), [0.2, 0.8])
    assert np.allclose(np.exp(b.log_first[0]), [2 / 3, 1 / 3])
    u = fit_baseline("uniform", d)
    assert u.loglik(d) == pytest.approx(5 * np.log(0.5))


@pytest.mark.parametrize("name", TABULAR_BASELINES)
def test_every_conditional_is_a_distribution(name):
    _, d = random_mdp(3, n_states=7, n_actions=4)
    pol = fit_baseline(name, d)
    assert np.allclose(np.exp(pol.log_first).sum(axis=1), 1.0)
    for prev in range(4):
        assert np.allclose(np.exp(pol.log_policy(prev)).sum(axis=1), 1.0)
    assert pol.loglik(d) == pytest.approx(pol.trajectory_logliks(d).sum())


def test_unknown_baseline_and_mismatched_space_are_errors():
    d = _tiny()
    with pytest.raises(ConfigError, match="unknown baseline 'foo'"):
        fit_baseline("foo", d)
    other = Demonstrations((np.array([0]),), (np.array([0]),), np.zeros((4, 2, 1)), 4, 2)
    with pytest.raises(DemonstrationError, match="4 states x 2 actions"):
        fit_baseline("bc", d).trajectory_logliks(other)


def test_leave_one_out_fits_each_fold_without_its_trajectory():
    _, d = random_mdp(5, n_traj=4)
    seen = []

    def fit_fold(train):
        seen.append(tuple(train))
        return fit_baseline("bc", d.subset(train))

    folds = leave_one_out(d, fit_fold)
    assert seen == [(1, 2, 3), (0, 2, 3), (0, 1, 3), (0, 1, 2)]
    for i in range(4):
        manual = fit_baseline("bc", d.subset([j for j in range(4) if j != i])).loglik(d.subset([i]))
        assert folds[i] == pytest.approx(manual)
    with pytest.raises(DemonstrationError, match="at least 2"):
        leave_one_out(d.subset([0]), fit_fold)


def test_tabular_policy_scores_a_state_policy():
    d = _tiny()
    lp = np.log(np.array([[0.9, 0.1], [0.5, 0.5], [0.2, 0.8]]))
    assert TabularPolicy("x", lp).trajectory_logliks(d) == pytest.approx(
        [np.log(0.9) + np.log(0.5) + np.log(0.8), 2 * np.log(0.8)])


def test_authors_ngsim_leave_one_out_figures(railusm):
    """The published baseline figures on the authors' 12 trajectories: marginal -1529.8, markov -907.5."""
    d = load_problem("merge", railusm / "merge_ngsim").demos
    totals = {name: float(baseline_leave_one_out(name, d).sum()) for name in TABULAR_BASELINES}
    assert totals["uniform"] == pytest.approx(1197 * np.log(1 / 5))
    assert totals["marginal"] == pytest.approx(-1529.8, abs=0.05)
    assert totals["markov"] == pytest.approx(-907.5, abs=0.05)
    assert totals["markov"] > totals["marginal"] > totals["bc"] > totals["uniform"]


def test_paired_test_on_per_fold_logliks():
    x = np.arange(12.0)
    assert paired_test(x, x) == 1.0
    assert np.isnan(paired_test(x[:1], x[:1] + 1))
    # every held-out trajectory better by a varying margin: exact two-sided p = 2 / 2^12
    assert paired_test(x + 1 + np.arange(12) / 10, x) == pytest.approx(2 / 2 ** 12)
    # mixed signs: no evidence
    assert paired_test(x + np.array([1, -1] * 6) * np.arange(1, 13), x) > 0.5
