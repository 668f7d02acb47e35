"""Drivers (policies) of a controlled vehicle: observation -> distribution over the 5 actions.

:class:`Driver` is the protocol every driver implements (``Policy`` is its old name, kept as an
alias).

A policy maps the merge observation of car A (:class:`sim.drivers.observe.MergeObservation`: the four
continuous variables, B's truck flag and the discrete state) to probabilities over the merge
domain's five acceleration actions (High Brake, Low Brake, Zero, Low Accel, High Accel): the
driver's *likelihood model*, what its held-out log-likelihood and the reports' action
distributions score. A driver fitted with a decision rule of its own (the planning driver: its most
likely fine acceleration, as the replay fit selects it) declares it as :meth:`PolicyDefaults.decide`
``(obs) -> (paper action, acceleration ft/s^2)``, and that rule drives A
(:func:`fitted_decision`). A driver without one (``decide`` returns None: the tabular IRL models,
fitted as stochastic policies) drives by its probabilities: the controller samples an action (or
takes the mode) and applies :data:`irl.domains.merge.actions.ACTION_ACC_FT_S2`, the representative
acceleration of each action bin, or the driver's own :meth:`Driver.acceleration` (the action bins
and names are :mod:`irl.domains.merge.actions`', the state encoding
:mod:`irl.domains.merge.states`').

Policies in the same harness:

* :class:`SumoPolicy`: the baseline; the vehicle is *not* taken over, SUMO's car-following
  model drives it (``controls = False``); the controller still observes it.
* :class:`UniformPolicy`: uniform random over the 5 actions.
* :class:`ConstantPolicy`: always the same action (e.g. always brake hard, for tests).

The learned drivers are in :mod:`sim.drivers.learned` (tabular IRL models, the fitted tabular
baselines, the car-following logit) and :mod:`sim.drivers.planning` (the planning driver).

Every policy scores held-out demonstrations itself (:meth:`Driver.heldout_loglik`), as learning
sees them; the evaluation reads that number and nothing else of the policy's kind
(:func:`analysis.evaluation.heldout_scoring.policy_heldout_loglik`).
"""

from __future__ import annotations

from bisect import bisect_right
from collections.abc import Hashable, MutableMapping
from dataclasses import dataclass
from itertools import accumulate
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

import numpy as np
import pandas as pd

from irl.domains.merge.actions import ACTION_ACC_FT_S2, ACTION_NAMES, N_ACTIONS
from irl.domains.merge.bins import MergeBins
from irl.domains.merge.mdp import discretize
from sim.errors import SimError

if TYPE_CHECKING:  # pragma: no cover
    from sim.drivers.observe import MergeObservation

#: ``(sum, per step)`` of a policy without a likelihood (SUMO's driver, the deterministic IDM).
NO_LIKELIHOOD = (float("nan"), float("nan"))


class PolicyError(SimError, ValueError):
    """A policy cannot be built from its inputs (e.g. a model that is not a merge model), or
    answered what no driver can (a callable's bad return).

    ``retry = False``: the same inputs fail the same way, so a sweep does not run the task again
    (:func:`analysis.sweep.worker.call_task`).
    """

    retry = False


