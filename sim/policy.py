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

Every policy scores held-out demonstrations itself (:meth:`Policy.heldout_loglik`), as learning
sees them; the evaluation reads that number and nothing else of the policy's kind
(:func:`analysis.evaluation.heldout_scoring.policy_heldout_loglik`).
"""

from __future__ import annotations

from bisect import bisect_right
from dataclasses import dataclass
from itertools import accumulate
from typing import TYPE_CHECKING, Protocol, runtime_checkable

import numpy as np
import pandas as pd

from irl.boltzmann import heldout_loglik
from irl.domains.merge.actions import ACTION_ACC_FT_S2, ACTION_NAMES, N_ACTIONS
from irl.domains.merge.bins import MergeBins
from irl.domains.merge.car_following import CFDecisions, car_following_decisions
from irl.domains.merge.mdp import discretize
from irl.errors import ConfigError
from sim.errors import SimError

if TYPE_CHECKING:  # pragma: no cover
    from irl.baselines import BaselinePolicy
    from irl.domains.merge.cf_logit import CarFollowingLogit
    from irl.result import SavedModel
    from sim.observe import MergeObservation

#: ``(sum, per step)`` of a policy without a likelihood (SUMO's driver, the deterministic IDM).
NO_LIKELIHOOD = (float("nan"), float("nan"))


class PolicyError(SimError, ValueError):
    """A policy cannot be built from its inputs (e.g. a model that is not a merge model)."""


@runtime_checkable
class Policy(Protocol):
    """Observation -> action distribution, and the policy's own held-out score.

    Everything the controller and the evaluation read of a policy is declared here.

    Attributes:
        name: label used in reports and logs.
        controls: False when the vehicle is left to SUMO (the baseline); the controller then
            only observes it.
        decision_step_s: seconds per decision the driver was trained at; None: any step (the
            controller then decides every
            :data:`irl.domains.merge.mdp.DEFAULT_DECISION_STEP_S`, unless told otherwise).
    """

    # read-only properties, so frozen dataclasses (the policies here) satisfy the protocol
    @property
    def name(self) -> str: ...

    @property
    def controls(self) -> bool: ...

    @property
    def decision_step_s(self) -> float | None: ...

    def probs(self, obs: MergeObservation) -> np.ndarray:
        """``[5]`` action probabilities (sum to 1)."""
        ...

    def heldout_loglik(self, encounters: pd.DataFrame, *, decision_step_s: float,
                       where: str) -> tuple[float, float]:
        """``(sum, per step)`` log-likelihood (nats) of held-out encounter frames under the
        policy, scored as learning sees them: resampled at a decision step
        (:func:`irl.domains.merge.mdp.discretize`; ``decision_step_s``, the evaluation's, unless
        the policy has its own), so an action is the forward difference of A's speed over one
        decision. ``(NaN, NaN)`` where no likelihood exists (:data:`NO_LIKELIHOOD`).
        ``encounters``: prepared frames
        (:func:`analysis.evaluation.heldout_scoring.prepare_encounters`); ``where`` names them
        in errors.

        Raises:
            DemonstrationError: the frames cannot be resampled (e.g. every encounter shorter
                than one decision step).
        """
        ...


def missing_members(policy: object, *, scoring: bool = True) -> list[str]:
    """The members of :class:`Policy` that ``policy`` lacks (``heldout_loglik`` only when
    ``scoring``); empty: it has them all."""
    names = ["name", "controls", "decision_step_s", "probs"] + (["heldout_loglik"] if scoring else [])
    return [n for n in names if not hasattr(policy, n)]


def check_policy(policy: object, *, scoring: bool = True, where: str = "") -> None:
    """Refuse an object that does not declare what the controller (and, with ``scoring``, the
    held-out evaluation) reads of a :class:`Policy`.

    Raises:
        PolicyError: a member is missing (named, with the class).
    """
    missing = missing_members(policy, scoring=scoring)
    if missing:
        raise PolicyError(f"{where + ': ' if where else ''}{type(policy).__name__} is not a sim.policy.Policy: it "
                          f"lacks {', '.join(missing)} (a driver declares name, controls, decision_step_s (None: any "
                          "step), probs and heldout_loglik (NaN, NaN without a likelihood))")


def state_independent_loglik(p: np.ndarray, encounters: pd.DataFrame, *, decision_step_s: float,
                             where: str) -> tuple[float, float]:
    """``(sum, per step)`` of ``log p(a)`` over the held-out decisions (paper bins at
    ``decision_step_s``), for a policy whose ``[5]`` probabilities ``p`` do not depend on the
    observation (uniform, constant). A decision of probability 0 scores ``-inf``."""
    d = discretize(encounters, MergeBins.assumed_authors(), where=where, decision_step_s=decision_step_s)
    _, actions, _ = d.flat()
    with np.errstate(divide="ignore"):
        lp = np.log(np.asarray(p, dtype=float))[actions]
    return float(lp.sum()), float(lp.mean()) if lp.size else float("nan")


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

    @property
    def decision_step_s(self) -> None:
        """Any step."""
        return None

    def probs(self, obs: MergeObservation) -> np.ndarray:
        return np.full(N_ACTIONS, 1.0 / N_ACTIONS)

    def heldout_loglik(self, encounters: pd.DataFrame, *, decision_step_s: float,
                       where: str) -> tuple[float, float]:
        """``log 1/5`` per decision at ``decision_step_s``."""
        return state_independent_loglik(np.full(N_ACTIONS, 1.0 / N_ACTIONS), encounters,
                                        decision_step_s=decision_step_s, where=where)


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

    @property
    def decision_step_s(self) -> None:
        """Any step."""
        return None

    def probs(self, obs: MergeObservation) -> np.ndarray:
        p = np.zeros(N_ACTIONS)
        p[int(self.action)] = 1.0
        return p

    def heldout_loglik(self, encounters: pd.DataFrame, *, decision_step_s: float,
                       where: str) -> tuple[float, float]:
        """``log 1`` per decision of ``action`` at ``decision_step_s``, ``-inf`` for any other."""
        p = np.zeros(N_ACTIONS)
        p[int(self.action)] = 1.0
        return state_independent_loglik(p, encounters, decision_step_s=decision_step_s, where=where)


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

    @property
    def decision_step_s(self) -> None:
        """Any step (SUMO's driver acts every simulation step; the controller only observes)."""
        return None

    def probs(self, obs: MergeObservation) -> np.ndarray:
        return np.full(N_ACTIONS, 1.0 / N_ACTIONS)

    def heldout_loglik(self, encounters: pd.DataFrame, *, decision_step_s: float,
                       where: str) -> tuple[float, float]:
        """NaN, NaN: SUMO's driver has no likelihood over the five actions."""
        return NO_LIKELIHOOD


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
                   decision_step_s=float(model.decision_step_s),
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

    def heldout_loglik(self, encounters: pd.DataFrame, *, decision_step_s: float,
                       where: str) -> tuple[float, float]:
        """``log pi(a|s)`` over the held-out decisions in the model's own bins, state encoding and
        decision step (``decision_step_s``, the evaluation's, is not used)."""
        d = discretize(encounters, self.encoder, where=where, encoding=self.state_encoding,
                       decision_step_s=self.decision_step_s)
        s, a, _ = d.flat()
        return heldout_loglik(self.log_pi, s, a)


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
        decision_step_s: the step the baseline was fitted at (None: any; scored at the
            evaluation's).

    ``markov`` scores ``pi(a | a_prev)`` with ``obs.prev_action`` (A's previous action in the
    closed loop) and falls back to the first-step table (the marginal) without one.
    """

    baseline: BaselinePolicy
    encoder: MergeBins
    name: str = ""
    controls: bool = True
    action_acc_ft_s2: tuple[float, ...] = tuple(float(x) for x in ACTION_ACC_FT_S2)
    decision_step_s: float | None = None

    def __post_init__(self) -> None:
        if not self.name:
            object.__setattr__(self, "name", self.baseline.name)

    def probs(self, obs: MergeObservation) -> np.ndarray:
        b = self.baseline
        if b.log_next is not None and 0 <= obs.prev_action < N_ACTIONS:
            return np.exp(b.log_next[obs.prev_action])
        s = obs.state if 0 <= obs.state < b.log_first.shape[0] else 0
        return np.exp(b.log_first[s])

    def heldout_loglik(self, encounters: pd.DataFrame, *, decision_step_s: float,
                       where: str) -> tuple[float, float]:
        """The baseline's log-likelihood of the held-out decisions in its bins, at its own step
        (else ``decision_step_s``); ``markov`` scores a trajectory's first step by its marginal."""
        d = discretize(encounters, self.encoder, where=where,
                       decision_step_s=self.decision_step_s if self.decision_step_s is not None else decision_step_s)
        n = sum(len(x) for x in d.actions)
        total = float(self.baseline.loglik(d))
        return total, total / n if n else float("nan")


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

    def heldout_loglik(self, encounters: pd.DataFrame, *, decision_step_s: float, where: str,
                       cf_decisions: CFDecisions | None = None) -> tuple[float, float]:
        """The model's log-likelihood of the held-out decisions at its own step
        (``decision_step_s``, the evaluation's, is not used). ``cf_decisions``: those decisions
        when already taken (:func:`~irl.domains.merge.car_following.car_following_decisions` of
        ``encounters`` at the model's step), so several drivers of one step share them."""
        dec = cf_decisions if cf_decisions is not None else car_following_decisions(
            encounters, decision_step_s=self.decision_step_s, where=where)
        total = self.model.loglik_of(dec)
        return total, total / dec.n
