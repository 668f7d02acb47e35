"""Reference scores for the planning driver's held-out likelihood (nats per decision, the paper
action bins of :class:`~irl.planning.decisions.PlanningDecisions`): the smoothed
marginal, the previous-bin Markov model and a history-free classifier tuned by grouped
cross-validation (the "ceiling" a reward over the same observation could approach).

* :class:`Marginal`: ``P(b)`` from the training actions, Laplace smoothing ``alpha``.
* :class:`PreviousBinMarkov`: ``P(b | b_prev)``, ``b_prev`` the paper bin of ``prev_acc``,
  Laplace smoothing ``alpha`` on each row; a decision whose previous acceleration is unknown
  (NaN) gets the marginal. It sees history, so it is not a like-for-like comparison with a
  model of the observation alone.
* :func:`fit_ceiling`: a classifier of the observation the driver sees (:func:`ceiling_features`:
  ``obs [N, 7]`` with its NaNs, and ``acc_C``; no previous action), one setting of several
  chosen by the pooled validation likelihood over the given folds of the training decisions
  (folds by group, e.g. scikit-learn's ``GroupKFold``), then refitted on all of them. The
  classifier comes from a factory (any object with ``fit(X, y)``, ``predict_proba(X)`` and
  ``classes_``), so this module needs no scikit-learn.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from irl.domains.merge.actions import N_ACTIONS, actions_of
from irl.errors import DemonstrationError
from irl.planning.decisions import PlanningDecisions

#: Probabilities a classifier gives below this are raised to it (then renormalised): a class it
#: never saw in training costs ``log(1e-9)`` = -20.7 nats, not minus infinity.
PROB_FLOOR = 1e-9


def laplace_log_probs(counts: np.ndarray, alpha: float = 1.0) -> np.ndarray:
    """``log((counts + alpha) / (sum + n alpha))`` along the last axis."""
    c = np.asarray(counts, dtype=np.float64) + alpha
    return np.log(c / c.sum(axis=-1, keepdims=True))


def previous_bins(prev_acc: np.ndarray) -> np.ndarray:
    """``[N]`` int64 paper bin of each previous acceleration, ``-1`` where it is unknown (NaN)."""
    p = np.asarray(prev_acc, dtype=np.float64)
    known = np.isfinite(p)
    return np.where(known, actions_of(np.where(known, p, 0.0)), -1).astype(np.int64)


@dataclass(frozen=True)
class Marginal:
    """``log P(b)`` ``[5]`` of the training actions (Laplace smoothing)."""

    log_p: np.ndarray

    @classmethod
    def fit(cls, actions: np.ndarray, alpha: float = 1.0) -> Marginal:
        return cls(laplace_log_probs(np.bincount(np.asarray(actions, dtype=np.int64), minlength=N_ACTIONS), alpha))

    def ll_per_decision(self, decisions: PlanningDecisions) -> float:
        """Mean ``log P(b)`` of ``decisions``' actions (nats per decision)."""
        return float(self.log_p[decisions.actions].mean())


@dataclass(frozen=True)
class PreviousBinMarkov:
    """``log P(b | b_prev)`` ``[5, 5]`` (row: the previous bin) and the marginal ``[5]`` used when
    the previous acceleration is unknown; both with Laplace smoothing."""

    log_next: np.ndarray
    log_marginal: np.ndarray

    @classmethod
    def fit(cls, decisions: PlanningDecisions, alpha: float = 1.0) -> PreviousBinMarkov:
        """Counts of (previous bin, action) over the decisions whose previous acceleration is
        known; the marginal over all of them."""
        prev = previous_bins(decisions.prev_acc)
        known = prev >= 0
        counts = np.zeros((N_ACTIONS, N_ACTIONS))
        np.add.at(counts, (prev[known], decisions.actions[known]), 1.0)
        return cls(laplace_log_probs(counts, alpha), Marginal.fit(decisions.actions, alpha).log_p)

    def log_probs(self, prev_acc: np.ndarray) -> np.ndarray:
        """``[N, 5]`` ``log P(b | bin of prev_acc)`` (the marginal where ``prev_acc`` is NaN)."""
        prev = previous_bins(prev_acc)
        return np.where((prev >= 0)[:, None], self.log_next[np.maximum(prev, 0)], self.log_marginal[None, :])

    def ll_per_decision(self, decisions: PlanningDecisions) -> float:
        """Mean ``log P(b | b_prev)`` of ``decisions`` (nats per decision)."""
        lp = self.log_probs(decisions.prev_acc)
        return float(lp[np.arange(decisions.n), decisions.actions].mean())


