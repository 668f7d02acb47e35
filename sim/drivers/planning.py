"""The planning driver in the closed loop: a :class:`sim.drivers.policy.Policy` around a learned
:class:`irl.planning.driver.PlanningDriver`.

At each decision the driver sees what a driver sees (:class:`sim.drivers.observe.MergeObservation`):
the gaps and closing speeds to C and B, A's speed, the vehicle lengths, the acceleration it
applied over its previous decision (``acc_prev``) and C's acceleration from C's speed change over
that decision (``acc_C``: brake lights, not C's true acceleration). It plans over its horizon on
a kinematic model. What drives A is the rule its fit selected (:meth:`PlanningDriverPolicy.decide`):
the most likely fine acceleration, as applied, exactly :meth:`PlanningDriver.act` of the
observation (the acceleration the replay fit and the pair scores use), under the physical actuation
(nothing of the simulator's ground truth is read). :meth:`PlanningDriverPolicy.probs`, the
probabilities of the five paper actions (the sums of its fine accelerations' probabilities at the
likelihood temperature in each bin), is the driver's likelihood model: its held-out
log-likelihood and the reports' action distributions, not how it drives (a draw from it is
reachable with ``ControllerConfig(rule="likelihood-draw")``).

The planning driver's format (``merge-irl-planner/...``, ``merge-irl learn-driver``) is
registered here in the driver-format registry (:mod:`sim.drivers.formats`): its policy, its
replay of car-following pairs (:meth:`PlanningDriver.act`) and its reward for the environment
(:class:`PlanningReward`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from irl.domains.merge.actions import N_ACTIONS, actions_of
from irl.planning.decisions import encounter_decisions
from irl.planning.driver import PLANNER_FORMAT, PlanningDriver
from sim.drivers.formats import DriverFormat, family_of
from sim.drivers.observe import MergeObservation
from sim.drivers.policy import PolicyDefaults


@dataclass(frozen=True)
class PlanningDriverPolicy(PolicyDefaults):
    """A learned planning driver as a closed-loop policy.

    Attributes:
        driver: the learned driver (``merge-irl learn-driver``'s file, format ``merge-irl-planner/1``;
            ``sim.drivers.formats.driver_policy`` builds the policy of a file).
        name: label in reports (the file's stem when read from one).
        source: the file it was read from ("" when built in code).
        flags: ``("not_converged",)`` when the driver's fit did not converge.
        action_acc_ft_s2: ``[5]`` the training data's mean acceleration per paper action
            (ft/s^2), applied for a bin the driver's fine grid does not cover.
    """

    driver: PlanningDriver
    name: str = "planner"
    controls: bool = True
    source: str = ""
    flags: tuple[str, ...] = field(init=False, default=())
    action_acc_ft_s2: tuple[float, ...] = field(init=False, default=())
    _last: dict[str, Any] = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "flags", () if self.driver.converged else ("not_converged",))
        object.__setattr__(self, "action_acc_ft_s2", tuple(self.driver.action_acc_ft_s2))

    @property
    def decision_step_s(self) -> float:
        """Seconds per decision the driver was trained at."""
        return self.driver.decision_step_s

    def _fine_log_policy(self, obs: MergeObservation) -> np.ndarray:
        """``[G]`` log-probabilities of the fine accelerations at ``obs`` (the controller asks
        :meth:`probs` and then :meth:`acceleration` of one observation: planned once)."""
        if self._last.get("obs") is obs:
            return self._last["lp"]
        prev = obs.acc_prev if math.isfinite(obs.acc_prev) else 0.0
        acc_c = obs.acc_C if math.isfinite(obs.acc_C) else 0.0
        lp = self.driver.fine_log_policy(obs.continuous(), np.array([prev]), np.array([acc_c]),
                                         np.array([bool(obs.b_merged)]))[0]
        grid = self.driver.fine_grid
        applied = self.driver.applied(grid, np.full(grid.size, prev))  # the grid itself unless a lag
        self._last.update(obs=obs, lp=lp, applied=applied, bins=actions_of(applied))
        return lp

    def decide(self, obs: MergeObservation) -> tuple[int, float] | None:
        """The driver's fitted decision rule at ``obs``: ``(paper action, acceleration ft/s^2)``.

        A driver fitted by replay (``info["fit"] == "replay"``, ``merge-irl learn-driver --fit
        replay``) was selected for what its most likely acceleration does: its rule is that
        acceleration as applied (:meth:`PlanningDriver.act` of the observation, ``acc_prev``/
        ``acc_C`` unknown read as 0, ``b_merged`` the observation's) and its bin. A driver fitted
        by likelihood was fitted as the stochastic policy :meth:`probs`: None, and the controller
        draws from it as the fit scored it.
        """
        if self.driver.info.get("fit") != "replay":
            return None
        lp = self._fine_log_policy(obs)
        g = int(np.argmax(lp))
        return int(self._last["bins"][g]), float(self._last["applied"][g])

    def probs(self, obs: MergeObservation) -> np.ndarray:
        """``[5]`` probabilities of the paper actions, the driver's likelihood model (what its
        held-out log-likelihood scores; it drives by :meth:`decide`): the sums over the fine
        accelerations in each bin."""
        p = np.exp(self._fine_log_policy(obs))
        out = np.zeros(N_ACTIONS)
        np.add.at(out, self._last["bins"], p)
        return out / out.sum()

    def acceleration(self, obs: MergeObservation, action: int) -> float:
        """The driver's most likely fine acceleration (ft/s^2) within the bin ``action`` at
        ``obs`` (for the bin of :meth:`decide`, its acceleration; for another bin, one a safety
        filter or a draw from the likelihood model chose), as applied (under an actuation lag, :meth:`PlanningDriver.applied`; the paper
        action is the bin of the applied acceleration), or the training mean of the bin when no
        fine acceleration lies in it."""
        lp = self._fine_log_policy(obs)
        inside = np.flatnonzero(self._last["bins"] == action)
        if inside.size == 0:
            return float(self.action_acc_ft_s2[action])
        return float(self._last["applied"][inside[np.argmax(lp[inside])]])

    def heldout_loglik(self, encounters: pd.DataFrame, *, decision_step_s: float,
                       where: str) -> tuple[float, float]:
        """``(sum, per decision)`` of ``log P(paper action | x)`` over the held-out encounters'
        decisions at the driver's own step (:func:`irl.planning.decisions.encounter_decisions`)."""
        dec = encounter_decisions(encounters, self.driver.decision_step_s, where=where)
        lp = self.driver.bin_log_policy(dec.obs, dec.prev_acc, dec.acc_C)[np.arange(dec.n), dec.actions]
        total = float(lp.sum())
        return total, total / dec.n if dec.n else float("nan")


@dataclass(frozen=True)
class PlanningReward:
    """The planning driver's learned reward of one decision step as the environment's reward,
    ``theta . phi(x, acc)`` plus its collision penalty
    (:meth:`~irl.planning.driver.PlanningDriver.step_reward`)."""

    driver: PlanningDriver
    name: str = "planner"

    @property
    def action_acc_ft_s2(self) -> tuple[float, ...]:
        """``[5]`` the training data's mean acceleration per paper action (ft/s^2)."""
        return self.driver.action_acc_ft_s2

    def __call__(self, obs: MergeObservation, action: int, acc_ft_s2: float) -> float:
        prev = obs.acc_prev if np.isfinite(obs.acc_prev) else 0.0
        return float(self.driver.step_reward(obs.continuous(), np.array([prev]), np.array([obs.acc_C]),
                                             np.array([acc_ft_s2]))[0])


#: The planning driver's format (registered lazily in :data:`sim.drivers.formats.FORMATS`).
PLANNER_DRIVER_FORMAT = DriverFormat(
    family_of(PLANNER_FORMAT), "planning driver ('merge-irl learn-driver')", load=PlanningDriver.load,
    parse=PlanningDriver.from_json_dict,
    policy=lambda driver, name, source: PlanningDriverPolicy(driver, name=name, source=source),
    replay_act=lambda driver: (driver.act, driver.decision_step_s), reward=PlanningReward)
