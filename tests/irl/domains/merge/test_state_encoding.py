"""The merge state encodings ("paper", "driver") and the model-file fields that came with them
(decision step, action accelerations)."""

import json

import numpy as np
import pytest

from irl.domains.merge.actions import ZERO_ACTION
from irl.domains.merge.bins import MergeBins
from irl.domains.merge.states import n_states, previous_action, split_driver_state
from irl.errors import ConfigError, EncodingError
from irl.result import SavedModel

BINS = MergeBins.assumed_authors()


def test_n_states():
    assert n_states("paper") == 1250
    assert n_states("driver") == 6250
    with pytest.raises(ConfigError, match="encoding"):
        n_states("both")


@pytest.mark.parametrize("prev", [0, 2, 4])
def test_driver_state_is_paper_times_actions_plus_prev(prev):
    args = (20.0, 5.0, 0.0, 0.0, True)
    s_p = BINS.state(*args)
    s_d = BINS.state(*args, prev_action=prev, encoding="driver")
    assert s_d == s_p * 5 + prev
    v = BINS.states(*([a] for a in args), prev_action=[prev], encoding="driver")
    assert v.tolist() == [s_d]
    assert split_driver_state(s_d) == (s_p, prev)


def test_driver_state_edges_cover_0_to_6249():
    # smallest and largest paper states with the smallest/largest previous action
    lo = BINS.state(1e9, -1e9, -1e9, -1e9, False, prev_action=0, encoding="driver")
    hi = BINS.state(0.0, 1e9, 1e9, 1e9, True, prev_action=4, encoding="driver")
    assert (lo, hi) == (0, 6249)
    s = BINS.states([1e9, 0.0], [-1e9, 1e9], [-1e9, 1e9], [-1e9, 1e9], [0, 1],
                    prev_action=np.array([0, 4]), encoding="driver")
    assert s.tolist() == [0, 6249]


def test_driver_without_prev_action_is_an_error():
    with pytest.raises(EncodingError, match="prev_action"):
        BINS.state(20.0, 5.0, 0.0, 0.0, True, encoding="driver")
    with pytest.raises(EncodingError, match="prev_action"):
        BINS.states([20.0], [5.0], [0.0], [0.0], [1], encoding="driver")
    for bad in (5, -1):
        with pytest.raises(EncodingError, match="0..4"):
            BINS.state(20.0, 5.0, 0.0, 0.0, True, prev_action=bad, encoding="driver")
        with pytest.raises(EncodingError, match="0..4"):
            BINS.states([20.0], [5.0], [0.0], [0.0], [1], prev_action=[bad], encoding="driver")
    with pytest.raises(ConfigError):
        BINS.state(20.0, 5.0, 0.0, 0.0, True, prev_action=1, encoding="nope")


def test_paper_encoding_ignores_prev_action():
    assert BINS.state(20.0, 5.0, 0.0, 0.0, True, prev_action=3) == BINS.state(20.0, 5.0, 0.0, 0.0, True)


def test_previous_action_from_speed_history():
    assert previous_action(None, 50.0, 0.3) == ZERO_ACTION
    assert previous_action(float("nan"), 50.0, 0.3) == ZERO_ACTION
    assert previous_action(50.0, 48.5, 0.3) == 0  # -5.0 ft/s^2: High Brake
    assert previous_action(50.0, 50.0, 0.3) == ZERO_ACTION
    assert previous_action(50.0, 50.0 + 0.3 * 5.0, 0.3) == 4


def test_model_file_new_fields_round_trip_and_old_files_default(tmp_path):
    from irl.config import IRLConfig
    model = SavedModel(method="qavg", theta=np.ones(3), loglik=-1.0, q=np.zeros((6250, 5)), config=IRLConfig(),
                       domain="merge", state_encoding="driver", decision_step_s=0.3,
                       action_acc_ft_s2=(-12.3, -2.0, 0.1, 2.2, 6.0), feature_set="driver",
                       unvisited_rule="nearest")
    p = model.save(tmp_path / "m.json")
    back = SavedModel.load(p)
    assert (back.state_encoding, back.decision_step_s, back.action_acc_ft_s2, back.feature_set, back.unvisited_rule) \
        == ("driver", 0.3, (-12.3, -2.0, 0.1, 2.2, 6.0), "driver", "nearest")
    data = json.loads(p.read_text())
    for k in ("state_encoding", "decision_step_s", "action_acc_ft_s2", "feature_set", "unvisited_rule"):
        del data[k]
    p.write_text(json.dumps(data))
    old = SavedModel.load(p)
    assert (old.state_encoding, old.decision_step_s, old.action_acc_ft_s2, old.unvisited_rule) \
        == ("paper", 0.1, (-8.0, -2.7, 0.0, 2.7, 8.0), "none")
    data["state_encoding"] = "fancy"
    p.write_text(json.dumps(data))
    from irl.errors import ModelFileError
    with pytest.raises(ModelFileError, match="state_encoding"):
        SavedModel.load(p)
