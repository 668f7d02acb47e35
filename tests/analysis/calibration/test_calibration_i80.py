"""The i80 scenario in the real congested state: the downstream bottleneck, the resampled driver
distribution SUMO loads, and the same spacing / time-headway definitions on both sides of
``calibrate check``."""

import hashlib
import json
from dataclasses import asdict, replace

import numpy as np
import pytest
import sumolib

from analysis.calibration import CFParams, PairFit, load_result
from analysis.calibration.pairs import CarFollowingPair
from analysis.calibration.preset import preset_with_drivers
from analysis.calibration.result import CalibrationResult
from analysis.calibration.states import accepted_gaps, pair_states, table_states
from analysis.calibration.vtypes import SIM_RANGE, member_spread, resample_members, to_vtype_specs
from merge_irl.units import M_PER_FT
from scenarios.errors import SpecError
from scenarios.loader import load_scenario
from scenarios.network import NETWORK_FORMAT_VERSION, build_network, network_key
from scenarios.routes import routes_xml
from scenarios.spec.model import DemandSpec, RoadSpec, ScenarioSpec, SimulationSpec
from scenarios.spec.parse import spec_from_toml
from sim.runtime.run import run_scenario
from sim.runtime.schema import COLUMNS
from sim.runtime.table import DERIVED, table_from_columns


def _result(n: int = 5) -> CalibrationResult:
    """Per-pair fits with distinct, recognisable parameters (one out of SIM_RANGE)."""
    fits = tuple(
        PairFit(name=f"p{i}", group=f"g{i}", rmse_m=1.0,
                params=CFParams(accel=0.6 + 0.3 * i, decel=1.5 + i, tau=0.7 + 0.2 * i, minGap=1.5 + 0.5 * i,
                                maxSpeed=16.0 + 2 * i))
        for i in range(n))
    fits = fits[:-1] + (replace(fits[-1], params=replace(fits[-1].params, tau=9.0)),)  # beyond SIM_RANGE
    return CalibrationResult(model="idm", fitted=("accel", "decel", "tau", "minGap", "maxSpeed"),
                             population=CFParams(), population_median_rmse_m=1.0, per_pair=fits, spread=(),
                             n_pairs=n, seconds_population=0.0, seconds_per_pair=0.0)


def test_resample_draws_whole_per_pair_vectors_deterministically() -> None:
    res = _result()
    a, b = resample_members(res, 12, seed=3), resample_members(res, 12, seed=3)
    assert a == b and a != resample_members(res, 12, seed=4)
    fitted = {f.params for f in res.per_pair}
    clipped = {replace(p, tau=min(max(p.tau, SIM_RANGE["tau"][0]), SIM_RANGE["tau"][1])) for p in fitted}
    for m in a:  # a whole fitted vector (the joint distribution), clipped to the simulation range
        assert m.params in clipped
        assert m.probability == pytest.approx(1 / 12)
    assert len({m.params for m in a}) > 1
    spread = member_spread(a)
    assert spread["tau"][2] <= SIM_RANGE["tau"][1]
    assert spread["accel"][0] <= spread["accel"][1] <= spread["accel"][2]
    with pytest.raises(ValueError, match="no per-pair fits"):
        resample_members(replace(res, per_pair=()), 4)


def test_sumo_loads_the_sampled_vtype_distribution() -> None:
    """The resampled members go into the route file's vTypeDistribution and SUMO's vehicles
    carry exactly their parameters."""
    members = resample_members(_result(), 4, seed=1)
    base = load_scenario("synthetic")
    cars = to_vtype_specs(members, base.drivers.car[0], "idm")
    spec = replace(base, drivers=replace(base.drivers, car=cars),
                   demand=replace(base.demand, main_veh_h=(1500.0, 1500.0, 1500.0), truck_share=0.0),
                   simulation=replace(base.simulation, duration_s=40.0, warmup_s=5.0))
    xml = routes_xml(spec)
    for m in members:
        assert f'id="{m.id}"' in xml and f'tau="{m.params.tau:.6g}"' in xml

    seen: dict[str, tuple[float, float, float, float]] = {}

    class TypeProbe:
        def on_start(self, ctx) -> None:
            pass

        def on_step(self, ctx, frame) -> None:
            import libsumo

            for sid in frame.sumo_ids:
                tid = libsumo.vehicle.getTypeID(sid)
                seen[sid] = (libsumo.vehicle.getTau(sid), libsumo.vehicle.getAccel(sid),
                             libsumo.vehicle.getMinGap(sid), libsumo.vehicle.getMaxSpeed(sid))
                seen[sid + "|type"] = tid  # type: ignore[assignment]

        def on_end(self, ctx) -> None:
            pass

    run_scenario(spec, seed=5, hooks=[TypeProbe()])
    by_id = {m.id: m.params for m in members}
    types = {v for k, v in seen.items() if k.endswith("|type")}
    assert types and types <= set(by_id) | {"truck"}
    assert len(types) > 1  # the distribution is sampled, not one average driver
    for k, tid in seen.items():
        if not k.endswith("|type") or tid == "truck":
            continue
        tau, accel, min_gap, max_speed = seen[k[: -len("|type")]]
        p = by_id[tid]
        assert (tau, accel, min_gap, max_speed) == pytest.approx((p.tau, p.accel, p.minGap, p.maxSpeed))


