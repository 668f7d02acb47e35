"""The learned drivers of the closed loop: tabular IRL models (:class:`LearnedPolicy`), the
fitted tabular baselines (:class:`BaselineTabularPolicy`) and the car-following logit
(:class:`CarFollowingLogitPolicy`), each a :class:`sim.drivers.policy.Policy`.

* :class:`LearnedPolicy`: ``softmax(beta Q(s, .))`` of a saved IRL model (Q-Avg, Q-SM, MLIRL,
  REIRL), discretising with the model's own bin edges.
* :class:`BaselineTabularPolicy`: ``marginal``, ``markov`` or ``bc`` fitted on the training
  demonstrations (:mod:`irl.baselines`); ``markov`` conditions on A's previous action.
* :class:`CarFollowingLogitPolicy`: a :class:`irl.domains.merge.cf_logit.CarFollowingLogit`
  driver on the continuous observation (A's speed, gaps, closing speeds, previous action).
* :class:`TabularReward`: a tabular model's ``theta . phi(s, a)`` as the environment's reward.

Two formats of the driver-format registry (:mod:`sim.drivers.formats`) are registered here: the
tabular IRL model (``merge-irl-model/...``, ``merge-irl learn``; given to ``--model``) and the
car-following logit (``merge-irl-cf-logit/...``, ``merge-irl dagger``; a driver).
"""

from __future__ import annotations

from collections.abc import Hashable, MutableMapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from irl.boltzmann import heldout_loglik
from irl.domains.merge.actions import ACTION_ACC_FT_S2, N_ACTIONS, actions_of
from irl.domains.merge.bins import MergeBins
from irl.domains.merge.car_following import CFDecisions, car_following_decisions
from irl.domains.merge.cf_logit import CF_FORMAT, CarFollowingLogit
from irl.domains.merge.features import feature_set
from irl.domains.merge.mdp import discretize
from irl.errors import ConfigError
from irl.planning.replay import ActFn
from irl.result import MODEL_FORMAT, SavedModel
from merge_irl.units import FRAME_S
from sim.drivers.formats import DriverFormat, family_of
from sim.drivers.policy import PolicyDefaults, PolicyError

if TYPE_CHECKING:  # pragma: no cover
    from irl.baselines import BaselinePolicy
    from sim.drivers.observe import MergeObservation

