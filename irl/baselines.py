"""Policies that need no IRL, and leave-one-trajectory-out evaluation of any policy.

Four baselines, each fitted on training demonstrations and giving ``log pi(a_t | s_t, a_{t-1})``:

* ``uniform``: ``pi(a) = 1/A``.
* ``marginal``: the action frequencies of the training steps, add-one smoothed:
  ``pi(a) = (n(a) + 1) / (N + A)``.
* ``markov``: the next action given the previous one, add-one smoothed:
  ``pi(a | a_prev) = (n(a_prev -> a) + 1) / (n(a_prev -> .) + A)`` over consecutive steps of
  each trajectory. A trajectory's first step has no previous action: it is scored by the
  ``marginal`` (add-one smoothed).
* ``bc``: tabular behaviour cloning, add-one smoothed: ``pi(a | s) = (n(s, a) + 1) / (n(s) + A)``
  (uniform in states never seen in training).

Every policy here, and the learned IRL policies (:class:`TabularPolicy`, ``log pi(a|s)`` from a
Q table), score demonstrations the same way: :meth:`trajectory_logliks` gives one
log-likelihood per trajectory (paper Eq. 5 without ``log Pr(s_1)``), and
:func:`leave_one_out` fits on all trajectories but one and scores the one left out, fold by
fold, so paired tests can compare two methods on the same held-out trajectories
(:func:`paired_test`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from scipy.stats import wilcoxon

from irl.demonstrations import Demonstrations
from irl.errors import ConfigError, DemonstrationError
from merge_irl.registry import Registry, RegistryError


class TabularBaselineError(RegistryError, ConfigError):
    """An unknown tabular baseline, or one registered twice (a :class:`ConfigError`)."""


#: The tabular baselines' fitters by name, ``fit(demos) -> BaselinePolicy`` (not the closed-loop
#: drivers of an evaluation: those are :data:`sim.drivers.baselines.BASELINES`).
BASELINE_FITTERS: Registry[Callable[[Demonstrations], BaselinePolicy]] = Registry(
    "baseline", error=TabularBaselineError)


class TrajectoryScorer(Protocol):
    """Anything that scores each trajectory of some demonstrations."""

    def trajectory_logliks(self, demos: Demonstrations) -> np.ndarray:
        """``[n_trajectories]`` sum over each trajectory's steps of ``log pi(a_t | ...)``."""
        ...


def _check_space(n_states: int, n_actions: int, demos: Demonstrations, what: str) -> None:
    if (demos.n_states, demos.n_actions) != (n_states, n_actions):
        raise DemonstrationError(
            f"{demos.source or 'demonstrations'}: {demos.n_states} states x {demos.n_actions} actions, "
            f"but the {what} has {n_states} x {n_actions}")


@dataclass(frozen=True)
class TabularPolicy:
    """A state-conditional policy ``log pi(a|s)`` (e.g. an IRL model's ``softmax(beta Q)``).

    Attributes:
        name: a label (method name).
        log_pi: ``[S, A]`` log-probabilities; rows log-sum-exp to 0.
    """

    name: str
    log_pi: np.ndarray

    def trajectory_logliks(self, demos: Demonstrations) -> np.ndarray:
        """``[n_trajectories]`` ``sum_t log pi(a_t | s_t)`` per trajectory.

        Raises:
            DemonstrationError: the demonstrations' state or action count differs from ``log_pi``'s.
        """
        S, A = self.log_pi.shape
        _check_space(S, A, demos, f"policy {self.name!r}")
        return np.array([float(np.sum(self.log_pi[s, a])) for s, a in zip(demos.states, demos.actions)])

    def loglik(self, demos: Demonstrations) -> float:
        """Total log-likelihood of ``demos`` (sum of :meth:`trajectory_logliks`)."""
        return float(np.sum(self.trajectory_logliks(demos)))


@dataclass(frozen=True)
class BaselinePolicy:
    """A fitted baseline: ``log pi(a | s)`` for a trajectory's first step and, for ``markov``,
    ``log pi(a | a_prev)`` for the later ones.

    Attributes:
        name: one of ``TABULAR_BASELINES``.
        log_first: ``[S, A]`` log-probabilities of a trajectory's first step (and of every step
            when ``log_next`` is None).
        log_next: ``[A, A]`` ``log pi(a | a_prev)`` indexed ``[a_prev, a]``, or None.
    """

    name: str
    log_first: np.ndarray
    log_next: np.ndarray | None = None

    def step_logprobs(self, states: np.ndarray, actions: np.ndarray) -> np.ndarray:
        """``[T]`` ``log pi(a_t | s_t, a_{t-1})`` of one trajectory (``states, actions [T]``)."""
        out = self.log_first[states, actions].astype(np.float64)
        if self.log_next is not None and actions.size > 1:
            out[1:] = self.log_next[actions[:-1], actions[1:]]
        return out

    def log_policy(self, prev_action: int | None = None) -> np.ndarray:
        """``[S, A]`` ``log pi(a | s)`` given the previous action (None: a first step)."""
        if self.log_next is None or prev_action is None:
            return self.log_first
        return np.broadcast_to(self.log_next[int(prev_action)], self.log_first.shape)

    def trajectory_logliks(self, demos: Demonstrations) -> np.ndarray:
        """``[n_trajectories]`` per-trajectory log-likelihoods.

        Raises:
            DemonstrationError: the demonstrations' state or action count differs from the fit's.
        """
        S, A = self.log_first.shape
        _check_space(S, A, demos, f"baseline {self.name!r}")
        return np.array([float(np.sum(self.step_logprobs(s, a))) for s, a in zip(demos.states, demos.actions)])

    def loglik(self, demos: Demonstrations) -> float:
        """Total log-likelihood of ``demos``."""
        return float(np.sum(self.trajectory_logliks(demos)))