def test_spacing_and_headway_defined_alike_on_both_sides() -> None:
    """One hand-made following situation as a trajectory table and as a real pair: bumper-to-bumper
    spacing and front-to-front time headway come out equal."""
    # follower front bumper at 100 ft, leader front bumper at 150 ft, leader 15 ft long: 35 ft bumper to bumper
    y_f, y_l, len_l, len_f, v = 100.0, 150.0, 15.0, 14.0, 20.0
    cols = {c: np.zeros(2, dtype=COLUMNS[c]) for c in COLUMNS if c not in DERIVED}
    cols.update(Vehicle_ID=np.array([1, 2]), Frame_ID=np.array([10, 10]), Lane_ID=np.array([3, 3]),
                Local_Y=np.array([y_f, y_l]), v_Vel=np.array([v, v]), v_Length=np.array([len_f, len_l]))
    table = table_from_columns(cols)
    sim = table_states(table, study_length_ft=1000.0)
    pair = CarFollowingPair(
        name="hand", group="hand/1", t=np.array([0.0]), x_follower=np.array([y_f * M_PER_FT]),
        v_follower=np.array([v * M_PER_FT]), x_leader=np.array([y_l * M_PER_FT]),
        v_leader=np.array([v * M_PER_FT]), leader_length=len_l * M_PER_FT,
    )
    assert pair.spacing == pytest.approx([(y_l - y_f - len_l) * M_PER_FT])
    real = pair_states([pair])
    assert sim["spacing_ft"] == pytest.approx([35.0]) and real["spacing_ft"] == pytest.approx([35.0])
    assert sim["time_headway_s"] == pytest.approx([50.0 / v]) and real["time_headway_s"] == pytest.approx([2.5])
    assert sim["speed_ft_s"] == pytest.approx(real["speed_ft_s"])
    # outside the study area, on the HOV lane or the ramp: not compared
    assert len(table_states(table, study_length_ft=120.0)["spacing_ft"]) == 1  # the leader (150 ft) has none
    assert len(table_states(table, study_length_ft=90.0)["spacing_ft"]) == 0
    for lane in (1, 7):
        cols["Lane_ID"] = np.array([lane, lane])
        assert len(table_states(table_from_columns(cols))["spacing_ft"]) == 0


def test_bottleneck_network_lane_drop_and_speed(tmp_path) -> None:
    road = RoadSpec(main_lanes=3, bottleneck_length_m=120.0, bottleneck_speed_mps=8.0, bottleneck_lanes=2)
    net = sumolib.net.readNet(str(build_network(road, cache_dir=tmp_path)))
    b, out = net.getEdge("bottleneck"), net.getEdge("bottleneck_out")
    assert len(b.getLanes()) == 3 and len(out.getLanes()) == 2
    assert b.getSpeed() == pytest.approx(8.0) and b.getLength() == pytest.approx(120.0, abs=10.0)  # less the junction
    assert not b.getLanes()[0].getOutgoing()  # the rightmost lane ends: a lane drop
    assert net.getEdge("main_out").getOutgoing()
    # a road without a bottleneck keeps its network (and cache key) as before the fields existed
    old = {k: v for k, v in asdict(RoadSpec()).items() if not k.startswith("bottleneck_")}
    payload = json.dumps({"v": NETWORK_FORMAT_VERSION, "road": old}, sort_keys=True)
    assert network_key(RoadSpec()) == hashlib.sha256(payload.encode()).hexdigest()[:16]
    assert network_key(road) != network_key(replace(road, bottleneck_lanes=3))
    spec = ScenarioSpec(name="bn", road=road, demand=DemandSpec(main_veh_h=(900.0, 900.0, 900.0), ramp_veh_h=200.0),
                        simulation=SimulationSpec(duration_s=90.0, warmup_s=10.0))
    assert "main_out bottleneck bottleneck_out" in routes_xml(spec)
    table = run_scenario(spec, seed=2).table
    assert (table["Local_Y"] > road.main_length_m / M_PER_FT).any()  # vehicles drive on past the section


