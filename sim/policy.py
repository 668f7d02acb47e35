"""Driving policies for a controlled vehicle: observation -> distribution over the 5 actions.

A policy maps the merge observation of car A (:class:`sim.observe.MergeObservation`: the four
continuous variables, B's truck flag and the discrete state) to probabilities over the merge
domain's five acceleration actions (High Brake, Low Brake, Zero, Low Accel, High Accel). The
controller samples an action (or takes the mode) and applies
:data:`irl.domains.merge.actions.ACTION_ACC_FT_S2`, the representative acceleration of each action bin
(the action bins and names are :mod:`irl.domains.merge.actions`', the state encoding
:mod:`irl.domains.merge.states`').

Policies in the same harness:

* :class:`LearnedPolicy`: ``softmax(beta Q(s, .))`` of a saved IRL model (Q-Avg, Q-SM, MLIRL,
  REIRL), discretising with the model's own bin edges.
* :class:`SumoPolicy`: the baseline; the vehicle is *not* taken over, SUMO's car-following
  model drives it (``controls = False``); the controller still observes it.
* :class:`UniformPolicy`: uniform random over the 5 actions.
* :class:`BaselineTabularPolicy`: ``marginal``, ``markov`` or ``bc`` fitted on the training
  demonstrations (:mod:`irl.baselines`); ``markov`` conditions on A's previous action.
* :class:`CarFollowingLogitPolicy`: a :class:`irl.domains.merge.cf_logit.CarFollowingLogit`
  driver on the continuous observation (A's speed, gaps, closing speeds, previous action).
* :class:`ConstantPolicy`: always the same action (e.g. always brake hard, for tests).
"""

from __future__ import annotations

from bisect import bisect_right
from dataclasses import dataclass
from itertools import accumulate
from typing import TYPE_CHECKING, Protocol, runtime_checkable

import numpy as np

from irl.domains.merge.actions import ACTION_ACC_FT_S2, ACTION_NAMES, N_ACTIONS
from irl.domains.merge.bins import MergeBins
from irl.errors import ConfigError
from sim.errors import SimError

if TYPE_CHECKING:  # pragma: no cover
    from irl.baselines import BaselinePolicy
    from irl.domains.merge.cf_logit import CarFollowingLogit
    from irl.result import SavedModel
    from sim.observe import MergeObservation


class PolicyError(SimError, ValueError):
    """A policy cannot be built from its inputs (e.g. a model that is not a merge model)."""


@runtime_checkable
class Policy(Protocol):
    """Observation -> action distribution.

    Attributes:
        name: label used in reports and logs.
        controls: False when the vehicle is left to SUMO (the baseline); the controller then
            only observes it.
    """

    # read-only properties, so frozen dataclasses (the policies here) satisfy the protocol
    @property
    def name(self) -> str: ...

    @property
    def controls(self) -> bool: ...

    def probs(self, obs: MergeObservation) -> np.ndarray:
        """``[5]`` action probabilities (sum to 1)."""
        ...


def choose_action(probs: np.ndarray, rng: np.random.Generator, *, mode: bool = False) -> int:
    """Sample an action from ``probs [A]`` with ``rng`` (or take the most likely one)."""
    p = np.asarray(probs, dtype=np.float64).tolist()  # five numbers: plain Python is faster than numpy
    if mode:
        return p.index(max(p))  # the first of equal maxima, as argmax
    cdf = list(accumulate(p))  # sequential sums, bit for bit numpy's cumsum
    u = rng.random() * cdf[-1]
    return min(bisect_right(cdf, u), len(p) - 1)


@dataclass(frozen=True)
class UniformPolicy:
    """Every action with probability 1/5."""

    name: str = "uniform"
    controls: bool = True

    def probs(self, obs: MergeObservation) -> np.ndarray:
        return np.full(N_ACTIONS, 1.0 / N_ACTIONS)


@dataclass(frozen=True)
class ConstantPolicy:
    """Always ``action`` (0 = High Brake ... 4 = High Accel)."""

    action: int = 0
    name: str = ""
    controls: bool = True

    def __post_init__(self) -> None:
        if not 0 <= int(self.action) < N_ACTIONS:
            raise PolicyError(f"ConstantPolicy.action must be in 0..{N_ACTIONS - 1}, got {self.action}")
        if not self.name:
            object.__setattr__(self, "name", f"constant-{ACTION_NAMES[int(self.action)].lower().replace(' ', '-')}")

    def probs(self, obs: MergeObservation) -> np.ndarray:
        p = np.zeros(N_ACTIONS)
        p[int(self.action)] = 1.0
        return p


