"""The Policy protocol: the frozen-dataclass policies satisfy it; duplicate names are renamed
only where a policy can be renamed (no SUMO run: the checks happen before any episode)."""

from dataclasses import FrozenInstanceError

import numpy as np
import pytest

from analysis.evaluation.evaluate import evaluate
from sim.drivers.policy import (
    ConstantPolicy,
    Policy,
    PolicyDefaults,
    PolicyError,
    SumoPolicy,
    UniformPolicy,
    state_independent_loglik,
)


@pytest.mark.parametrize("policy", [SumoPolicy(), UniformPolicy(), ConstantPolicy(0)])
def test_frozen_dataclass_policies_are_policies(policy):
    assert policy.decision_step_s is None  # any step
    assert isinstance(policy, Policy)
    with pytest.raises(FrozenInstanceError):
        policy.name = "renamed"  # read-only, which the protocol's properties allow


class PlainPolicy(PolicyDefaults):
    """A user policy that is not a dataclass."""

    name = "plain"
    controls = True
    decision_step_s = None

    def probs(self, obs):
        return np.full(5, 0.2)

    def heldout_loglik(self, encounters, *, decision_step_s, where):
        return state_independent_loglik(np.full(5, 0.2), encounters, decision_step_s=decision_step_s, where=where)


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
    from analysis.evaluation.plan import DecisionStepWarning
    from sim.closed_loop.config import ControllerConfig

    # the duplicate names stop the evaluation before SUMO starts; the warning comes first
    with pytest.warns(DecisionStepWarning, match=r"every 0.1 s, but stepped was trained at 0.3 s"), \
            pytest.raises(PolicyError):
        evaluate([], "synthetic", 1, 0, tmp_path, baselines=(), policies=[SteppedPolicy(), PlainPolicy(), PlainPolicy()],
                 controller=ControllerConfig(decision_step_s=0.1), rrd=False, progress=False)


class SlowPolicy(SteppedPolicy):
    """The same name as SteppedPolicy, trained at 0.6 s decisions."""

    decision_step_s = 0.6


def test_the_first_policys_step_is_the_default_even_when_names_repeat(tmp_path):
    from analysis.evaluation.plan import DecisionStepWarning

    with pytest.warns(DecisionStepWarning, match=r"every 0.3 s, but stepped was trained at 0.6 s"), \
            pytest.raises(PolicyError):
        evaluate([], "synthetic", 1, 0, tmp_path, baselines=(), policies=[SteppedPolicy(), SlowPolicy()],
                 rrd=False, progress=False)


@pytest.mark.parametrize("step", [0.25, 0.05, 1e-9])
def test_a_decision_step_off_the_simulation_step_is_refused_before_any_work(tmp_path, step):
    from sim.closed_loop.config import ControllerConfig
    from sim.errors import SimError

    with pytest.raises(SimError, match="positive multiple of the 0.1 s simulation step"):
        evaluate([], "synthetic", 1, 0, tmp_path / "out", baselines=("uniform",),
                 controller=ControllerConfig(decision_step_s=step), rrd=False, progress=False)
    assert not (tmp_path / "out").exists()


def test_held_out_tables_are_checked_before_any_episode(tmp_path):
    import pandas as pd

    from irl.errors import DemonstrationError

    no_id = pd.DataFrame({"d_AC": [100.0] * 4, "d_AB": [10.0] * 4, "v_AC": [0.0] * 4, "v_AB": [0.0] * 4,
                          "B_is_truck": False, "acc_A": [0.0] * 4})
    with pytest.raises(DemonstrationError, match=r"lacks column\(s\) \['encounter_id'\]"):
        evaluate([], "synthetic", 1, 0, tmp_path / "a", baselines=("uniform",), demos=no_id, rrd=False,
                 progress=False)
    other = pd.DataFrame({"x": [1.0], "y": [2.0]})  # e.g. a trajectory table given as encounters
    with pytest.raises(DemonstrationError, match="lacks column"):
        evaluate([], "synthetic", 1, 0, tmp_path / "b", baselines=("idm",), train_demos=other, rrd=False,
                 progress=False)
    short = no_id.assign(encounter_id=[1, 1, 2, 2])  # every encounter shorter than one 0.3 s decision
    with pytest.raises(DemonstrationError, match="shorter than one decision step"):
        evaluate([], "synthetic", 1, 0, tmp_path / "c", baselines=("uniform",), demos=short, rrd=False,
                 progress=False)
    assert not any((tmp_path / d).exists() for d in "abc")