@runtime_checkable
class Driver(Protocol):
    """What drives A: observation -> action distribution, and the driver's own held-out score.

    ``Driver`` is the protocol's name (the word for what drives A); :data:`Policy` is the same
    protocol under its old name, and the classes that implement it keep ``Policy`` in theirs.

    Everything the controller and the evaluation read of a policy is declared here.

    Attributes:
        name: label used in reports and logs.
        controls: False when the vehicle is left to SUMO (the baseline); the controller then
            only observes it.
        decision_step_s: seconds per decision the driver was trained at; None: any step (the
            controller then decides every
            :data:`irl.domains.merge.mdp.DEFAULT_DECISION_STEP_S`, unless told otherwise).
        keep_lane: keep A in its lane while observed (lane-change mode 0) even when not commanded.
        encoder: the state bins the controller encodes the observation's discrete state with
            (None: no state, -1), with ``state_encoding`` (``"paper"`` or ``"driver"``).
        flags: warnings the evaluation reports beside the driver's row (e.g. not converged).
        source: the file the driver was read from ("" when built in code).

    :class:`PolicyDefaults` gives every member but ``name``, ``controls``, ``decision_step_s``,
    ``probs`` and ``heldout_loglik`` a default; the policies here inherit it.

    Two optional members, read when present (so a class without them still is a ``Policy``):

    * ``heldout_inputs(encounters, *, where, cache) -> dict``, extra keyword arguments of
      :meth:`heldout_loglik` prepared from the held-out encounters, so that work several policies
      need (the car-following decisions at one step) is done once: ``cache`` is one dict shared by
      every policy scored on the same held-out table (:meth:`PolicyDefaults.heldout_inputs`: none).
    * ``decide(obs) -> (action, acc_ft_s2) | None``, the driver's *fitted decision rule*: the
      paper action (0..4, the bin of the acceleration) and the acceleration (ft/s^2) the driver
      applies at ``obs``, the rule its fit selected. When it answers, that is what drives A
      (:func:`fitted_decision`); ``probs`` stays the driver's likelihood model (held-out scores,
      action distributions). None (:meth:`PolicyDefaults.decide`): no rule of its own; the
      controller draws from ``probs`` (or takes its mode).
    """

    # read-only properties, so frozen dataclasses (the policies here) satisfy the protocol
    @property
    def name(self) -> str: ...

    @property
    def controls(self) -> bool: ...

    @property
    def decision_step_s(self) -> float | None: ...

    @property
    def keep_lane(self) -> bool: ...

    @property
    def encoder(self) -> MergeBins | None: ...

    @property
    def state_encoding(self) -> str: ...

    @property
    def flags(self) -> tuple[str, ...]: ...

    @property
    def source(self) -> str: ...

    def probs(self, obs: MergeObservation) -> np.ndarray:
        """``[5]`` action probabilities (sum to 1): the driver's likelihood model (what drives A
        unless the driver has a fitted decision rule, ``decide``)."""
        ...

    def acceleration(self, obs: MergeObservation, action: int) -> float:
        """The acceleration (ft/s^2) the driver applies for ``action`` (a paper bin) in ``obs``."""
        ...

    def heldout_loglik(self, encounters: pd.DataFrame, *, decision_step_s: float,
                       where: str) -> tuple[float, float]:
        """``(sum, per step)`` log-likelihood (nats) of held-out encounter frames under the
        policy, scored as learning sees them: resampled at a decision step
        (:func:`irl.domains.merge.mdp.discretize`; ``decision_step_s``, the evaluation's, unless
        the policy has its own), so an action is the forward difference of A's speed over one
        decision. ``(NaN, NaN)`` where no likelihood exists (:data:`NO_LIKELIHOOD`).
        ``encounters``: prepared frames
        (:func:`irl.domains.merge.encounters.prepare_encounters`); ``where`` names them
        in errors.

        Raises:
            DemonstrationError: the frames cannot be resampled (e.g. every encounter shorter
                than one decision step).
        """
        ...


#: The old name of :class:`Driver` (the same protocol; ``isinstance(x, Policy)`` works as before).
Policy = Driver

#: What the controller reads of every policy (the evaluation also reads ``heldout_loglik``).
CONTROLLER_MEMBERS = ("name", "controls", "decision_step_s", "keep_lane", "encoder", "state_encoding", "flags",
                      "source", "probs", "acceleration")