@dataclass(frozen=True)
class SumoPolicy:
    """The baseline: SUMO's own car-following model drives A (the controller only observes).

    ``keep_lane``: A's lane changes are switched off while it is observed (lane-change mode 0,
    restored at release), as for every driver the controller commands, whose actions are
    accelerations alone: SUMO's driver kept in its lane (``sumo-in-lane``) is the like-for-like
    floor of those drivers' distances to the demonstrations. ``probs`` returns the distribution
    implied by nothing (uniform) and is never used to act.
    """

    name: str = "sumo"
    controls: bool = False
    keep_lane: bool = False

    def probs(self, obs: MergeObservation) -> np.ndarray:
        return np.full(N_ACTIONS, 1.0 / N_ACTIONS)


@dataclass(frozen=True)
class LearnedPolicy:
    """``pi(a|s) = softmax(beta Q(s, .))`` of a learned IRL model.

    Attributes:
        log_pi: ``[S, 5]`` log-policy table (``SavedModel.log_policy()``).
        encoder: the state bins the model was trained with (:class:`irl.domains.merge.bins.MergeBins`,
            the one merge-state encoder; see :meth:`from_model`).
        name: label (e.g. the method).
        action_acc_ft_s2: ``[5]`` acceleration applied for each action (ft/s^2): the model's
            conditional mean of each action bin in its training data (cause 8 of issue 11);
            the bin midpoints for models that do not save it.
        decision_step_s: the step the demonstrations were resampled to (s); the controller
            decides this often unless told otherwise.
        state_encoding: ``"paper"`` (the 1250 paper states) or ``"driver"`` (paper state x A's
            previous action, ``5 s + prev``).
        flags: what the model's fit reported (``not_converged``, ``unbounded``, ``infeasible``,
            ``uninformative``); empty: none.
    """

    log_pi: np.ndarray
    encoder: MergeBins
    name: str = "learned"
    controls: bool = True
    action_acc_ft_s2: tuple[float, ...] = tuple(float(x) for x in ACTION_ACC_FT_S2)
    decision_step_s: float = 0.1
    state_encoding: str = "paper"
    flags: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        lp = np.asarray(self.log_pi, dtype=np.float64)
        if lp.ndim != 2 or lp.shape[1] != N_ACTIONS or not np.all(np.isfinite(lp)):
            raise PolicyError(f"policy {self.name!r}: log_pi must be a finite [S, {N_ACTIONS}] table, got {lp.shape}")
        object.__setattr__(self, "log_pi", lp)
        acc = tuple(float(x) for x in self.action_acc_ft_s2)
        if len(acc) != N_ACTIONS or not all(np.isfinite(acc)):
            raise PolicyError(f"policy {self.name!r}: action_acc_ft_s2 must be {N_ACTIONS} finite numbers, got {acc}")
        object.__setattr__(self, "action_acc_ft_s2", acc)

    @classmethod
    def from_model(cls, model: SavedModel, *, encoder: MergeBins | None = None, name: str = "") -> LearnedPolicy:
        """From a saved merge model (``q [S, 5]``, ``bin_edges``, ``config.beta``).

        Raises:
            PolicyError: ``q`` is not ``[S, 5]``, or the model has no or bad ``bin_edges``.
        """
        q = np.asarray(model.q)
        if q.ndim != 2 or q.shape[1] != N_ACTIONS:
            raise PolicyError(
                f"model {model.method!r}: q must be [S, {N_ACTIONS}] for the merge domain, got {q.shape}"
            )
        if encoder is None:
            if not model.bin_edges:
                raise PolicyError(
                    f"model {model.method!r} has no 'bin_edges': the closed loop needs the state bin "
                    "edges the model was trained with (learn it from encounters, not from pre-binned "
                    "data, or add bin_edges to model.json)"
                )
            try:
                encoder = MergeBins.from_dict(dict(model.bin_edges), where=f"model {model.method!r} bin_edges")
            except ConfigError as e:
                raise PolicyError(str(e)) from None
        acc = getattr(model, "action_acc_ft_s2", None)
        return cls(log_pi=model.log_policy(), encoder=encoder, name=name or model.method,
                   action_acc_ft_s2=tuple(ACTION_ACC_FT_S2) if acc is None or len(acc) == 0 else tuple(acc),
                   decision_step_s=float(getattr(model, "decision_step_s", 0.1) or 0.1),
                   state_encoding=str(getattr(model, "state_encoding", "paper") or "paper"),
                   flags=model_flags(model))

    @property
    def n_states(self) -> int:
        return int(self.log_pi.shape[0])

    def probs(self, obs: MergeObservation) -> np.ndarray:
        """``[5]`` the learned policy's action probabilities in ``obs.state``.

        Raises:
            PolicyError: ``obs.state`` is outside ``[0, n_states)``.
        """
        if not 0 <= obs.state < self.n_states:
            raise PolicyError(f"state {obs.state} out of range [0, {self.n_states}) for policy {self.name!r}")
        return np.exp(self.log_pi[obs.state])


