"""Scenario specs: presets load and round-trip through TOML; bad specs fail naming the field."""

from __future__ import annotations

import copy
import tomllib

import pytest

from scenarios.errors import SpecError
from scenarios.loader import load_scenario, preset_names
from scenarios.spec.model import ScenarioSpec, VTypeSpec
from scenarios.spec.parse import spec_from_dict, spec_from_toml, with_overrides


@pytest.mark.parametrize("name", ["synthetic", "i80"])
def test_presets_load_and_round_trip(name):
    spec = load_scenario(name)
    assert isinstance(spec, ScenarioSpec) and spec.name == name
    again = spec_from_toml(spec.to_toml(), source="roundtrip")
    assert again == spec
    assert isinstance(spec.demand.main_veh_h, tuple) and len(spec.demand.main_veh_h) == spec.road.main_lanes
    assert all(isinstance(v, VTypeSpec) for v in spec.drivers.car + spec.drivers.truck)


def test_i80_preset_shape():
    spec = load_scenario("i80")
    assert spec.road.main_lanes == 6
    assert 600 <= spec.road.main_length_m <= 620  # 2005 ft: on-ramp start to off-ramp, derived from I-80 geometry
    assert len(spec.drivers.car) >= 2  # a distribution of car drivers
    assert set(preset_names()) >= {"synthetic", "i80"}


def test_load_from_file_and_overrides(tmp_path):
    spec = with_overrides(load_scenario("synthetic"), seed=7, duration_s=90.0)
    p = tmp_path / "mine.toml"
    p.write_text(spec.to_toml())
    loaded = load_scenario(p)
    assert loaded == spec and loaded.simulation.seed == 7 and loaded.simulation.duration_s == 90.0
    assert load_scenario(str(p)) == spec


def test_duration_override_within_the_warmup_names_the_override():
    """``generate --scenario i80 --duration 60``: the error is the override's, not the preset's warmup_s."""
    spec = load_scenario("i80")
    w = spec.simulation.warmup_s
    with pytest.raises(SpecError, match=rf"simulation\.duration_s: overridden \(e\.g\. --duration\) with 60 s; "
                                        rf"must be longer than the scenario's simulation\.warmup_s = {w:g} s"):
        with_overrides(spec, duration_s=60.0)
    assert with_overrides(spec, duration_s=w + 1).simulation.duration_s == w + 1


def _base() -> dict:
    return tomllib.loads(load_scenario("synthetic").to_toml())


def _set(d: dict, path: str, value) -> dict:
    d = copy.deepcopy(d)
    keys = path.split(".")
    cur = d
    for k in keys[:-1]:
        cur = cur[int(k)] if isinstance(cur, list) else cur[k]
    cur[keys[-1]] = value
    return d


BAD = [
    # (path to set, value, text the message must contain)
    ("road.ramp_length_m", -5, "road.ramp_length_m: must be positive, got -5"),
    ("road.main_length_m", 0, "road.main_length_m: must be positive"),
    ("road.aux_length_m", 1000.0, "road.aux_length_m"),
    ("road.ramp_length_m", 400.0, "road.ramp_length_m"),
    ("road.main_lanes", 2.5, "road.main_lanes: must be an integer"),
    ("road.main_lanes", 7, "road.main_lanes: must be at most 6"),
    ("road.lane_width_m", "wide", "road.lane_width_m: must be a number"),
    ("road.bridges", 2, "road.bridges: unknown key"),
    ("colour", "red", "colour: unknown key"),
    ("demand.truck_share", 1.5, "demand.truck_share"),
    ("demand.main_veh_h", [100.0], "demand.main_veh_h: must have one value per main lane"),
    ("demand.main_veh_h", [100.0, -1.0, 100.0], "demand.main_veh_h[1]: must be >= 0"),
    ("demand.arrivals", "bursty", "demand.arrivals: must be one of"),
    ("simulation.step_s", 0.03, "simulation.step_s"),
    ("simulation.warmup_s", 1e6, "simulation.warmup_s"),
    ("simulation.seed", -1, "simulation.seed"),
    ("simulation.time_to_teleport_s", -3.0, "simulation.time_to_teleport_s: must be >= 0"),
    ("simulation.time_to_teleport_s", "never", "simulation.time_to_teleport_s: must be a number"),
    ("drivers.car.0.car_follow_model", "Bogus", "drivers.car[0].car_follow_model: must be one of"),
    ("drivers.car.0.sigma", 2.0, "drivers.car[0].sigma"),
    ("drivers.car.0.wheels", 4, "drivers.car[0].wheels: unknown key"),
    ("drivers.truck.0.lc_params", {"speedGain": 1.0}, "drivers.truck[0].lc_params.speedGain"),
    ("drivers.truck.0.cf_params", {"tau": 1.0}, "drivers.truck[0].cf_params.tau"),
    ("drivers.truck.0.id", "car", "drivers.truck[0].id: duplicate"),
    ("drivers.bus", [{"id": "b"}], "drivers.bus: unknown key"),
]


@pytest.mark.parametrize("path,value,message", BAD, ids=[b[0] + "=" + repr(b[1]) for b in BAD])
def test_bad_spec_names_the_field(path, value, message):
    data = _set(_base(), path, value)
    with pytest.raises(SpecError) as e:
        spec_from_dict(data, source="scenario.toml")
    assert str(e.value).startswith("scenario.toml: ")
    assert message in str(e.value)


def test_zero_demand_everywhere():
    data = _set(_set(_base(), "demand.main_veh_h", [0.0, 0.0, 0.0]), "demand.ramp_veh_h", 0.0)
    with pytest.raises(SpecError, match="demand: zero demand everywhere"):
        spec_from_dict(data, source="scenario.toml")


def test_unknown_preset_and_missing_file(tmp_path):
    with pytest.raises(SpecError, match="unknown preset 'nowhere'.*i80"):
        load_scenario("nowhere")
    with pytest.raises(SpecError, match="not found"):
        load_scenario(tmp_path / "absent.toml")


def test_bad_toml_file_names_the_file(tmp_path):
    p = tmp_path / "broken.toml"
    p.write_text("name = \n")
    with pytest.raises(SpecError, match="broken.toml: invalid TOML"):
        load_scenario(p)
    p.write_text('name = "x"\n[road]\nramp_length_m = -5\n')
    with pytest.raises(SpecError, match=r"^broken.toml: road.ramp_length_m: must be positive, got -5"):
        load_scenario(p)


def test_vtype_distribution_in_routes():
    from scenarios.routes import routes_xml

    spec = load_scenario("i80")
    xml = routes_xml(spec)
    assert xml.count("<vType ") == len(spec.drivers.car) + len(spec.drivers.truck) and '<vTypeDistribution id="traffic">' in xml
    probs = [float(x.split('"')[0]) for x in xml.split('probability="')[1:]]
    assert abs(sum(probs) - 1.0) < 1e-6
