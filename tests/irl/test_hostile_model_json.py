"""Hostile input for ``SavedModel.load`` (model.json): random bytes, random JSON, and a valid
model with fields replaced by values of the wrong type or shape. Only a loaded model (which
then saves and loads back equal) or a ``ModelFileError`` naming the file is allowed."""

from __future__ import annotations

import copy
import json
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from irl.config import IRLConfig
from irl.errors import ModelFileError
from irl.result import SavedModel

pytestmark = pytest.mark.hostile

SETTINGS = settings(max_examples=150, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])

VALID = SavedModel(
    method="qavg", theta=np.array([0.5, -1.0, 2.0]), loglik=-12.5, q=np.arange(6.0).reshape(3, 2),
    config=IRLConfig(beta=0.5), domain="merge", feature_names=("a", "b", "c"),
    bin_edges={"d_AC": (1.0, 2.0, 3.0, 4.0)}, info={"seed": 1},
).to_json_dict()

json_scalars = st.one_of(
    st.none(), st.booleans(), st.integers(), st.integers(min_value=10**300, max_value=10**320),
    st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=10),
    st.sampled_from(["qavg", "reirl", "1.5", "", "NaN"]),
)
json_values = st.recursive(
    json_scalars,
    lambda inner: st.one_of(st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=6), inner, max_size=4)),
    max_leaves=10,
)
FIELDS = sorted(VALID) + ["settings.beta", "settings.max_outer", "settings.solver", "settings.nope",
                          "settings.stop_scale_by_gamma", "bin_edges.d_AC"]


def _write(tmp_path, text: str | bytes):
    p = tmp_path / "model.json"
    if isinstance(text, bytes):
        p.write_bytes(text)
    else:
        p.write_text(text, encoding="utf-8")
    return p


def _check(p):
    try:
        m = SavedModel.load(p)
    except ModelFileError as e:
        assert str(p) in str(e)
        return None
    assert isinstance(m, SavedModel)
    assert m.theta.ndim == 1 and np.all(np.isfinite(m.theta))
    assert m.q.ndim == 2 and np.all(np.isfinite(m.q))
    assert not math.isnan(m.loglik)
    assert all(isinstance(n, str) for n in m.feature_names)
    assert isinstance(m.info, dict) and isinstance(m.converged, bool)
    again = SavedModel.load(m.save(p.with_name("again.json")))
    np.testing.assert_array_equal(again.theta, m.theta)
    np.testing.assert_array_equal(again.q, m.q)
    assert again.config == m.config and again.bin_edges == m.bin_edges
    return m


@SETTINGS
@given(st.binary(max_size=300))
def test_random_bytes(tmp_path, data):
    _check(_write(tmp_path, data))


@SETTINGS
@given(json_values)
def test_random_json(tmp_path, value):
    _check(_write(tmp_path, json.dumps(value)))


@SETTINGS
@given(st.sampled_from(FIELDS), json_values)
def test_one_field_replaced(tmp_path, field, value):
    data = copy.deepcopy(VALID)
    if "." in field:
        top, key = field.split(".")
        data[top][key] = value
    else:
        data[field] = value
    _check(_write(tmp_path, json.dumps(data)))


@SETTINGS
@given(st.sampled_from(sorted(VALID)))
def test_one_field_missing(tmp_path, field):
    data = copy.deepcopy(VALID)
    del data[field]
    m = _check(_write(tmp_path, json.dumps(data)))
    if field in ("method", "theta", "loglik", "settings", "q"):
        assert m is None


@SETTINGS
@given(st.integers(min_value=0, max_value=len(json.dumps(VALID))))
def test_truncated_file(tmp_path, n):
    text = json.dumps(VALID)
    m = _check(_write(tmp_path, text[:n]))
    assert (m is None) == (n < len(text))


def test_regressions(tmp_path):
    """Inputs that used to escape as TypeError/ValueError/OverflowError or load as nonsense."""
    for field, value in [("info", 5), ("info", "ab"), ("theta", [10**400]), ("bin_edges", {"x": "123"}),
                         ("feature_names", "abc"), ("converged", "no"), ("loglik", "1.5"),
                         ("theta", [True, False, True]), ("q", [[1.0, 2.0], [3.0]])]:
        data = copy.deepcopy(VALID)
        data[field] = value
        with pytest.raises(ModelFileError, match=field):
            SavedModel.load(_write(tmp_path, json.dumps(data)))
    data = copy.deepcopy(VALID)
    data["settings"]["max_outer"] = "5"
    with pytest.raises(ModelFileError, match="settings.max_outer"):
        SavedModel.load(_write(tmp_path, json.dumps(data)))
    with pytest.raises(ModelFileError, match="not a JSON"):
        SavedModel.load(_write(tmp_path, "[" * 100_000))
    with pytest.raises(ModelFileError, match="cannot read"):
        SavedModel.load(tmp_path)  # a directory
    m = _check(_write(tmp_path, json.dumps(VALID)))
    assert m is not None and m.feature_names == ("a", "b", "c")


@pytest.mark.parametrize("step", [10**400, -0.3, 0.25, 0.0, "0.3", True])
def test_decision_step_must_be_a_whole_number_of_frames(tmp_path, step):
    # 10**400 once crashed with OverflowError (found by the property test above)
    data = copy.deepcopy(VALID)
    data["decision_step_s"] = step
    with pytest.raises(ModelFileError, match="decision_step_s"):
        SavedModel.load(_write(tmp_path, json.dumps(data)))
