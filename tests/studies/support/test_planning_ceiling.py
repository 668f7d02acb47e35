"""Reference scores of the planning driver's held-out likelihood (irl/planning/ceiling):
the smoothed marginal and previous-bin Markov by hand, the classifier's columns and floor, and the
grouped cross-validated choice with a stub classifier (no scikit-learn)."""

from __future__ import annotations

import numpy as np
import pytest

from irl.domains.merge.actions import actions_of
from irl.errors import DemonstrationError
from irl.planning.decisions import PlanningDecisions
from studies.support.ceiling import (
    PROB_FLOOR,
    Marginal,
    PreviousBinMarkov,
    ceiling_features,
    class_log_probs,
    fit_ceiling,
    previous_bins,
)

#: One acceleration inside each paper bin (ft/s^2).
BIN_ACC = np.array([-8.0, -2.7, 0.0, 2.7, 8.0])


def decisions(acts, prev, *, obs=None, acc_C=None, groups=None) -> PlanningDecisions:
    acc = BIN_ACC[np.asarray(acts)]
    n = acc.size
    obs = np.zeros((n, 7)) if obs is None else obs
    return PlanningDecisions(obs, np.asarray(prev, dtype=float), np.zeros(n) if acc_C is None else acc_C,
                             actions_of(acc), acc, np.arange(n) if groups is None else groups)


def test_marginal_and_markov_by_hand() -> None:
    # actions 2 2 3 1 after previous bins ? 2 2 3: counts (0, 1, 2, 1, 0) -> (1, 2, 3, 2, 1) / 9
    d = decisions([2, 2, 3, 1], [np.nan, 0.0, 0.0, 2.7])
    m = Marginal.fit(d.actions)
    assert np.allclose(np.exp(m.log_p), np.array([1, 2, 3, 2, 1]) / 9)
    k = PreviousBinMarkov.fit(d)
    # after Zero: 2, 3 once each -> (1, 1, 2, 2, 1) / 7; after Low Accel: 1 once -> (1, 2, 1, 1, 1) / 6;
    # after High Brake (never seen): uniform
    assert np.allclose(np.exp(k.log_next[2]), np.array([1, 1, 2, 2, 1]) / 7)
    assert np.allclose(np.exp(k.log_next[3]), np.array([1, 2, 1, 1, 1]) / 6)
    assert np.allclose(np.exp(k.log_next[0]), 0.2)
    assert np.allclose(k.log_marginal, m.log_p)
    test = decisions([3, 1, 4], [0.1, np.nan, -9.0])
    want = np.mean([np.log(2 / 7), np.log(2 / 9), np.log(0.2)])  # the unknown previous: the marginal
    assert k.ll_per_decision(test) == pytest.approx(want)
    assert m.ll_per_decision(test) == pytest.approx(np.mean(np.log([2 / 9, 2 / 9, 1 / 9])))


def test_previous_bins_unknown_is_minus_one() -> None:
    assert previous_bins(np.array([np.nan, -5.0, -0.6, 0.59, 0.6, 4.8])).tolist() == [-1, 0, 1, 2, 3, 4]


def test_features_are_the_observation_and_acc_C_without_history() -> None:
    obs = np.arange(14.0).reshape(2, 7)
    obs[0, 2] = np.nan
    a = decisions([1, 2], [0.0, 0.0], obs=obs, acc_C=np.array([1.5, -2.0]))
    b = decisions([1, 2], [-9.0, np.nan], obs=obs, acc_C=np.array([1.5, -2.0]))
    X = ceiling_features(a)
    assert X.shape == (2, 8)
    assert np.array_equal(X, ceiling_features(b), equal_nan=True)
    assert np.isnan(X[0, 2]) and X[1, 7] == -2.0


class SignClassifier:
    """Stub: class 3 when column 0 > 0, else class 1, with probability ``p`` (the setting); with
    ``p=None`` the training frequencies whatever the features."""

    def __init__(self, p: float | None) -> None:
        self.p = p
        self.seen_columns = -1

    def fit(self, X: np.ndarray, y: np.ndarray) -> SignClassifier:
        self.seen_columns = X.shape[1]
        self.classes_ = np.unique(y)
        self.freq = np.array([(y == c).mean() for c in self.classes_])
        return self

    def predict_proba(self, X: np.ndarray) -> np.ndarray:
        if self.p is None:
            return np.tile(self.freq, (X.shape[0], 1))
        hi = (X[:, 0] > 0)[:, None]
        col = {int(c): i for i, c in enumerate(self.classes_)}
        out = np.full((X.shape[0], self.classes_.size), (1 - self.p) / max(self.classes_.size - 1, 1))
        out[:, col[3]] = np.where(hi[:, 0], self.p, out[:, col[3]])
        out[:, col[1]] = np.where(hi[:, 0], out[:, col[1]], self.p)
        return out


def test_class_log_probs_places_columns_and_floors_unseen_classes() -> None:
    model = SignClassifier(0.9).fit(np.array([[1.0], [-1.0]]), np.array([3, 1]))
    lp = class_log_probs(model, np.array([[2.0], [-2.0]]))
    assert lp.shape == (2, 5)
    assert np.allclose(np.exp(lp).sum(axis=1), 1.0)
    assert np.exp(lp[0, 3]) == pytest.approx(0.9, rel=1e-6) and np.exp(lp[1, 1]) == pytest.approx(0.9, rel=1e-6)
    assert np.exp(lp[0, 0]) == pytest.approx(PROB_FLOOR, rel=1e-6)


def test_grouped_cv_picks_the_setting_that_generalises_and_refits_on_all() -> None:
    rng = np.random.default_rng(0)
    n = 200
    x = rng.normal(size=n)
    acts = np.where(rng.random(n) < 0.85, np.where(x > 0, 3, 1), np.where(x > 0, 1, 3))
    obs = np.full((n, 7), np.nan)  # columns without a number are dropped before fitting
    obs[:, 0] = x
    groups = np.arange(n) // 10
    d = decisions(acts, np.zeros(n), obs=obs, groups=groups)
    folds = [(np.flatnonzero(groups % 4 != k), np.flatnonzero(groups % 4 == k)) for k in range(4)]
    settings = [None, 0.55, 0.85, 0.99]
    fit = fit_ceiling(SignClassifier, settings, d, folds)
    assert fit.setting == 0.85
    assert [s for s, _ in fit.cv] == settings
    assert fit.cv[2][1] == max(v for _, v in fit.cv)
    assert fit.columns.tolist() == [True] + [False] * 6 + [True]
    assert fit.model.seen_columns == 2
    assert fit.ll_per_decision(d) == pytest.approx(fit.cv[2][1], abs=0.02)
    with pytest.raises(DemonstrationError):
        fit_ceiling(SignClassifier, [], d, folds)
    with pytest.raises(DemonstrationError):
        fit_ceiling(SignClassifier, settings, d, [(np.arange(n), np.array([], dtype=int))])
