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