def model_flags(model: SavedModel) -> tuple[str, ...]:
    """What a saved model's fit reported, as :attr:`irl.result.FitResult.flags` names it:
    ``not_converged``, ``unbounded``, ``infeasible``, ``uninformative`` (empty: none)."""
    out = [] if model.converged else ["not_converged"]
    if model.unbounded:
        out.append("unbounded")
    extra = model.info.get("extra", {}) if isinstance(model.info, dict) else {}
    out += [k for k in ("infeasible", "uninformative") if isinstance(extra, dict) and extra.get(k)]
    return tuple(out)


@dataclass(frozen=True)
class BaselineTabularPolicy:
    """A baseline of :mod:`irl.baselines` (``marginal``, ``markov``, ``bc``) as a driver.

    Attributes:
        baseline: the fitted :class:`irl.baselines.BaselinePolicy` (``log_first [S, 5]``,
            ``log_next [5, 5]`` or None).
        encoder: the paper state bins (for ``bc``; the others ignore the state).
        name: label (the baseline's name).
        action_acc_ft_s2: ``[5]`` acceleration applied per action (ft/s^2), as
            :class:`LearnedPolicy`.

    ``markov`` scores ``pi(a | a_prev)`` with ``obs.prev_action`` (A's previous action in the
    closed loop) and falls back to the first-step table (the marginal) without one.
    """

    baseline: BaselinePolicy
    encoder: MergeBins
    name: str = ""
    controls: bool = True
    action_acc_ft_s2: tuple[float, ...] = tuple(float(x) for x in ACTION_ACC_FT_S2)

    def __post_init__(self) -> None:
        if not self.name:
            object.__setattr__(self, "name", self.baseline.name)

    def probs(self, obs: MergeObservation) -> np.ndarray:
        b = self.baseline
        if b.log_next is not None and 0 <= obs.prev_action < N_ACTIONS:
            return np.exp(b.log_next[obs.prev_action])
        s = obs.state if 0 <= obs.state < b.log_first.shape[0] else 0
        return np.exp(b.log_first[s])


@dataclass(frozen=True)
class CarFollowingLogitPolicy:
    """A car-following logit driver (:class:`irl.domains.merge.cf_logit.CarFollowingLogit`).

    ``probs`` evaluates the model's features on the observation itself (``d_AC, v_AC, d_AB,
    v_AB``, ``speed_A`` and the lengths ``len_C``, ``len_B``; ft and ft/s; no bins) and A's previous action in this control
    episode (before the first decision ``initial_action``, the bin of A's last acceleration, as
    the driver encoding takes it; Zero if unknown). Actions are applied at the model's
    ``action_acc_ft_s2``; the controller decides every ``decision_step_s``.
    """

    model: CarFollowingLogit
    name: str = "cf-logit"
    controls: bool = True
    source: str = ""  # the model's file, when read from one (recorded in evaluations' provenance)

    @property
    def action_acc_ft_s2(self) -> tuple[float, ...]:
        """``[5]`` acceleration applied per action (ft/s^2), the model's."""
        return self.model.action_acc_ft_s2

    @property
    def decision_step_s(self) -> float:
        """Seconds per decision the model was trained at."""
        return self.model.decision_step_s

    @property
    def flags(self) -> tuple[str, ...]:
        """What the model's fit reported, named as :func:`model_flags` names it:
        ``("not_converged",)`` when its optimiser did not converge, else empty."""
        return () if self.model.converged else ("not_converged",)

    def probs(self, obs: MergeObservation) -> np.ndarray:
        """``[5]`` action probabilities at ``obs``.

        Raises:
            PolicyError: A's speed or ``d_AB``/``v_AB`` is not finite.
        """
        if not all(np.isfinite([obs.speed_A, obs.d_AB, obs.v_AB])):
            raise PolicyError(f"policy {self.name!r}: A's speed, d_AB and v_AB must be finite, got "
                              f"{obs.speed_A}, {obs.d_AB}, {obs.v_AB}")
        x = np.array([[obs.d_AC, obs.v_AC, obs.d_AB, obs.v_AB, obs.speed_A, obs.len_C, obs.len_B]], dtype=np.float64)
        prev = obs.prev_action if obs.prev_action >= 0 else obs.initial_action
        return np.exp(self.model.log_policy(x, np.array([prev]))[0])
