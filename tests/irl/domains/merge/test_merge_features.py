"""Named merge feature sets on bin representatives, custom features, the unvisited-state rule."""

import numpy as np
import pytest

from irl.domains.merge.actions import ACTION_ACC_FT_S2
from irl.domains.merge.bins import MergeBins
from irl.domains.merge.features import (
    DRIVER_FEATURES,
    FeatureSet,
    feature_array,
    feature_set,
    features,
)
from irl.errors import ConfigError
from irl.unvisited_states import apply_unvisited_rule

BINS = MergeBins.assumed_authors()


def test_paper_set_is_the_papers_three_features():
    np.testing.assert_array_equal(feature_set("paper", BINS).array, features())
    drv = feature_set("paper", BINS, "driver").array
    assert drv.shape == (6250, 5, 3)
    np.testing.assert_array_equal(drv[::5], features())


def test_driver_features_values_at_representatives():
    f = feature_set("driver", BINS, "driver", decision_step_s=0.3)
    assert f.array.shape == (6250, 5, len(DRIVER_FEATURES)) and f.names == DRIVER_FEATURES
    col = {n: f.array[..., i] for i, n in enumerate(f.names)}
    s_paper = BINS.state(20.0, 5.0, 5.0, 0.0, False)  # close to C, closing at 5 ft/s
    s = s_paper * 5 + 4  # previous action High Accel
    # jerk: |a - a_prev| / 8 with midpoints; keep_action one-hot of the previous action
    np.testing.assert_allclose(col["jerk"][s], np.abs(np.array(ACTION_ACC_FT_S2) - 8.0) / 8.0)
    np.testing.assert_array_equal(col["keep_action"][s], [0, 0, 0, 0, 1])
    np.testing.assert_array_equal(col["bias_high_brake"][s], [1, 0, 0, 0, 0])
    # braking lowers the inverse TTC to C; the exact value from the representatives
    d = BINS.representatives("d_AC")[4]
    v = BINS.representatives("v_AC")[3]  # 5 ft/s: bin 3
    acc = np.array(ACTION_ACC_FT_S2)
    want = np.maximum(v + acc * 0.3, 0) / np.maximum(d - v * 0.3 - 0.5 * acc * 0.09, 1.0)
    np.testing.assert_allclose(col["ittc_C"][s], want)
    assert np.all(np.diff(col["ittc_C"][s]) >= 0)


def test_jerk_needs_the_driver_encoding_and_names_are_checked():
    with pytest.raises(ConfigError, match="previous action"):
        feature_array(("jerk",), BINS, "paper")
    with pytest.raises(ConfigError, match="unknown merge feature"):
        feature_array(("speed_of_light",), BINS)
    with pytest.raises(ConfigError, match="feature set"):
        feature_set("fancy", BINS)


def test_custom_features_from_python(tmp_path):
    arr = np.random.default_rng(0).normal(size=(1250, 5, 2))
    fs = FeatureSet.custom(["a", "b"], arr)
    assert fs.name == "custom" and fs.names == ("a", "b")
    with pytest.raises(ConfigError, match=r"\[S, A, 2\]"):
        FeatureSet.custom(["a", "b"], arr[..., :1])
    import pandas as pd

    from irl.problems import load_problem
    n = 12
    df = pd.DataFrame({"encounter_id": 1, "d_AC": np.linspace(20, 100, n), "d_AB": 5.0, "v_AC": 0.0, "v_AB": 0.0,
                       "B_is_truck": False, "acc_A": np.linspace(-6, 6, n)})
    path = tmp_path / "enc.csv"
    df.to_csv(path, index=False)
    p = load_problem("merge", path, bins=BINS, features=fs)
    assert p.feature_names == ("a", "b") and p.feature_set == "custom" and p.decision_step_s == 0.3
    np.testing.assert_array_equal(p.demos.features, arr)
    assert p.demos.n_steps == 4


def test_unvisited_nearest_copies_the_nearest_visited_row():
    q = np.arange(6250 * 5, dtype=float).reshape(6250, 5)
    visited = np.zeros(6250, bool)
    a = BINS.state(20.0, 5.0, 0.0, 0.0, False, prev_action=1, encoding="driver")
    b = BINS.state(100.0, 5.0, 0.0, 0.0, False, prev_action=1, encoding="driver")
    visited[[a, b]] = True
    out = apply_unvisited_rule(q, visited, "nearest")
    near_a = BINS.state(40.0, 5.0, 0.0, 0.0, False, prev_action=1, encoding="driver")  # one d_AC bin from a
    np.testing.assert_array_equal(out[near_a], q[a])
    np.testing.assert_array_equal(out[a], q[a])
    np.testing.assert_array_equal(apply_unvisited_rule(q, visited, "none"), q)
    with pytest.raises(ConfigError, match="unvisited rule"):
        apply_unvisited_rule(q, visited, "guess")
