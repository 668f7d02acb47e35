"""The take-over rule (sim.merges.take_over): demonstrations cut as the closed-loop controller observes.

Hand-made tables with known answers, and one real SUMO run in which the encounters of the
recorded table equal, row for row, what the controller observed of SUMO's driver."""

from __future__ import annotations

import numpy as np
import pytest
from sim_testutil import short_run
from test_encounters import make_table, straight

from analysis.demo.config import DemoConfig
from sim.closed_loop.config import ControllerConfig
from sim.closed_loop.controller import Controller
from sim.drivers.policy import SumoPolicy
from sim.merges.demonstrators import demonstrator_hooks, encounters_of_run
from sim.merges.encounters import EncounterWindow, extract
from sim.merges.generate import generate
from sim.merges.take_over import TakeOverRule

FR = range(10, 41)


def test_A_is_the_lag_car_when_B_enters_the_zone_not_at_its_merge():
    # B (2) enters the zone (y >= 200) at frame 20 with car 1 behind it; car 1 then overtakes B
    # on lane 6, so at B's merge (frame 30) car 4 is B's lag: the merge-frame rule picks 4,
    # the controller (and the take-over rule) keep 1.
    tracks = {
        1: [(f, 6, 150.0 + 4.0 * (f - 10), 40.0) for f in FR],  # behind B at frame 20, ahead at 30
        2: [(f, 7 if f < 30 else 6, 190.0 + 1.0 * (f - 10), 10.0) for f in FR],  # B, in zone from frame 20
        4: straight(FR, 6, 100.0, 40.0),
    }
    t = make_table(tracks)
    assert extract(t).merges.A_id[0] == 4
    rule = TakeOverRule(zone_start_ft=200.0, max_lag_ft=250.0, hold_frames=3)
    enc = extract(t, take_over=rule)
    m = enc.merges
    assert (m.A_id[0], m.first_frame[0]) == (1, 20)
    # observed from the take-over until hold_frames after the merge (frames 20..32)
    assert enc.frames.Frame_ID.tolist() == list(range(20, 33))
    assert m.n_frames[0] == 13


def test_no_lag_within_reach_waits_and_a_busy_car_is_not_taken():
    tracks = {
        1: straight(FR, 6, 0.0, 30.0),  # 250 ft behind B2 at first; within reach later
        2: [(f, 7 if f < 35 else 6, 250.0 + 1.0 * (f - 10), 10.0) for f in FR],  # B
        3: [(f, 7 if f < 35 else 6, 255.0 + 1.0 * (f - 10), 10.0) for f in FR],  # a second B beside it
    }
    rule = TakeOverRule(zone_start_ft=200.0, max_lag_ft=240.0, hold_frames=0)
    enc = extract(make_table(tracks), take_over=rule)
    m = enc.merges.set_index("B_id")
    # B2 is 250 - 2 (f - 10) ft ahead of car 1: within 240 ft from frame 15 on, when B2 takes it
    # (a lower Vehicle_ID than B3's in the same frame); B3 gets no A while car 1 is busy with B2
    assert m.loc[2, "A_id"] == 1 and m.loc[3, "A_id"] == 0
    assert m.loc[2, "first_frame"] == 15


def test_encounter_ends_when_A_leaves_lane_6_and_C_is_As_lead_other_than_B():
    tracks = {
        1: [(f, 6 if f < 26 else 5, 150.0 + 4.0 * (f - 10), 40.0) for f in FR],  # A leaves lane 6 at 26
        2: [(f, 7 if f < 24 else 6, 210.0 + 3.0 * (f - 10), 30.0) for f in FR],  # B merges at 24
        3: straight(FR, 6, 400.0, 30.0),  # C
    }
    rule = TakeOverRule(zone_start_ft=200.0, hold_frames=30)
    enc = extract(make_table(tracks), take_over=rule)
    f = enc.frames
    assert f.Frame_ID.tolist() == list(range(10, 26))
    assert (f.C_id == 3).all()  # B in lane 6 ahead of A after frame 24 is not C
    k = f.Frame_ID.to_numpy() - 10
    np.testing.assert_allclose(f.d_AC, 400.0 + 3.0 * k - (150.0 + 4.0 * k))


def test_rule_and_window_checks():
    with pytest.raises(ValueError, match="window"):
        extract(make_table({1: straight(FR, 6, 0.0, 30.0)}), window=EncounterWindow(frames_after=3),
                take_over=TakeOverRule(zone_start_ft=0.0))
    for bad in ({"zone_start_ft": float("nan")}, {"zone_start_ft": 0.0, "max_lag_ft": 0.0},
                {"zone_start_ft": 0.0, "hold_frames": -1}, {"zone_start_ft": 0.0, "max_frames": 0}):
        with pytest.raises(ValueError):
            TakeOverRule(**bad)
    with pytest.raises(ValueError, match="encounter rule"):
        generate(None, encounter_rule="lag-at-merge")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="merge-frame"):  # before any simulation
        generate(None, window=EncounterWindow(frames_after=2))  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="encounter rule"):
        DemoConfig(encounter_rule="merge")
    rule = TakeOverRule.of_controller(ControllerConfig(zone_margin_ft=50.0, hold_after_merge_s=2.0), 500.0)
    assert (rule.zone_start_ft, rule.hold_frames, rule.max_frames) == (450.0, 20, 600)
    with pytest.raises(ValueError, match="auxiliary lane starts.*merge-frame"):
        TakeOverRule.of_controller(ControllerConfig(), float("nan"))
    assert TakeOverRule.of_controller(ControllerConfig(zone_start_ft=300.0), float("nan")).zone_start_ft == 300.0


