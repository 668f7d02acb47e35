"""Hostile input for the scenario loader: random TOML text, valid TOML with wrong types, values
and unknown keys. The only outcomes allowed are a valid spec (which then round-trips through
its own TOML) or a ``SpecError`` naming the source; never another exception, never a hang."""

from __future__ import annotations

import copy
import datetime as dt
import math
import tomllib

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from scenarios.errors import SpecError
from scenarios.loader import load_scenario
from scenarios.spec.model import ScenarioSpec
from scenarios.spec.parse import spec_from_dict, spec_from_toml

pytestmark = pytest.mark.hostile

BASE = load_scenario("synthetic").to_dict()
SETTINGS = settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])

# values tomllib can produce
toml_scalars = st.one_of(
    st.booleans(),
    st.integers(min_value=-(2**63), max_value=2**63 - 1),
    st.integers(min_value=-(10**40), max_value=10**40),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0, 1, -1, 0.0, 1e-320, 5e-324, 1e308, -0.0, 7, 2**31, 0.1, 0.05, 0.03]),
    st.text(max_size=12),
    st.sampled_from(["", "poisson", "IDM", "LC2013", "max", "lcStrategic", "x y", "\x00", "\t\n\"\\"]),
    st.dates(), st.times(), st.datetimes(),
)
toml_values = st.recursive(
    toml_scalars,
    lambda inner: st.one_of(st.lists(inner, max_size=4),
                            st.dictionaries(st.text(min_size=1, max_size=8), inner, max_size=4)),
    max_leaves=12,
)


def _paths(d, prefix=()):
    """Every (path, value) in a nested dict/list."""
    if isinstance(d, dict):
        for k, v in d.items():
            yield prefix + (k,), v
            yield from _paths(v, prefix + (k,))
    elif isinstance(d, list):
        for i, v in enumerate(d):
            yield prefix + (i,), v
            yield from _paths(v, prefix + (i,))


ALL_PATHS = [p for p, _ in _paths(BASE)]
KNOWN_KEYS = sorted({p[-1] for p in ALL_PATHS if isinstance(p[-1], str)})


def _set(d, path, value):
    for k in path[:-1]:
        d = d[k]
    d[path[-1]] = value


def _check(make):
    """Run ``make()``; it must give a valid spec (that round-trips) or a SpecError."""
    try:
        spec = make()
    except SpecError as e:
        msg = str(e)
        assert msg and ": " in msg  # "<source>: <field>: <problem>"
        return None
    assert isinstance(spec, ScenarioSpec)
    again = spec_from_toml(spec.to_toml(), source="roundtrip")
    assert again == spec
    return spec


@SETTINGS
@given(st.text(max_size=400))
def test_random_text(text):
    _check(lambda: spec_from_toml(text, source="random.toml"))


@SETTINGS
@given(st.binary(max_size=200))
def test_random_bytes_file(tmp_path_factory, data):
    p = tmp_path_factory.mktemp("b") / "bytes.toml"
    p.write_bytes(data)
    _check(lambda: load_scenario(p))


@SETTINGS
@given(st.sampled_from(ALL_PATHS), toml_values)
def test_one_field_replaced_by_a_random_value(path, value):
    data = copy.deepcopy(BASE)
    _set(data, path, value)
    _check(lambda: spec_from_dict(data, source="mutated.toml"))


@SETTINGS
@given(st.lists(st.tuples(st.sampled_from(ALL_PATHS), toml_scalars), min_size=1, max_size=5))
def test_several_fields_replaced_by_scalars(edits):
    data = copy.deepcopy(BASE)
    for path, value in edits:
        try:
            _set(data, path, value)
        except (TypeError, KeyError, IndexError):
            pass  # an earlier edit replaced a parent
    _check(lambda: spec_from_dict(data, source="mutated.toml"))


@SETTINGS
@given(st.sampled_from([(), ("road",), ("demand",), ("simulation",), ("drivers",),
                        ("drivers", "car", 0), ("drivers", "truck", 0), ("drivers", "car", 0, "cf_params")]),
       st.one_of(st.text(min_size=1, max_size=10), st.sampled_from(KNOWN_KEYS)), toml_values)
def test_unknown_or_misplaced_key(where, key, value):
    data = copy.deepcopy(BASE)
    if where == ("drivers", "car", 0, "cf_params"):
        data["drivers"]["car"][0]["cf_params"] = {}
    target = data
    for k in where:
        target = target[k]
    target[key] = value
    _check(lambda: spec_from_dict(data, source="extra.toml"))