class UnscoredPolicy(PolicyDefaults):
    """A state-dependent user policy that does not score held-out demonstrations itself."""

    name = "unscored"
    controls = True
    decision_step_s = None

    def probs(self, obs):
        return np.eye(5)[0 if obs.d_AB < 20.0 else 4]


def _heldout_frames():
    import pandas as pd

    return pd.DataFrame({"encounter_id": [1] * 6, "d_AC": [100.0] * 6, "d_AB": [10.0] * 6, "v_AC": [0.0] * 6,
                         "v_AB": [0.0] * 6, "B_is_truck": False, "acc_A": [0.0] * 6})


def test_a_policy_without_its_own_heldout_scoring_is_refused_not_scored(tmp_path):
    """No silent number from a guess at the policy's kind: a clear error naming the class,
    from the scoring and from evaluate before any work."""
    from analysis.evaluation.heldout_scoring import load_heldout, policy_heldout_loglik

    assert not isinstance(UnscoredPolicy(), Policy)
    with pytest.raises(PolicyError, match="UnscoredPolicy is not a sim.drivers.policy.Policy: it lacks heldout_loglik"):
        policy_heldout_loglik(UnscoredPolicy(), load_heldout(_heldout_frames()), 0.3)
    with pytest.raises(PolicyError, match="UnscoredPolicy .* lacks heldout_loglik"):
        evaluate([], "synthetic", 1, 0, tmp_path / "out", baselines=(), policies=[UnscoredPolicy()],
                 demos=_heldout_frames(), rrd=False, progress=False)
    assert not (tmp_path / "out").exists()


def test_a_policy_without_a_decision_step_is_refused_by_the_controller():
    from sim.closed_loop.controller import Controller

    class Stepless(PolicyDefaults):
        name, controls = "stepless", True

        def probs(self, obs):
            return np.full(5, 0.2)

    with pytest.raises(PolicyError, match="controller: Stepless .* lacks decision_step_s"):
        Controller(Stepless())


def test_the_controller_decides_at_the_policys_step_else_the_domains_default():
    from irl.domains.merge.mdp import DEFAULT_DECISION_STEP_S
    from sim.closed_loop.config import ControllerConfig
    from sim.closed_loop.controller import Controller

    assert Controller(UniformPolicy()).decision_step_s == DEFAULT_DECISION_STEP_S
    assert Controller(SteppedPolicy()).decision_step_s == 0.3
    assert Controller(SlowPolicy()).decision_step_s == 0.6
    assert Controller(SlowPolicy(), ControllerConfig(decision_step_s=0.2)).decision_step_s == 0.2


def test_every_policy_scores_itself_as_the_evaluation_did():
    """Uniform and constant score log p(a) per decision; SUMO's driver and IDM have no likelihood."""
    from analysis.evaluation.heldout_scoring import load_heldout, policy_heldout_loglik
    from sim.drivers.idm import IdmPolicy

    held = load_heldout(_heldout_frames())  # 6 frames: two 0.3 s decisions, both Zero
    total, per = policy_heldout_loglik(UniformPolicy(), held, 0.3)
    assert per == pytest.approx(np.log(0.2)) and total == pytest.approx(2 * np.log(0.2))
    assert policy_heldout_loglik(ConstantPolicy(2), held, 0.3) == (0.0, 0.0)
    assert policy_heldout_loglik(ConstantPolicy(0), held, 0.3)[1] == -np.inf
    for p in (SumoPolicy(), IdmPolicy()):
        assert all(np.isnan(policy_heldout_loglik(p, held, 0.3)))