def ceiling_features(decisions: PlanningDecisions) -> np.ndarray:
    """``[N, 8]``: ``obs`` (d_AC, v_AC, d_AB, v_AB, v_A, len_C, len_B; ft, ft/s, NaN where
    absent) and ``acc_C`` (ft/s^2); no previous action."""
    return np.column_stack([decisions.obs, decisions.acc_C])


def class_log_probs(model: Any, X: np.ndarray, n_classes: int = N_ACTIONS) -> np.ndarray:
    """``[N, n_classes]`` log probabilities of a fitted classifier, its ``predict_proba``
    columns placed by ``model.classes_`` (classes it never saw: :data:`PROB_FLOOR`), floored
    and renormalised."""
    p = np.zeros((X.shape[0], n_classes))
    p[:, np.asarray(model.classes_, dtype=np.int64)] = np.asarray(model.predict_proba(X), dtype=np.float64)
    p = np.maximum(p, PROB_FLOOR)
    return np.log(p / p.sum(axis=1, keepdims=True))


def _fit_on(factory: Callable[[Any], Any], setting: Any, X: np.ndarray, y: np.ndarray) -> tuple[Any, np.ndarray]:
    """A classifier of ``setting`` fitted on the columns of ``X`` with at least one number."""
    cols = np.isfinite(X).any(axis=0)
    return factory(setting).fit(X[:, cols], y), cols


@dataclass(frozen=True)
class CeilingFit:
    """A classifier chosen by grouped cross-validation and refitted on all training decisions.

    Attributes:
        setting: the chosen setting (what the factory took).
        model: the refitted classifier; columns: ``[8]`` bool, the feature columns it uses.
        cv: ``(setting, pooled validation LL per decision)`` of every setting tried, in order.
    """

    setting: Any
    model: Any
    columns: np.ndarray
    cv: tuple[tuple[Any, float], ...]

    def log_probs(self, decisions: PlanningDecisions) -> np.ndarray:
        """``[N, 5]`` ``log P(b | x)``."""
        return class_log_probs(self.model, ceiling_features(decisions)[:, self.columns])

    def ll_per_decision(self, decisions: PlanningDecisions) -> float:
        """Mean ``log P(b | x)`` of ``decisions`` (nats per decision)."""
        return float(self.log_probs(decisions)[np.arange(decisions.n), decisions.actions].mean())


def fit_ceiling(factory: Callable[[Any], Any], settings: Sequence[Any], decisions: PlanningDecisions,
                folds: Sequence[tuple[np.ndarray, np.ndarray]], *,
                log: Callable[[str], None] = lambda s: None) -> CeilingFit:
    """The setting of ``settings`` whose classifiers (``factory(setting)``) give the highest
    pooled log-likelihood on the validation parts of ``folds`` (index pairs ``(train, val)``
    into ``decisions``; split by group so that no group is on both sides), refitted on all of
    ``decisions``. Ties: the first. ``log`` receives one line per setting.

    Raises:
        DemonstrationError: no settings, no folds, or a fold with an empty side.
    """
    if not settings or not folds:
        raise DemonstrationError("fit_ceiling: needs one or more settings and one or more folds")
    X, y = ceiling_features(decisions), decisions.actions
    cv = []
    for setting in settings:
        total, n = 0.0, 0
        for tr, va in folds:
            tr, va = np.asarray(tr), np.asarray(va)
            if tr.size == 0 or va.size == 0:
                raise DemonstrationError("fit_ceiling: a fold with no training or no validation decisions")
            model, cols = _fit_on(factory, setting, X[tr], y[tr])
            total += float(class_log_probs(model, X[va][:, cols])[np.arange(va.size), y[va]].sum())
            n += va.size
        cv.append((setting, total / n))
        log(f"ceiling setting {setting}: validation LL {total / n:.4f} per decision")
    best = max(range(len(cv)), key=lambda i: (cv[i][1], -i))
    model, cols = _fit_on(factory, settings[best], X, y)
    return CeilingFit(settings[best], model, cols, tuple(cv))