@dataclass(frozen=True)
class LearnedPolicy(PolicyDefaults):
    """``pi(a|s) = softmax(beta Q(s, .))`` of a learned IRL model.

    Attributes:
        log_pi: ``[S, 5]`` log-policy table (``SavedModel.log_policy()``).
        encoder: the state bins the model was trained with (:class:`irl.domains.merge.bins.MergeBins`,
            the one merge-state encoder; see :meth:`from_model`).
        name: label (e.g. the method).
        action_acc_ft_s2: ``[5]`` acceleration applied for each action (ft/s^2): the model's
            conditional mean of each action bin in its training data (bin midpoints overstated braking);
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
    decision_step_s: float = FRAME_S  # a model file without the field: the 0.1 s frame
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
class BaselineTabularPolicy(PolicyDefaults):
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
class CarFollowingLogitPolicy(PolicyDefaults):
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
    #: ``("not_converged",)`` when the model's optimiser did not converge (:func:`model_flags`' name)
    flags: tuple[str, ...] = field(init=False, default=())
    #: ``[5]`` acceleration applied per action (ft/s^2), the model's
    action_acc_ft_s2: tuple[float, ...] = field(init=False, default=())

    def __post_init__(self) -> None:
        # what the model's fit reported, named as model_flags names it
        object.__setattr__(self, "flags", () if self.model.converged else ("not_converged",))
        object.__setattr__(self, "action_acc_ft_s2", tuple(float(x) for x in self.model.action_acc_ft_s2))

    @property
    def decision_step_s(self) -> float:
        """Seconds per decision the model was trained at."""
        return self.model.decision_step_s

    def probs(self, obs: MergeObservation) -> np.ndarray:
        """``[5]`` action probabilities at ``obs``.

        Raises:
            PolicyError: A's speed or ``d_AB``/``v_AB`` is not finite.
        """
        if not all(np.isfinite([obs.speed_A, obs.d_AB, obs.v_AB])):
            raise PolicyError(f"policy {self.name!r}: A's speed, d_AB and v_AB must be finite, got "
                              f"{obs.speed_A}, {obs.d_AB}, {obs.v_AB}")
        prev = obs.prev_action if obs.prev_action >= 0 else obs.initial_action
        return np.exp(self.model.log_policy(obs.continuous(), np.array([prev]))[0])

    def heldout_inputs(self, encounters: pd.DataFrame, *, where: str,
                       cache: MutableMapping[Hashable, Any]) -> dict[str, Any]:
        """The held-out car-following decisions at the model's step, taken once per step for
        every car-following driver scored on the same table (``cache``)."""
        key = ("car-following decisions", self.decision_step_s)
        if key not in cache:
            cache[key] = car_following_decisions(encounters, decision_step_s=self.decision_step_s, where=where)
        return {"cf_decisions": cache[key]}

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


@dataclass(frozen=True)
class TabularReward:
    """``r(s, a) = theta . phi(s, a)`` of a tabular model as the environment's reward;
    ``phi`` is ``[S, 5, K]`` (the model's feature set on its bins, encoding, decision step and
    action accelerations).

    Attributes:
        theta: ``[K]`` weights; phi: ``[S, 5, K]``; encoder: the model's state bins (the
            environment encodes states with them); state_encoding: ``"paper"`` or ``"driver"``;
        action_acc_ft_s2: ``[5]`` the model's per-action accelerations (ft/s^2; the discrete
            actions apply them).
    """

    theta: np.ndarray
    phi: np.ndarray
    encoder: MergeBins
    state_encoding: str = "paper"
    action_acc_ft_s2: tuple[float, ...] = ()
    name: str = "tabular"
    _r: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "_r", np.einsum("sak,k->sa", self.phi, self.theta))

    @classmethod
    def from_model(cls, model: SavedModel) -> TabularReward:
        """From a saved merge model (its ``bin_edges``, ``feature_set`` or ``feature_names``).

        Raises:
            PolicyError: the model has no bin edges or its features do not match ``theta``.
        """
        if not model.bin_edges:
            raise PolicyError(f"model {model.method!r} has no 'bin_edges': its reward needs the state bins")
        bins = MergeBins.from_dict(dict(model.bin_edges), where=f"model {model.method!r} bin_edges")
        names = model.feature_names or model.feature_set or "paper"
        # as training built them (irl.problems): the model's step, the actions' nominal accelerations
        fs = feature_set(names, bins, model.state_encoding, decision_step_s=model.decision_step_s)
        theta = np.asarray(model.theta, dtype=np.float64)
        if fs.array.shape[-1] != theta.shape[0]:
            raise PolicyError(f"model {model.method!r}: theta has {theta.shape[0]} weights, its features "
                              f"{fs.names} {fs.array.shape[-1]}")
        return cls(theta, fs.array, bins, model.state_encoding, tuple(model.action_acc_ft_s2), model.method)

    def __call__(self, obs: MergeObservation, action: int, acc_ft_s2: float) -> float:
        """The reward of ``action`` in ``obs.state``.

        Raises:
            PolicyError: the observation has no state index.
        """
        if obs.state < 0:
            raise PolicyError("TabularReward: the observation has no state index (the environment encodes "
                              "states with this reward's encoder)")
        return float(self._r[obs.state, action])


def cf_replay_act(cf: CarFollowingLogit) -> tuple[ActFn, float]:
    """``(act, decision_step_s)``: the logit's most likely action at its per-action acceleration,
    A's previous action taken as the bin of the acceleration it applied (unknown: none)."""
    acc = np.asarray(cf.action_acc_ft_s2, dtype=np.float64)

    def act(obs: np.ndarray, prev_acc: np.ndarray, acc_C: np.ndarray) -> np.ndarray:
        known = np.isfinite(prev_acc)
        prev = np.where(known, actions_of(np.where(known, prev_acc, 0.0)), -1)
        return acc[np.argmax(cf.log_policy(obs, prev), axis=1)]

    return act, cf.decision_step_s


#: The tabular IRL model's driver format (registered lazily in :data:`sim.drivers.formats.FORMATS`).
MODEL_DRIVER_FORMAT = DriverFormat(
    family_of(MODEL_FORMAT), "tabular IRL model ('merge-irl learn')", load=SavedModel.load,
    parse=SavedModel.from_json_dict,
    policy=lambda model, name, source: LearnedPolicy.from_model(model, name=name or model.method),
    reward=TabularReward.from_model, role="model")

#: The car-following logit's driver format (registered lazily in :data:`sim.drivers.formats.FORMATS`).
CF_DRIVER_FORMAT = DriverFormat(
    family_of(CF_FORMAT), "car-following logit ('merge-irl dagger')", load=CarFollowingLogit.load,
    parse=CarFollowingLogit.from_json_dict,
    policy=lambda cf, name, source: CarFollowingLogitPolicy(cf, name=name, source=source),
    replay_act=cf_replay_act)
