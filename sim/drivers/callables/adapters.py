"""The two adapters: any callable ``obs -> action`` as a closed-loop driver (:class:`DriverFromCallable`),
and any driver as such a callable (:class:`CallableFromDriver`).

The observation a callable sees is the continuous merge observation of car A,
``MergeObservation.continuous()[0]``: ``[7]`` float64, columns
:data:`sim.drivers.observe.CONTINUOUS_NAMES` (``d_AC, v_AC, d_AB, v_AB, v_A, len_C, len_B``; ft and ft/s,
:data:`sim.drivers.observe.CONTINUOUS_UNITS`; ``d_AC``, ``v_AC`` and ``len_C`` NaN without a lead car C).
What it returns is one of:

* a **discrete action**: an integer ``0..4``, the merge action in the controller's order (High
  Brake, Low Brake, Zero, Low Accel, High Accel; :mod:`irl.domains.merge.actions`), applied at
  the policy's ``action_acc_ft_s2`` (by default the bins' midpoints) as every tabular driver's;
* a **continuous action**: a float, A's acceleration in m/s^2, applied as it is (a deceleration
  capped at A's emergency deceleration by the controller, as for every driver).

Numpy scalars and one-element arrays count as their element (Stable-Baselines3's ``predict``
returns a ``()`` or ``(1,)`` array): integer dtypes are discrete actions, float dtypes
continuous ones. An object with a ``predict(obs, deterministic=True)`` method returning
``(action, state)`` (Stable-Baselines3's and imitation's policies) is called through it.

* :class:`DriverFromCallable` wraps such a callable into :class:`sim.drivers.policy.Policy`, so the controller
  (and ``merge-irl evaluate --policy module:callable[:name]``) drives with it.
* :func:`~sim.drivers.callables.specs.load_callable` resolves a ``module:callable[:name]`` spec (a dotted module or a path to a
  ``.py`` file; :mod:`sim.drivers.callables.specs`); a :class:`DriverFromCallable` built from a spec
  pickles as its spec, so evaluation workers (fresh processes) import the callable again instead
  of pickling it. What a callable returns is checked by
  :func:`~sim.drivers.callables.actions.parse_action`.
* :class:`CallableFromDriver` goes the other way: any :class:`sim.drivers.policy.Policy` (a learned model, a
  driver file's policy) as a callable ``obs [7] -> int`` (the action index), e.g. for the
  Gymnasium environment; ``sim.drivers.formats.policy_callable`` builds one from a file.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from irl.domains.merge.actions import ACTION_ACC_FT_S2, N_ACTIONS, ZERO_ACTION, action_of
from merge_irl.units import FT_PER_M
from sim.drivers.callables.actions import act_of, parse_action
from sim.drivers.callables.limits import DEFAULT_DECISION_LIMIT_S, call_with_limit, check_limit
from sim.drivers.callables.messages import one_line
from sim.drivers.callables.specs import CallableSpec, load_callable
from sim.drivers.observe import CONTINUOUS_NAMES, MergeObservation, policy_observation, unfill_policy_row
from sim.drivers.policy import (
    NO_LIKELIHOOD,
    Policy,
    PolicyDefaults,
    PolicyError,
    check_policy,
    choose_action,
    fitted_decision,
)

#: A vehicle at least this long (ft) is taken as a truck when only the continuous observation
#: is known (:class:`CallableFromDriver` encoding a tabular state): 8 m, between the presets' cars
#: (4.5-5 m) and trucks (12 m). A heuristic: the controller itself reads B's vehicle class.
TRUCK_MIN_LENGTH_FT = 8.0 * FT_PER_M

__all__ = ["CallableFromDriver", "CallablePolicy", "DriverFromCallable", "PolicyCallable", "TRUCK_MIN_LENGTH_FT"]


# -- callable -> Policy -----------------------------------------------------------------------
@dataclass(frozen=True)
class DriverFromCallable(PolicyDefaults):
    """A callable ``obs [7] -> action`` (see the module docstring) as a :class:`sim.drivers.policy.Policy`.

    At each decision the controller asks :meth:`probs` (one-hot on the returned action, or on the
    bin of the returned acceleration) and then :meth:`acceleration` of the same observation: the
    callable is called once per decision. :meth:`heldout_loglik` scores the held-out decisions by the
    callable's action distribution when it exposes one (Stable-Baselines3's ``get_distribution``, a
    ``probs(obs)`` method: :mod:`sim.drivers.action_distribution`); a rule that returns an action
    only has no likelihood, ``(NaN, NaN)``.

    Attributes:
        fn: the callable (or an object with ``predict(obs, deterministic=True)``).
        name: label in reports.
        spec: the ``module:callable:name`` spec it was loaded from ("" when built from an object);
            with a spec, the policy pickles as :meth:`from_spec` of it (fresh worker processes
            import the callable again).
        source: the file it came from ("" when unknown).
        decision_step_s: seconds between decisions (None: any; the evaluation's).
        action_acc_ft_s2: ``[5]`` acceleration applied for each discrete action (ft/s^2).
        obs_stats: a ``VecNormalize.save`` file whose observation statistics normalise every
            observation before the callable sees it ("" none;
            :func:`sim.drivers.action_distribution.with_vecnormalize`).

    Raises:
        PolicyError (at a decision): see :func:`parse_action`; an exception of the callable is
        re-raised as one, naming the policy.
    """

    fn: Callable[..., Any] = field(compare=False)
    name: str = ""
    spec: str = ""
    source: str = ""
    controls: bool = True
    decision_step_s: float | None = None
    action_acc_ft_s2: tuple[float, ...] = tuple(float(x) for x in ACTION_ACC_FT_S2)
    obs_stats: str = ""
    timeout_s: float = DEFAULT_DECISION_LIMIT_S
    _act: Callable[[np.ndarray], Any] = field(init=False, repr=False, compare=False)
    _last: dict[str, Any] = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if self.obs_stats:
            from sim.drivers.action_distribution import with_vecnormalize

            object.__setattr__(self, "fn", with_vecnormalize(self.fn, self.obs_stats))
        object.__setattr__(self, "_act", act_of(self.fn))
        if not self.name:
            object.__setattr__(self, "name", getattr(self.fn, "__name__", "") or type(self.fn).__name__)
        acc = tuple(float(x) for x in self.action_acc_ft_s2)
        if len(acc) != N_ACTIONS or not all(math.isfinite(a) for a in acc):
            raise PolicyError(f"policy {self.name!r}: action_acc_ft_s2 must be {N_ACTIONS} finite numbers, got {acc}")
        object.__setattr__(self, "action_acc_ft_s2", acc)
        object.__setattr__(self, "timeout_s", check_limit(self.timeout_s))

    @classmethod
    def from_spec(cls, spec: str | CallableSpec, *, name: str = "", **kw: Any) -> DriverFromCallable:
        """The policy of a ``module:callable[:name]`` spec (:func:`load_callable`), named ``name``
        or the spec's name; ``kw``: the other fields.

        Raises:
            PolicyError: see :func:`load_callable`.
        """
        fn, s = load_callable(spec)
        source = s.module if s.is_file else str(getattr(sys.modules.get(s.module), "__file__", "") or "")
        return cls(fn, name=name or s.name, spec=s.text, source=source, **kw)

    def __reduce__(self):
        if not self.spec:  # the callable itself is pickled (a module-level function, a picklable object)
            return (_rebuild, (getattr(self.fn, "fn", self.fn) if self.obs_stats else self.fn, self.name, "",
                               self.source, self.controls, self.decision_step_s, self.action_acc_ft_s2, self.obs_stats,
                               self.timeout_s))
        return (_from_spec, (self.spec, self.name, self.controls, self.decision_step_s, self.action_acc_ft_s2,
                             self.obs_stats, self.timeout_s))

    def _decide(self, obs: MergeObservation) -> tuple[int, float]:
        """``(bin, acceleration ft/s^2 or NaN for a discrete action)`` of ``obs``, called once per observation."""
        if self._last.get("obs") is obs:
            return self._last["bin"], self._last["acc"]
        vec = policy_observation(obs)
        where = f"policy {self.name!r}" + (f" ({self.spec})" if self.spec else "")
        try:
            out = call_with_limit(self._act, vec, self.timeout_s, where=where)
        except PolicyError:
            raise
        except Exception as e:  # the user's callable may raise anything: named, with its message
            raise PolicyError(f"{where}: the callable raised {type(e).__name__}: {one_line(e)}") from e
        a = parse_action(out, where=where)
        if isinstance(a, int):
            b, acc = a, math.nan
        else:
            acc = a * FT_PER_M
            b = action_of(acc)
        self._last.update(obs=obs, bin=b, acc=acc)
        return b, acc

    def probs(self, obs: MergeObservation) -> np.ndarray:
        """``[5]`` one-hot on the returned action (or on the bin of the returned acceleration)."""
        p = np.zeros(N_ACTIONS)
        p[self._decide(obs)[0]] = 1.0
        return p

    def acceleration(self, obs: MergeObservation, action: int) -> float:
        """The returned acceleration (ft/s^2) for its own bin; ``action_acc_ft_s2[action]`` for a
        discrete action and for another bin (a safety filter's replacement)."""
        b, acc = self._decide(obs)
        return acc if action == b and math.isfinite(acc) else float(self.action_acc_ft_s2[action])

    def heldout_loglik(self, encounters: pd.DataFrame, *, decision_step_s: float,
                       where: str) -> tuple[float, float]:
        """``log pi(a|s)`` of the held-out decisions at ``decision_step_s`` (the car-following
        decisions, :func:`irl.domains.merge.car_following.car_following_decisions`, their
        observations as a policy sees them) by the callable's action distribution; NaN, NaN
        when it exposes none."""
        from sim.drivers.action_distribution import action_probs_fn, heldout_probs_loglik

        probs = action_probs_fn(self.fn)
        if probs is None:
            return NO_LIKELIHOOD
        from irl.domains.merge.car_following import car_following_decisions
        from sim.drivers.observe import policy_rows

        dec = car_following_decisions(encounters, decision_step_s=self.decision_step_s or decision_step_s, where=where)
        return heldout_probs_loglik(probs, policy_rows(dec.obs), dec.actions)


def _from_spec(spec: str, name: str, controls: bool, decision_step_s: float | None,
               action_acc_ft_s2: tuple[float, ...], obs_stats: str = "",
               timeout_s: float = DEFAULT_DECISION_LIMIT_S) -> DriverFromCallable:
    return DriverFromCallable.from_spec(spec, name=name, controls=controls, decision_step_s=decision_step_s,
                                    action_acc_ft_s2=action_acc_ft_s2, obs_stats=obs_stats, timeout_s=timeout_s)


def _rebuild(fn: Callable[..., Any], name: str, spec: str, source: str, controls: bool,
             decision_step_s: float | None, action_acc_ft_s2: tuple[float, ...], obs_stats: str = "",
             timeout_s: float = DEFAULT_DECISION_LIMIT_S) -> DriverFromCallable:
    return DriverFromCallable(fn, name=name, spec=spec, source=source, controls=controls,
                          decision_step_s=decision_step_s, action_acc_ft_s2=action_acc_ft_s2, obs_stats=obs_stats,
                          timeout_s=timeout_s)


# -- Policy -> callable -----------------------------------------------------------------------
class CallableFromDriver:
    """A :class:`sim.drivers.policy.Policy` as a callable ``obs -> int`` (the action index 0..4).

    ``obs``: the ``[7]`` (or ``[1, 7]``) continuous observation (:data:`sim.drivers.observe.CONTINUOUS_NAMES`),
    or a whole :class:`sim.drivers.observe.MergeObservation` (then used as it is). From the vector
    alone, what the policy reads beyond it is rebuilt as the controller would have it: A's previous
    action is the last one this callable returned in the episode (:meth:`reset` starts a new
    episode; unknown before the first decision), the acceleration over the previous decision is the
    one the policy applied (its fitted rule's, else :meth:`sim.drivers.policy.Policy.acceleration`), C's acceleration 0 (unknown), B a truck when ``len_B`` is at least
    :data:`TRUCK_MIN_LENGTH_FT`, and the discrete state encoded with the policy's bins
    (``encoder``, ``state_encoding``) when it has them.

    Args:
        policy: the driver (its members checked as the controller checks them).
        mode: take the most likely action (default) instead of sampling one, for a driver
            without a fitted decision rule; a driver with one (``decide``, the planning driver)
            decides by it either way, as in the closed loop
            (:func:`sim.drivers.policy.fitted_decision`).
        seed: the sampling generator's seed (``numpy.random.default_rng``).

    Raises:
        PolicyError: ``policy`` is not a :class:`sim.drivers.policy.Policy`; at a call, an observation
            that is not ``[7]`` numbers.
    """

    def __init__(self, policy: Policy, *, mode: bool = True, seed: int = 0):
        check_policy(policy, scoring=False, where="policy callable")
        self.policy = policy
        self.mode = mode
        self.seed = seed
        self._rng = np.random.default_rng(seed)
        self._prev = -1
        self._prev_acc = math.nan

    def reset(self, seed: int | None = None) -> None:
        """Start a new episode (no previous action); ``seed``: reseed the sampling."""
        self._prev, self._prev_acc = -1, math.nan
        if seed is not None:
            self._rng = np.random.default_rng(seed)

    def observation(self, obs: np.ndarray | MergeObservation) -> MergeObservation:
        """The :class:`~sim.drivers.observe.MergeObservation` the policy is asked about (see the class docstring)."""
        if isinstance(obs, MergeObservation):
            return obs
        x = unfill_policy_row(np.asarray(obs, dtype=np.float64))
        if x.size != len(CONTINUOUS_NAMES):
            raise PolicyError(f"policy callable {self.policy.name!r}: expected an observation of "
                              f"{len(CONTINUOUS_NAMES)} numbers ({', '.join(CONTINUOUS_NAMES)}), got shape "
                              f"{np.shape(obs)}")
        d_ac, v_ac, d_ab, v_ab, v_a, len_c, len_b = (float(v) for v in x)
        truck = bool(math.isfinite(len_b) and len_b >= TRUCK_MIN_LENGTH_FT)
        prev = self._prev
        encoder = self.policy.encoder
        if encoder is None:
            state = -1
        elif self.policy.state_encoding == "paper":
            state = encoder.state(d_ac, d_ab, v_ac, v_ab, truck)
        else:
            state = encoder.state(d_ac, d_ab, v_ac, v_ab, truck, prev_action=prev if prev >= 0 else ZERO_ACTION,
                                  encoding=self.policy.state_encoding)
        return MergeObservation(d_ac, d_ab, v_ac, v_ab, truck, state, v_a, prev, -1, False, len_c, len_b,
                                self._prev_acc, 0.0)

    def __call__(self, obs: np.ndarray | MergeObservation) -> int:
        """The action index ``0..4`` the policy takes at ``obs``."""
        o = self.observation(obs)
        rule = fitted_decision(self.policy, o)  # a driver's fitted rule drives, as in the controller
        if rule is not None:
            self._prev, self._prev_acc = rule
            return rule[0]
        a = choose_action(np.asarray(self.policy.probs(o), dtype=np.float64), self._rng, mode=self.mode)
        self._prev, self._prev_acc = a, float(self.policy.acceleration(o, a))
        return a


#: The old names (still working): ``CallablePolicy`` is :class:`DriverFromCallable` (a callable
#: as a driver), ``PolicyCallable`` is :class:`CallableFromDriver` (a driver as a callable).
CallablePolicy = DriverFromCallable
PolicyCallable = CallableFromDriver
