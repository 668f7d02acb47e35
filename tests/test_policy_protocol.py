"""The Policy protocol: the frozen-dataclass policies satisfy it; duplicate names are renamed
only where a policy can be renamed (no SUMO run: the checks happen before any episode)."""

from dataclasses import FrozenInstanceError

import numpy as np
import pytest

from analysis.evaluate import evaluate
from sim.policy import ConstantPolicy, Policy, PolicyError, SumoPolicy, UniformPolicy


@pytest.mark.parametrize("policy", [SumoPolicy(), UniformPolicy(), ConstantPolicy(0)])
def test_frozen_dataclass_policies_are_policies(policy):
    assert isinstance(policy, Policy)
    with pytest.raises(FrozenInstanceError):
        policy.name = "renamed"  # read-only, which the protocol's properties allow


class PlainPolicy:
    """A user policy that is not a dataclass."""

    name = "plain"
    controls = True

    def probs(self, obs):
        return np.full(5, 0.2)


def test_duplicate_names_of_a_non_dataclass_policy_is_a_policy_error(tmp_path):
    assert isinstance(PlainPolicy(), Policy)
    with pytest.raises(PolicyError, match="'plain'.*PlainPolicy is not a dataclass"):
        evaluate([], "synthetic", 1, 0, tmp_path, baselines=(), policies=[PlainPolicy(), PlainPolicy()],
                 rrd=False, progress=False)


class SteppedPolicy(PlainPolicy):
    """A user policy trained at 0.3 s decisions."""

    name = "stepped"
    decision_step_s = 0.3


def test_a_decision_step_other_than_a_policys_own_is_said_before_any_episode(tmp_path):
    from analysis.evaluate import DecisionStepWarning
    from sim.controller_config import ControllerConfig

    # the duplicate names stop the evaluation before SUMO starts; the warning comes first
    with pytest.warns(DecisionStepWarning, match=r"every 0.1 s, but stepped was trained at 0.3 s"), \
            pytest.raises(PolicyError):
        evaluate([], "synthetic", 1, 0, tmp_path, baselines=(), policies=[SteppedPolicy(), PlainPolicy(), PlainPolicy()],
                 controller=ControllerConfig(decision_s=0.1), rrd=False, progress=False)
