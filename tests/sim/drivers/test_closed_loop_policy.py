"""Policies, action bins and controller settings (no SUMO)."""

from __future__ import annotations

import numpy as np
import pytest

from irl.config import IRLConfig
from irl.domains.merge.bins import MergeBins
from irl.result import SavedModel
from sim.closed_loop.config import ControllerConfig, ControllerError
from sim.drivers.learned import LearnedPolicy
from sim.drivers.observe import MergeObservation
from sim.drivers.policy import ConstantPolicy, PolicyError, SumoPolicy, UniformPolicy, choose_action
from sim.errors import SimError


def test_choose_action_samples_with_the_generator_and_mode():
    p = np.array([0.1, 0.2, 0.4, 0.2, 0.1])
    a = [choose_action(p, np.random.default_rng(5)) for _ in range(3)]
    assert a[0] == a[1] == a[2]  # same seed, same draw
    rng = np.random.default_rng(0)
    draws = np.array([choose_action(p, rng) for _ in range(20000)])
    np.testing.assert_allclose(np.bincount(draws, minlength=5) / draws.size, p, atol=0.015)
    assert choose_action(p, rng, mode=True) == 2
    assert choose_action(np.array([0, 0, 0, 0, 1.0]), rng) == 4


def test_simple_policies():
    obs = MergeObservation(50.0, 20.0, 1.0, -1.0, False, 0)
    np.testing.assert_allclose(UniformPolicy().probs(obs), 0.2)
    assert ConstantPolicy(0).probs(obs).tolist() == [1, 0, 0, 0, 0]
    assert ConstantPolicy(0).name == "constant-high-brake"
    assert not SumoPolicy().controls and UniformPolicy().controls
    with pytest.raises(PolicyError, match="0..4"):
        ConstantPolicy(5)


def test_learned_policy_from_model():
    rng = np.random.default_rng(1)
    edges = MergeBins.assumed_authors().to_dict()
    m = SavedModel(method="qsm", theta=np.ones(3), loglik=-1.0, q=rng.normal(size=(1250, 5)) * 50,
                   config=IRLConfig(beta=0.05), domain="merge", bin_edges={k: tuple(v) for k, v in edges.items()})
    pol = LearnedPolicy.from_model(m)
    assert pol.name == "qsm"
    s = pol.encoder.state(20.0, 5.0, 0.0, 0.0, True)
    obs = MergeObservation(20.0, 5.0, 0.0, 0.0, True, s)
    q = m.q[s] * 0.05
    expected = np.exp(q - q.max()) / np.exp(q - q.max()).sum()
    np.testing.assert_allclose(pol.probs(obs), expected, rtol=1e-12)
    with pytest.raises(PolicyError, match="bin_edges"):
        LearnedPolicy.from_model(SavedModel(method="qavg", theta=np.ones(3), loglik=-1.0, q=m.q, config=IRLConfig()))
    with pytest.raises(PolicyError, match="out of range"):
        pol.probs(MergeObservation(0, 0, 0, 0, False, 5000))
    bad = {**m.bin_edges, "d_AB": (3, 2, 1, 0)}
    with pytest.raises(PolicyError, match="d_AB"):
        LearnedPolicy.from_model(SavedModel(method="qavg", theta=np.ones(3), loglik=-1.0, q=m.q, config=IRLConfig(),
                                            domain="merge", bin_edges=bad))


def test_bad_settings_name_the_field():
    with pytest.raises(ControllerError, match="decision_step_s"):
        ControllerConfig(decision_step_s=0)
    with pytest.raises(ControllerError, match="hold_after_merge_s"):
        ControllerConfig(hold_after_merge_s=-1)
    assert issubclass(ControllerError, SimError) and issubclass(PolicyError, SimError)