def test_bottleneck_left_drop_ends_the_leftmost_lane(tmp_path) -> None:
    right = RoadSpec(main_lanes=3, bottleneck_length_m=120.0, bottleneck_speed_mps=8.0, bottleneck_lanes=2)
    road = replace(right, bottleneck_drop="left")
    net = sumolib.net.readNet(str(build_network(road, cache_dir=tmp_path)))
    b, out = net.getEdge("bottleneck"), net.getEdge("bottleneck_out")
    assert len(out.getLanes()) == 2
    assert not b.getLanes()[2].getOutgoing()  # SUMO index 2 = the leftmost lane ends
    for i in (0, 1):  # the others go on in their own lateral position
        (con,) = b.getLanes()[i].getOutgoing()
        assert con.getToLane().getID() == f"bottleneck_out_{i}"
        assert out.getLanes()[i].getShape()[0][1] == pytest.approx(b.getLanes()[i].getShape()[-1][1])
    assert network_key(road) != network_key(right)
    # the right drop keeps the key it had before the field existed
    old = {k: v for k, v in asdict(right).items() if k != "bottleneck_drop"}
    payload = json.dumps({"v": NETWORK_FORMAT_VERSION, "road": old}, sort_keys=True)
    assert network_key(right) == hashlib.sha256(payload.encode()).hexdigest()[:16]
    spec = ScenarioSpec(name="bn", road=road, demand=DemandSpec(main_veh_h=(900.0, 900.0, 900.0), ramp_veh_h=200.0),
                        simulation=SimulationSpec(duration_s=90.0, warmup_s=10.0))
    table = run_scenario(spec, seed=2).table
    past = table[table["Local_Y"] > (road.main_length_m + road.bottleneck_length_m + 20.0) / M_PER_FT]
    assert len(past) and set(past["Lane_ID"]) <= {5, 6}  # I-80 lanes 5, 6 go on; lane 4 (leftmost here) ended


@pytest.mark.parametrize("road, field", [
    ("bottleneck_length_m = 100.0\nbottleneck_speed_mps = 0.0", "road.bottleneck_speed_mps"),
    ("bottleneck_length_m = 100.0\nbottleneck_speed_mps = 8.0\nbottleneck_lanes = 4", "road.bottleneck_lanes"),
    ("bottleneck_lanes = 1.5", "road.bottleneck_lanes"),
    ('bottleneck_drop = "middle"', "road.bottleneck_drop"),
    # a bottleneck that would silently not exist or change nothing
    ("bottleneck_speed_mps = 8.0\nbottleneck_lanes = 2", "road.bottleneck_length_m: bottleneck_lanes, bottleneck_speed_mps given"),
    ('bottleneck_drop = "left"', "road.bottleneck_length_m: bottleneck_drop given but no bottleneck"),
    ("bottleneck_length_m = 100.0\nbottleneck_speed_mps = 29.0\nbottleneck_lanes = 3",
     "road.bottleneck_speed_mps: the bottleneck changes nothing"),
    # a lane drop without a speed limit: the missing field is named (was "at least 1 m/s, got 0", a 0 never written)
    ("bottleneck_length_m = 100.0\nbottleneck_lanes = 2",
     "road.bottleneck_speed_mps: missing: a bottleneck of 100 m needs its speed limit"),
])
def test_bottleneck_fields_checked(road: str, field: str) -> None:
    with pytest.raises(SpecError, match=field.replace(".", r"\.")):
        spec_from_toml(f'name = "x"\n[road]\nmain_lanes = 3\n{road}\n', source="x.toml")
    # the same bottleneck with a lower speed limit or a lane drop is accepted
    ok = spec_from_toml('name = "x"\n[road]\nmain_lanes = 3\nbottleneck_length_m = 100.0\n'
                        'bottleneck_speed_mps = 29.0\nbottleneck_lanes = 2\n', source="x.toml")
    assert ok.road.bottleneck_lanes == 2