@pytest.mark.sumo
def test_encounters_are_what_the_controller_observes_of_sumos_driver(tmp_path):
    ctl = Controller(SumoPolicy(), ControllerConfig(decision_step_s=0.1))  # observes every frame
    res = short_run(tmp_path, seed=2001, duration_s=240.0, hooks=[ctl])
    enc = extract(res.table, take_over=TakeOverRule.of_controller(ControllerConfig(), res.aux_lane_start_ft),
                  teleported=res.teleported_vehicle_ids)
    dec = ctl.decision_table().sort_values(["a_id", "b_id", "frame"]).reset_index(drop=True)
    f = enc.frames.sort_values(["A_id", "B_id", "Frame_ID"]).reset_index(drop=True)
    assert len(dec) >= 200 and len(f) == len(dec)
    assert (f.A_id.to_numpy() == dec.a_id.to_numpy()).all() and (f.B_id.to_numpy() == dec.b_id.to_numpy()).all()
    assert (f.Frame_ID.to_numpy() == dec.frame.to_numpy()).all() and (f.C_id.to_numpy() == dec.c_id.to_numpy()).all()
    for col in ("d_AC", "d_AB", "v_AC", "v_AB", "len_C", "len_B"):
        np.testing.assert_allclose(f[col].to_numpy(), dec[col].to_numpy(), rtol=0, atol=1e-9)
    # the lengths are the vehicles' own (trucks among them), NaN exactly without C
    np.testing.assert_array_equal(np.isnan(f.len_C.to_numpy()), f.C_id.to_numpy() == 0)
    length = res.table.groupby("Vehicle_ID").v_Length.first()
    np.testing.assert_array_equal(f.len_B.to_numpy(), length.loc[f.B_id].to_numpy())
    with_c = f[f.C_id != 0]
    np.testing.assert_array_equal(with_c.len_C.to_numpy(), length.loc[with_c.C_id].to_numpy())
    assert with_c.len_C.nunique() > 1  # cars and trucks
    # SUMO's driver leaves lane 6 in some encounters: released there, and no row has A outside lane 6
    reasons = ctl.control_table().reason
    assert (reasons == "left_lane").any()
    lane = res.table.set_index(["Vehicle_ID", "Frame_ID"]).Lane_ID
    assert (lane.loc[list(zip(f.A_id, f.Frame_ID))].to_numpy() == 6).all()


@pytest.mark.sumo
def test_in_lane_demonstrations_are_the_observing_controllers_encounters(tmp_path):
    hooks = demonstrator_hooks("in-lane")
    res = short_run(tmp_path, seed=2001, duration_s=200.0, hooks=hooks)
    enc = encounters_of_run(res)  # in-lane is the default
    ctl = hooks[0]
    assert isinstance(ctl, Controller) and not ctl.policy.controls and ctl.policy.keep_lane
    ct = ctl.control_table()
    assert len(ct) >= 5 and not (ct.reason == "left_lane").any()  # A's lane is held while observed
    m = enc.merges[enc.merges.A_id != 0].sort_values("B_id").reset_index(drop=True)
    # a B that never merges in the run holds its A in the controller and is no encounter
    assert (ct[~ct.b_id.isin(m.B_id)].merge_frame < 0).all()
    ct = ct[ct.b_id.isin(m.B_id)].sort_values("b_id").reset_index(drop=True)
    assert m.B_id.tolist() == ct.b_id.tolist() and m.A_id.tolist() == ct.a_id.tolist()
    assert m.first_frame.tolist() == ct.start_frame.tolist()
    lane = res.table.set_index(["Vehicle_ID", "Frame_ID"]).Lane_ID
    f = enc.frames
    assert (lane.loc[list(zip(f.A_id, f.Frame_ID))].to_numpy() == 6).all()
    with pytest.raises(ValueError, match="merge-frame"):
        encounters_of_run(res, window=EncounterWindow(frames_after=5))
    # a run made without the hooks: its As leave lane 6 while observed, and in-lane says so
    free = short_run(tmp_path, seed=2001, duration_s=200.0)
    with pytest.warns(UserWarning, match="demonstrator_hooks"):
        encounters_of_run(free)
    with pytest.raises(ValueError, match="encounter rule"):
        demonstrator_hooks("lag")