@SETTINGS
@given(st.dictionaries(st.sampled_from(["name", "road", "demand", "drivers", "simulation"]), toml_values))
def test_random_top_level_tables(data):
    _check(lambda: spec_from_dict(data, source="random.toml"))


@SETTINGS
@given(st.dictionaries(st.text(max_size=10).filter(lambda k: k not in ("id",)), toml_scalars, max_size=4),
       st.dictionaries(st.text(max_size=10), toml_scalars, max_size=3))
def test_random_sumo_parameter_tables(cf, lc):
    data = copy.deepcopy(BASE)
    data["drivers"]["car"][0]["cf_params"] = cf
    data["drivers"]["car"][0]["lc_params"] = {("lc" + k): v for k, v in lc.items()}
    spec = _check(lambda: spec_from_dict(data, source="params.toml"))
    if spec is not None:  # accepted parameter values are finite and TOML-writable
        for _, v in spec.drivers.car[0].cf_params + spec.drivers.car[0].lc_params:
            assert not (isinstance(v, float) and not math.isfinite(v))


def test_examples_found_by_the_properties():
    """Regressions of bugs the properties found (each used to escape as a non-SpecError)."""
    cases = [
        ("simulation", "step_s", 5e-324),         # 0.1 / step -> inf -> OverflowError in round()
        ("road", "main_length_m", 10**400),        # int too large for float -> OverflowError
        ("demand", "ramp_veh_h", 10**400),
        ("simulation", "seed", 10**400),
    ]
    for table, key, value in cases:
        data = copy.deepcopy(BASE)
        data[table][key] = value
        with pytest.raises(SpecError, match=f"{table}.{key}"):
            spec_from_dict(data, source="x.toml")
    data = copy.deepcopy(BASE)
    data["drivers"]["car"][0]["cf_params"] = {"delta": float("nan")}
    with pytest.raises(SpecError, match=r"drivers.car\[0\].cf_params.delta"):
        spec_from_dict(data, source="x.toml")
    data = copy.deepcopy(BASE)
    data["drivers"]["car"][0]["cf_params"] = {"note": "tab\there\x01\x7f"}
    spec = spec_from_dict(data, source="x.toml")
    assert spec_from_toml(spec.to_toml()) == spec
    data = copy.deepcopy(BASE)
    data["drivers"]["car"][0]["cf_params"] = {"when": dt.date(2020, 1, 1)}
    with pytest.raises(SpecError, match="cf_params.when"):
        spec_from_dict(data, source="x.toml")


def test_non_utf8_file_is_a_spec_error(tmp_path):
    p = tmp_path / "latin1.toml"
    p.write_bytes('name = "caf\xe9"\n'.encode("latin-1"))
    with pytest.raises(SpecError, match="latin1.toml"):
        load_scenario(p)
    d = tmp_path / "dir.toml"
    d.mkdir()
    with pytest.raises(SpecError, match="dir.toml"):
        load_scenario(d)


def test_toml_module_agrees_with_our_writer():
    text = load_scenario("synthetic").to_toml()
    assert tomllib.loads(text) == BASE


@pytest.mark.sumo
def test_a_value_only_sumo_rejects_is_a_sim_error_and_leaves_no_output(tmp_path):
    """Parameters passed through to SUMO unchecked: SUMO's refusal is a one-line error, exit 2."""
    import os
    import subprocess
    import sys

    bad = tmp_path / "bad.toml"
    bad.write_text('name = "bad"\n[simulation]\nduration_s = 70.0\n[[drivers.car]]\nid = "car"\n'
                   'lc_params = { lcStrategic = "abc" }\n')
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "-m", "analysis", "generate", "--scenario", str(bad), "--out", str(out),
                        "--no-progress"], capture_output=True, text=True,
                       env=dict(os.environ, MERGE_IRL_CACHE=str(tmp_path / "cache")))
    assert r.returncode == 2, r.stderr
    assert "merge-irl generate: error: SUMO failed to start scenario 'bad'" in r.stderr
    assert "Traceback" not in r.stderr
    assert not out.exists() or not any(out.iterdir())


def test_numeric_depart_speed_round_trips():
    data = copy.deepcopy(BASE)
    data["demand"]["depart_speed"] = 0
    spec = spec_from_dict(data, source="x.toml")
    assert spec.demand.depart_speed == "0.0"
    assert spec_from_toml(spec.to_toml()) == spec
    for bad in ("-1", "nan", "inf", "fast"):
        data["demand"]["depart_speed"] = bad
        with pytest.raises(SpecError, match="demand.depart_speed"):
            spec_from_dict(data, source="x.toml")