def test_i80_preset_has_the_bottleneck_and_a_resampled_population() -> None:
    spec = load_scenario("i80")
    assert spec.road.bottleneck_length_m > 0 and spec.road.bottleneck_lanes < spec.road.main_lanes
    cars = spec.drivers.car
    assert len(cars) >= 16 and len({(c.tau, c.accel, c.min_gap_m) for c in cars}) > len(cars) // 2
    # EIDM with its driver noise at SUMO's defaults: IDM made no stop-and-go (docs/calibration.md)
    assert {c.car_follow_model for c in cars} == {"EIDM"}
    assert not any(k.startswith("sigma") for c in cars for k, _ in c.cf_params)


def test_preset_writer_round_trips(tmp_path) -> None:
    res = _result()
    from analysis.calibration import save_result

    p = save_result(res, tmp_path / "params.toml")
    text = preset_with_drivers("synthetic", p, n=6, seed=2, header="written by a test\nline two")
    assert text.startswith("# written by a test\n# line two\n")
    spec = spec_from_toml(text, source="written.toml")
    assert [c.tau for c in spec.drivers.car] == [m.params.tau for m in resample_members(load_result(p), 6, seed=2)]


def test_preset_writer_switches_the_car_following_model(tmp_path) -> None:
    """car_follow_model="EIDM" keeps the resampled IDM vectors (delta included) and writes no
    noise key, so SUMO's EIDM driver noise stays on at its defaults."""
    from analysis.calibration import save_result

    p = save_result(_result(), tmp_path / "params.toml")
    spec = spec_from_toml(preset_with_drivers("synthetic", p, n=6, seed=2, car_follow_model="EIDM"),
                          source="written.toml")
    members = resample_members(load_result(p), 6, seed=2)
    assert [c.car_follow_model for c in spec.drivers.car] == ["EIDM"] * 6
    assert [(c.tau, c.accel, c.min_gap_m) for c in spec.drivers.car] == [
        (m.params.tau, m.params.accel, m.params.minGap) for m in members]
    assert all(dict(c.cf_params) == {"delta": m.params.delta} for c, m in zip(spec.drivers.car, members))
    xml = routes_xml(spec)
    assert xml.count('carFollowModel="EIDM"') == 6 and "sigmaleader" not in xml
    same = spec_from_toml(preset_with_drivers("synthetic", p, n=6, seed=2), source="written.toml")
    assert {c.car_follow_model for c in same.drivers.car} == {"IDM"}


def test_accepted_gaps_of_a_hand_made_merge() -> None:
    """B drives on lane 7 for two frames and is in lane 6 at frame 3, between lag A and lead C."""
    rows = []  # (vid, frame, lane, Local_Y, length)
    for f in (1, 2, 3, 4):
        rows.append((1, f, 6, 100.0 + f, 15.0))           # A: lag
        rows.append((3, f, 6, 200.0 + f, 20.0))           # C: lead
        rows.append((2, f, 7 if f < 3 else 6, 140.0 + f, 14.0))  # B: the ramp car
    rows.append((4, 3, 6, 400.0, 15.0))                  # a main-lane car never on the ramp: not a merge
    a = np.array(rows)
    cols = {c: np.zeros(len(a), dtype=COLUMNS[c]) for c in COLUMNS if c not in DERIVED}
    cols.update(Vehicle_ID=a[:, 0].astype(int), Frame_ID=a[:, 1].astype(int), Lane_ID=a[:, 2].astype(int),
                Local_Y=a[:, 3], v_Length=a[:, 4], v_Vel=np.full(len(a), 20.0))
    gaps = accepted_gaps(table_from_columns(cols))
    assert gaps.n == 1
    # at frame 3: A front 103, B front 143 (rear 129), C front 203 (rear 183)
    assert gaps.lag_ft == pytest.approx([129.0 - 103.0])
    assert gaps.lead_ft == pytest.approx([183.0 - 143.0])
    assert gaps.total_ft == pytest.approx([183.0 - 103.0])
    assert gaps.quantiles()["total_ft"][2] == pytest.approx(80.0)
