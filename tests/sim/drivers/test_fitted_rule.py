"""A driver's fitted decision rule drives A: the planning driver's closed-loop decision is
:meth:`irl.planning.driver.PlanningDriver.act` of the observation (no SUMO: the controller's
decision path called directly)."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
import pytest
from irl_testdata import planning_encounters

from irl.domains.merge.actions import action_of
from irl.planning.decisions import encounter_decisions
from irl.planning.driver import learn_planning_driver
from irl.planning.model import PlannerConfig
from sim.closed_loop.config import ControllerConfig, ControllerError
from sim.closed_loop.controller import Controller
from sim.drivers.callables import PolicyCallable
from sim.drivers.observe import MergeObservation
from sim.drivers.planning import PlanningDriverPolicy
from sim.drivers.policy import PolicyDefaults, PolicyError, UniformPolicy, fitted_decision


@pytest.fixture(scope="module")
def driver():
    d = encounter_decisions(planning_encounters(n=6))
    fitted = learn_planning_driver(d, selection=PlannerConfig(grid="g13", horizon_s=0.9))
    return replace(fitted, info={**fitted.info, "fit": "replay"})  # a replay-fitted driver's rule: act


def _random_obs(rng: np.random.Generator, n: int) -> list[MergeObservation]:
    out = []
    for _ in range(n):
        acc_prev = float(rng.uniform(-12, 8)) if rng.random() > 0.2 else math.nan
        acc_c = float(rng.uniform(-10, 5)) if rng.random() > 0.2 else math.nan
        out.append(MergeObservation(
            d_AC=float(rng.uniform(5, 250)), d_AB=float(rng.uniform(-80, 80)), v_AC=float(rng.uniform(-15, 15)),
            v_AB=float(rng.uniform(-15, 15)), b_is_truck=bool(rng.random() < 0.2), state=-1,
            speed_A=float(rng.uniform(0, 90)), len_C=15.0, len_B=16.0, acc_prev=acc_prev, acc_C=acc_c))
    return out


class _Commanded:
    commanded = True


def test_the_closed_loop_decision_is_the_fitted_act(driver):
    """Under ``mode`` and sampling alike, the controller's decision is ``act`` of the observation
    (``acc_prev``/``acc_C`` unknown read as 0) and its bin; ``probs`` is still the likelihood model."""
    pol = PlanningDriverPolicy(driver)
    ctls = [Controller(pol, ControllerConfig(mode=m)) for m in (True, False)]
    for ctl in ctls:
        ctl._rng = np.random.default_rng(0)
    obs = _random_obs(np.random.default_rng(1), 300)
    for o in obs:
        prev = o.acc_prev if math.isfinite(o.acc_prev) else 0.0
        acc_c = o.acc_C if math.isfinite(o.acc_C) else 0.0
        want = float(driver.act(o.continuous(), np.array([prev]), np.array([acc_c]), np.array([o.b_merged]))[0])
        assert pol.decide(o) == (action_of(want), want)
        for ctl in ctls:
            probs, action, acc = ctl.decide(_Commanded(), o)  # type: ignore[arg-type]
            assert (action, acc) == (action_of(want), want)
            np.testing.assert_allclose(probs, pol.probs(o))
        # the driver's acceleration for its own bin is the rule's (a safety filter's other bin: its best there)
        assert pol.acceleration(o, action_of(want)) == want


def test_the_likelihood_draw_stays_reachable_and_differs(driver):
    """``rule="likelihood-draw"``: a bin drawn from ``probs`` at the likelihood temperature (not
    always the fitted rule's); a driver without a rule draws under either setting."""
    pol = PlanningDriverPolicy(driver)
    ctl = Controller(pol, ControllerConfig(rule="likelihood-draw"))
    ctl._rng = np.random.default_rng(0)
    obs = _random_obs(np.random.default_rng(2), 300)
    drawn = [ctl.decide(_Commanded(), o) for o in obs]  # type: ignore[arg-type]
    assert all(acc is None for _, _, acc in drawn)
    assert sum(a != pol.decide(o)[0] for (_, a, _), o in zip(drawn, obs)) > 0
    uni = Controller(UniformPolicy())
    uni._rng = np.random.default_rng(0)
    assert fitted_decision(UniformPolicy(), obs[0]) is None
    assert len({uni.decide(_Commanded(), o)[1] for o in obs}) == 5  # type: ignore[arg-type]
    with pytest.raises(ControllerError, match="rule"):
        ControllerConfig(rule="argmax")


def test_the_policy_callable_follows_the_fitted_rule(driver):
    pol = PlanningDriverPolicy(driver)
    for mode in (True, False):
        fn = PolicyCallable(pol, mode=mode, seed=4)
        for o in _random_obs(np.random.default_rng(3), 50):
            assert fn(o) == pol.decide(o)[0]
            assert fn._prev_acc == pol.decide(o)[1]


def test_a_bad_rule_answer_is_refused():
    @dataclass(frozen=True)
    class Bad(PolicyDefaults):
        name: str = "bad"
        controls: bool = True
        decision_step_s: float | None = None

        def probs(self, obs):
            return np.full(5, 0.2)

        def decide(self, obs):
            return (7, 1.0)

        def heldout_loglik(self, encounters, *, decision_step_s, where):
            return (math.nan, math.nan)

    with pytest.raises(PolicyError, match="decide must return"):
        fitted_decision(Bad(), _random_obs(np.random.default_rng(0), 1)[0])


def test_a_driver_fitted_by_likelihood_is_driven_as_the_policy_it_was_fitted_as(driver):
    """Without info['fit'] == 'replay' the fit selected the stochastic policy: decide is None and
    the controller draws from probs."""
    likelihood = PlanningDriverPolicy(replace(driver, info={k: v for k, v in driver.info.items() if k != "fit"}))
    obs = MergeObservation(d_AC=60.0, d_AB=-20.0, v_AC=2.0, v_AB=1.0, b_is_truck=False, speed_A=50.0)
    assert likelihood.decide(obs) is None
    assert PlanningDriverPolicy(driver).decide(obs) is not None