def _smoothed_log(counts: np.ndarray) -> np.ndarray:
    """``log((counts + 1) / (row total + A))`` along the last axis (add-one smoothing)."""
    c = np.asarray(counts, dtype=np.float64) + 1.0
    return np.log(c) - np.log(c.sum(axis=-1, keepdims=True))


def _uniform(demos: Demonstrations) -> BaselinePolicy:
    S, A = demos.n_states, demos.n_actions
    return BaselinePolicy("uniform", np.full((S, A), -np.log(A)))


def _marginal_log(demos: Demonstrations) -> np.ndarray:
    return _smoothed_log(np.bincount(demos.flat()[1], minlength=demos.n_actions))  # [A]


def _marginal(demos: Demonstrations) -> BaselinePolicy:
    return BaselinePolicy("marginal", np.broadcast_to(_marginal_log(demos), (demos.n_states, demos.n_actions)).copy())


def _markov(demos: Demonstrations) -> BaselinePolicy:
    A = demos.n_actions
    pairs = np.zeros((A, A))
    for a in demos.actions:
        np.add.at(pairs, (a[:-1], a[1:]), 1.0)
    return BaselinePolicy("markov", np.broadcast_to(_marginal_log(demos), (demos.n_states, A)).copy(),
                          _smoothed_log(pairs))


def _bc(demos: Demonstrations) -> BaselinePolicy:
    states, actions, _ = demos.flat()
    counts = np.zeros((demos.n_states, demos.n_actions))
    np.add.at(counts, (states, actions), 1.0)
    return BaselinePolicy("bc", _smoothed_log(counts))


for _name, _fit in (("uniform", _uniform), ("marginal", _marginal), ("markov", _markov), ("bc", _bc)):
    BASELINE_FITTERS.register(_name, _fit)

#: The tabular baselines of the paper tables, scored by leave-one-trajectory-out, in their order.
TABULAR_BASELINES = BASELINE_FITTERS.names()


def fit_baseline(name: str, demos: Demonstrations) -> BaselinePolicy:
    """Fit baseline ``name`` (one of :data:`BASELINE_FITTERS`: ``TABULAR_BASELINES``) on ``demos``;
    see the module doc.

    Raises:
        ConfigError (TabularBaselineError): unknown ``name`` (the known ones listed).
    """
    return BASELINE_FITTERS[name](demos)


def leave_one_out(demos: Demonstrations,
                  fit_fold: Callable[[np.ndarray], TrajectoryScorer]) -> np.ndarray:
    """Per-fold held-out log-likelihoods, ``[n_trajectories]``: the one evaluation of every
    baseline and IRL method.

    Fold ``i`` fits ``fit_fold(train)`` on every trajectory index but ``i`` (``train``, int64
    ``[n - 1]``, indexes ``demos``) and scores trajectory ``i`` of ``demos`` with the fitted
    policy's ``trajectory_logliks``.

    Raises:
        DemonstrationError: fewer than 2 trajectories (nothing to train on).
    """
    n = demos.n_trajectories
    if n < 2:
        raise DemonstrationError(f"leave-one-trajectory-out needs at least 2 trajectories, got {n}")
    out = np.empty(n)
    for i in range(n):
        train = np.array([j for j in range(n) if j != i], dtype=np.int64)
        out[i] = float(fit_fold(train).trajectory_logliks(demos.subset([i]))[0])
    return out


def baseline_leave_one_out(name: str, demos: Demonstrations) -> np.ndarray:
    """``[n_trajectories]`` held-out log-likelihood of each trajectory under baseline ``name``
    fitted on the others (:func:`leave_one_out`)."""
    return leave_one_out(demos, lambda train: fit_baseline(name, demos.subset(train)))


def paired_test(x: np.ndarray, y: np.ndarray) -> float:
    """Two-sided Wilcoxon signed-rank p-value of paired held-out log-likelihoods.

    ``x, y`` are ``[n]`` per-fold (per held-out trajectory) log-likelihoods of two methods on
    the same folds (:func:`leave_one_out`): each pair is one trajectory, an independent
    observation. Pairs with a non-finite value are dropped. Returns NaN with fewer than 2 pairs,
    1.0 when every difference is zero (``scipy.stats.wilcoxon``, exact distribution for small
    ``n`` without ties).

    Raises:
        ValueError: ``x`` and ``y`` differ in shape.
    """
    x, y = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
    if x.shape != y.shape:
        raise ValueError(f"paired_test: x {x.shape} and y {y.shape} must have the same shape")
    d = x - y
    d = d[np.isfinite(d)]
    if d.size < 2:
        return float("nan")
    scale = max(1.0, float(np.max(np.abs(x[np.isfinite(x)]), initial=0.0)))
    if np.all(np.abs(d) <= 1e-12 * scale):
        return 1.0
    try:
        return float(wilcoxon(d).pvalue)
    except ValueError:
        return float("nan")
