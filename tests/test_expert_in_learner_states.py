"""benchmarks/expert_in_learner_states.py: the logit's gradient, its fit, and the SUMO expert's labels."""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks.expert_in_learner_states import ExpertLabels, fit_logit, logit_nll
from irl.domains.merge_actions import N_ACTIONS, action_of
from irl.domains.merge_bins import MergeBins
from irl.domains.merge_states import n_states
from scenarios.loader import load_scenario
from sim.controller import Controller
from sim.controller_config import ControllerConfig
from sim.policy import LearnedPolicy
from sim.run import run_scenario


def test_logit_gradient_matches_finite_differences():
    rng = np.random.default_rng(0)
    Fs, a = rng.normal(size=(40, N_ACTIONS, 3)), rng.integers(0, N_ACTIONS, 40)
    theta = rng.normal(size=3)
    _, g = logit_nll(theta, Fs, a, 0.7)
    h = 1e-6
    fd = [(logit_nll(theta + h * e, Fs, a, 0.7)[0] - logit_nll(theta - h * e, Fs, a, 0.7)[0]) / (2 * h)
          for e in np.eye(3)]
    np.testing.assert_allclose(g, fd, rtol=1e-6, atol=1e-6)


def test_fit_logit_recovers_the_weights_of_its_own_samples():
    rng = np.random.default_rng(1)
    F = rng.normal(size=(50, N_ACTIONS, 2))
    truth = np.array([1.5, -0.8])
    s = rng.integers(0, 50, 20000)
    u = F[s] @ truth
    p = np.exp(u - u.max(1, keepdims=True))
    p /= p.sum(1, keepdims=True)
    a = (p.cumsum(1) > rng.random(len(s))[:, None]).argmax(1)
    np.testing.assert_allclose(fit_logit(F, s, a, 0.0), truth, atol=0.08)


@pytest.mark.sumo
def test_expert_labels_every_decision_and_brakes_for_a_driver_that_only_accelerates():
    """A driver that always takes High Accel closes in on its lead car: the expert (SUMO's car
    following of A's type) labels every decision, and asks for braking in some of them."""
    bins = MergeBins.assumed_authors()
    log_pi = np.full((n_states("driver"), N_ACTIONS), -50.0)
    log_pi[:, 4] = 0.0  # High Accel
    pol = LearnedPolicy(log_pi=log_pi, encoder=bins, name="gas", decision_step_s=0.3, state_encoding="driver")
    ctl = Controller(pol, ControllerConfig(decision_s=0.3))
    hook = ExpertLabels(ctl)
    run_scenario(load_scenario("synthetic"), seed=3, duration_s=120, hooks=[ctl, hook])
    n_decisions = len(ctl.decision_table())
    assert n_decisions > 50
    assert len(hook.labels) == n_decisions
    states, actions = np.array(hook.labels).T
    assert np.all((states >= 0) & (states < n_states("driver")))
    assert (actions <= action_of(-6.0)).any(), "the expert never brakes behind a car A runs into"
    assert (actions == 4).any(), "the expert never accelerates"
