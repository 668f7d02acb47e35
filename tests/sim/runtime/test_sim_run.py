"""Real SUMO runs: schema and units, determinism, kinematics, neighbours, hooks, clean shutdown."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from sim_testutil import short_run

from merge_irl.units import FT_PER_M
from sim.runtime.schema import COLUMNS, V_CLASS_AUTO, V_CLASS_TRUCK

pytestmark = pytest.mark.sumo


class RecordingHook:
    def __init__(self):
        self.calls = []
        self.frames = []

    def on_start(self, ctx):
        self.calls.append("start")
        self.ctx = ctx

    def on_step(self, ctx, frame):
        self.calls.append("step")
        self.frames.append((frame.frame, frame.vehicle_id.copy(), frame.local_y.copy(), frame.speed.copy(),
                            frame.lane_id.copy(), frame.sumo_ids))

    def on_end(self, ctx):
        self.calls.append("end")


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    hook = RecordingHook()
    res = short_run(tmp_path_factory.mktemp("cache"), hooks=[hook])
    return res, hook


def test_schema_and_units(run):
    res, _ = run
    t = res.table
    assert list(t.columns) == list(COLUMNS)
    assert {c: str(t[c].dtype) for c in t.columns} == COLUMNS
    assert len(t) == res.n_vehicle_steps > 1000
    spec = res.spec
    # warm-up frames (60 s) are not recorded; frames are 0.1 s, Global_Time in ms
    assert t["Frame_ID"].min() == round(spec.simulation.warmup_s / 0.1)
    assert t["Frame_ID"].max() == round(spec.simulation.duration_s / 0.1)
    assert (t["Global_Time"] == t["Frame_ID"] * 100).all()
    # lanes: 3 main lanes numbered 4..6 like I-80's rightmost lanes, 7 the ramp/aux lane
    assert set(t["Lane_ID"].unique()) == {4, 5, 6, 7}
    # feet: lengths are the spec's metres times 3.2808
    car, truck = spec.drivers.car[0], spec.drivers.truck[0]
    cars, trucks = t[t.v_Class == V_CLASS_AUTO], t[t.v_Class == V_CLASS_TRUCK]
    assert np.allclose(cars["v_Length"], car.length_m * FT_PER_M)
    assert len(trucks) == 0 or np.allclose(trucks["v_Length"], truck.length_m * FT_PER_M)
    assert set(t["v_Class"].unique()) <= {V_CLASS_AUTO, V_CLASS_TRUCK}
    main = t[t.Lane_ID < 7]
    assert 0 <= main["Local_Y"].min() and main["Local_Y"].max() <= spec.road.main_length_m * FT_PER_M + 1
    assert 0 < main["Local_X"].min() and main["Local_X"].max() < spec.road.main_lanes * spec.road.lane_width_m * FT_PER_M
    # speeds in ft/s: a free-flowing freeway is 40..100 ft/s, never above the fastest vType's max
    assert 40 < t["v_Vel"].mean() < 100 and t["v_Vel"].max() <= 40.0 * FT_PER_M + 1e-6
    # Local_X is the lateral position from the left edge: lane k sits at about (k - 3.5) lane widths
    w = spec.road.lane_width_m * FT_PER_M
    for lane in (4, 5, 6):
        x = t.loc[t.Lane_ID == lane, "Local_X"]
        assert np.allclose(x.median(), (lane - 4 + 0.5) * w, atol=1.0)


def test_vehicle_ids_consecutive_and_total_frames(run):
    res, _ = run
    t = res.table
    ids = np.sort(t["Vehicle_ID"].unique())
    assert ids[0] == 1 and np.array_equal(ids, np.arange(1, len(ids) + 1)) and len(ids) == res.n_vehicles
    assert (t.groupby("Vehicle_ID")["Frame_ID"].transform("size") == t["Total_Frames"]).all()
    # each vehicle's frames are contiguous (no gaps) and in order
    g = t.groupby("Vehicle_ID")["Frame_ID"]
    assert ((g.max() - g.min() + 1) == g.size()).all()
    # insertion order: a vehicle with a larger id never appears earlier
    assert g.min().is_monotonic_increasing


def test_kinematic_consistency(run):
    t = run[0].table
    same = t["Vehicle_ID"].diff().eq(0).to_numpy()
    dy = t["Local_Y"].diff().to_numpy()[same] / 0.1
    v = t["v_Vel"].to_numpy()[same]
    ramp = (t["Lane_ID"].to_numpy()[same] == 7)
    # SUMO's Euler update: the position advances by the new speed x dt (cos of the ramp angle on the ramp)
    assert np.abs(dy[~ramp] - v[~ramp]).max() < 0.05 * 3.28
    assert np.abs(dy[ramp] - v[ramp]).max() < 0.01 * v[ramp].max() + 0.2
    # acceleration is the speed change per second
    dv = t["v_Vel"].diff().to_numpy()[same] / 0.1
    a = t["v_Acc"].to_numpy()[same]
    assert np.abs(dv - a).max() < 1e-6 * 3.28 + 1e-6


def test_preceding_following_headways(run):
    t = run[0].table
    key = t.set_index(["Vehicle_ID", "Frame_ID"])
    has = t[t.Preceding != 0]
    assert len(has) > 0
    lead = key.loc[pd.MultiIndex.from_arrays([has.Preceding, has.Frame_ID])]
    assert (lead["Lane_ID"].to_numpy() == has["Lane_ID"].to_numpy()).all()
    gap = lead["Local_Y"].to_numpy() - has["Local_Y"].to_numpy()
    assert (gap >= 0).all() and np.allclose(gap, has["Space_Headway"])
    moving = has["v_Vel"] > 1
    assert np.allclose(has.loc[moving, "Time_Headway"], has.loc[moving, "Space_Headway"] / has.loc[moving, "v_Vel"])
    # following is the inverse relation of preceding
    assert (lead["Following"].to_numpy() == has["Vehicle_ID"].to_numpy()).all()
    none = t[t.Preceding == 0]
    assert (none["Space_Headway"] == 0).all() and (none["Time_Headway"] == 0).all()
    # the preceding vehicle is the nearest one ahead: nobody in the same lane/frame lies in between
    sample = has.sample(200, random_state=0)
    for _, r in sample.iterrows():
        same = t[(t.Frame_ID == r.Frame_ID) & (t.Lane_ID == r.Lane_ID)]
        ahead = same[same.Local_Y > r.Local_Y]
        assert ahead.loc[ahead.Local_Y.idxmin(), "Vehicle_ID"] == r.Preceding


def test_hooks_called_once_per_frame_with_matching_data(run):
    res, hook = run
    t = res.table
    frames = np.sort(t["Frame_ID"].unique())
    assert hook.calls[0] == "start" and hook.calls[-1] == "end"
    assert hook.calls.count("step") == len(frames) == len(hook.frames)
    assert [f[0] for f in hook.frames] == list(frames)
    assert hook.ctx.main_lanes == (4, 5, 6) and set(hook.ctx.lane_shapes) == {"4", "5", "6", "7"}
    key = t.set_index(["Frame_ID", "Vehicle_ID"]).sort_index()
    for frame, vid, y, v, lane, sids in hook.frames[:: max(1, len(hook.frames) // 25)]:
        rows = key.loc[pd.MultiIndex.from_arrays([np.full(len(vid), frame), vid])]
        assert np.array_equal(rows["Local_Y"].to_numpy(), y)
        assert np.array_equal(rows["v_Vel"].to_numpy(), v)
        assert np.array_equal(rows["Lane_ID"].to_numpy(), lane)
        assert [res.sumo_ids[i - 1] for i in vid] == list(sids)
        assert (key.loc[frame].shape[0]) == len(vid)


def test_same_seed_same_table_other_seed_differs(run, tmp_path):
    res, _ = run
    again = short_run(tmp_path, seed=res.seed)
    pd.testing.assert_frame_equal(again.table, res.table)
    other = short_run(tmp_path, seed=res.seed + 1)
    assert len(other.table) != len(res.table) or not other.table.equals(res.table)


def test_interrupt_in_a_hook_closes_sumo(tmp_path):
    class Interrupt:
        def __init__(self):
            self.ended = False

        def on_start(self, ctx):
            pass

        def on_step(self, ctx, frame):
            if frame.time_s > 5:
                raise KeyboardInterrupt

        def on_end(self, ctx):
            self.ended = True

    h = Interrupt()
    with pytest.raises(KeyboardInterrupt):
        short_run(tmp_path, duration_s=30.0 + 60.0, hooks=[h])
    assert h.ended
    # the libsumo session was closed: a new simulation starts in this process
    res = short_run(tmp_path, duration_s=65.0)
    assert len(res.table) > 0