class PolicyDefaults:
    """The defaults of a :class:`Policy`'s optional members: kept in lane only when commanded, no
    discrete state, no flags, no source file, and each action applied at the paper bin's
    midpoint (:data:`irl.domains.merge.actions.ACTION_ACC_FT_S2`, or the policy's own
    ``action_acc_ft_s2`` where it has one). Inherit it and declare what differs."""

    keep_lane: bool = False
    encoder: MergeBins | None = None
    state_encoding: str = "paper"
    flags: tuple[str, ...] = ()
    source: str = ""
    action_acc_ft_s2: tuple[float, ...] = tuple(float(x) for x in ACTION_ACC_FT_S2)

    def acceleration(self, obs: MergeObservation, action: int) -> float:
        """``action_acc_ft_s2[action]`` (ft/s^2), whatever the observation."""
        return float(self.action_acc_ft_s2[action])

    def heldout_inputs(self, encounters: pd.DataFrame, *, where: str,
                       cache: MutableMapping[Hashable, Any]) -> dict[str, Any]:
        """No extra inputs to :meth:`Policy.heldout_loglik`."""
        return {}

    def decide(self, obs: MergeObservation) -> tuple[int, float] | None:
        """None: no fitted decision rule of the driver's own (it drives by its probabilities,
        :meth:`Driver.probs`, drawn or at their mode)."""
        return None


def missing_members(policy: object, *, scoring: bool = True) -> list[str]:
    """The members of :class:`Policy` that ``policy`` lacks (``heldout_loglik`` only when
    ``scoring``); empty: it has them all."""
    names = [*CONTROLLER_MEMBERS] + (["heldout_loglik"] if scoring else [])
    return [n for n in names if not hasattr(policy, n)]


def check_policy(policy: object, *, scoring: bool = True, where: str = "") -> None:
    """Refuse an object that does not declare what the controller (and, with ``scoring``, the
    held-out evaluation) reads of a :class:`Policy`.

    Raises:
        PolicyError: a member is missing (named, with the class).
    """
    missing = missing_members(policy, scoring=scoring)
    if missing:
        raise PolicyError(f"{where + ': ' if where else ''}{type(policy).__name__} is not a sim.drivers.policy.Policy: it "
                          f"lacks {', '.join(missing)} (a driver declares name, controls, decision_step_s (None: any "
                          "step), probs and heldout_loglik (NaN, NaN without a likelihood); inherit "
                          "sim.drivers.policy.PolicyDefaults for the rest)")


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


def fitted_decision(policy: object, obs: MergeObservation) -> tuple[int, float] | None:
    """``(action, acc_ft_s2)`` of ``policy``'s fitted decision rule at ``obs`` (its ``decide``;
    action 0..4, acceleration in ft/s^2), or None when it has none (no ``decide``, or one that
    answers None).

    Raises:
        PolicyError: ``decide`` answered something else than an action 0..4 and a finite number.
    """
    rule = getattr(policy, "decide", None)
    out = rule(obs) if rule is not None else None
    if out is None:
        return None
    try:
        action, acc = int(out[0]), float(out[1])
    except (TypeError, ValueError, IndexError):
        action, acc = -1, float("nan")
    if not (0 <= action < N_ACTIONS and np.isfinite(acc)):
        raise PolicyError(f"{getattr(policy, 'name', type(policy).__name__)}: decide must return (action 0..4, "
                          f"finite acceleration ft/s^2) or None, got {out!r}")
    return action, acc


def choose_action(probs: np.ndarray, rng: np.random.Generator, *, mode: bool = False) -> int:
    """Sample an action from ``probs [A]`` with ``rng`` (or take the most likely one)."""
    p = np.asarray(probs, dtype=np.float64).tolist()  # five numbers: plain Python is faster than numpy
    if mode:
        return p.index(max(p))  # the first of equal maxima, as argmax
    cdf = list(accumulate(p))  # sequential sums, bit for bit numpy's cumsum
    u = rng.random() * cdf[-1]
    return min(bisect_right(cdf, u), len(p) - 1)


@dataclass(frozen=True)
class UniformPolicy(PolicyDefaults):
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
class ConstantPolicy(PolicyDefaults):
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
class SumoPolicy(PolicyDefaults):
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
