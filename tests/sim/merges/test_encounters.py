"""Merge encounters: on a real SUMO run and on hand-made tables with known answers."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from sim_testutil import short_run

from irl.domains.merge.encounters import ENCOUNTER_COLUMNS
from sim.merges.encounters import MERGE_COLUMNS, EncounterWindow, extract, extract_encounters
from sim.runtime.schema import COLUMNS
from sim.runtime.table import add_derived_columns


def make_table(tracks: dict[int, list[tuple[int, int, float, float]]], *, trucks=(), acc=None) -> pd.DataFrame:
    """tracks: Vehicle_ID -> [(Frame_ID, Lane_ID, Local_Y, v_Vel)]; v_Acc = 10 * id + frame / 100."""
    rows = []
    for vid, pts in tracks.items():
        for frame, lane, y, v in pts:
            rows.append({
                "Vehicle_ID": vid, "Frame_ID": frame, "Total_Frames": 0, "Global_Time": frame * 100,
                "Local_X": 6.0 * lane, "Local_Y": y, "Global_X": y, "Global_Y": -6.0 * lane,
                "v_Length": 15.0, "v_Width": 6.0, "v_Class": 3 if vid in trucks else 2, "v_Vel": v,
                "v_Acc": 10.0 * vid + frame / 100.0, "Lane_ID": lane, "Preceding": 0, "Following": 0,
                "Space_Headway": 0.0, "Time_Headway": 0.0,
            })
    return add_derived_columns(pd.DataFrame(rows, columns=list(COLUMNS)))


def straight(frames, lane, y0, v):
    return [(f, lane, y0 + v * 0.1 * (f - frames[0]), v) for f in frames]


def test_definitions_and_signs_on_a_hand_made_merge():
    fr = range(10, 21)
    tracks = {
        1: straight(fr, 6, 100.0, 50.0),  # A: lane 6, behind
        2: [(f, 7 if f < 18 else 6, 130.0 + 40.0 * 0.1 * (f - 10), 40.0) for f in fr],  # B merges at 18
        3: straight(fr, 6, 200.0, 45.0),  # C: lane 6, ahead
        4: straight(fr, 6, 20.0, 50.0),  # further behind A: not A
        5: straight(fr, 5, 140.0, 60.0),  # lane 5: ignored
    }
    enc = extract(make_table(tracks, trucks=(2,)))
    m = enc.merges
    assert list(m.columns) == list(MERGE_COLUMNS) and len(m) == 1
    assert (m.B_id[0], m.A_id[0], m.C_id[0], m.merge_frame[0], m.first_frame[0]) == (2, 1, 3, 18, 10)
    f = enc.frames
    assert list(f.columns) == list(ENCOUNTER_COLUMNS) and len(f) == 9  # frames 10..18
    assert {c: str(f[c].dtype) for c in f.columns} == ENCOUNTER_COLUMNS
    k = np.arange(10, 19)
    yA, yB, yC = 100 + 5.0 * (k - 10), 130 + 4.0 * (k - 10), 200 + 4.5 * (k - 10)
    assert np.allclose(f.d_AC, yC - yA) and np.allclose(f.d_AB, yB - yA)
    assert np.allclose(f.v_AC, 50 - 45) and np.allclose(f.v_AB, 50 - 40)
    assert f.B_is_truck.all() and np.allclose(f.acc_A, 0.0)  # A's speed is constant; v_Acc is not used
    assert (f.Global_Time == f.Frame_ID * 100).all() and (f.merge_frame == 18).all()
    assert (f.len_C == 15.0).all() and (f.len_B == 15.0).all()  # the vehicles' v_Length
    # lengths are unknown (NaN) without a v_Length column, or where it is not > 0
    table = make_table(tracks, trucks=(2,))
    table.loc[table.Vehicle_ID == 3, "v_Length"] = 0.0
    f0 = extract(table).frames
    assert f0.len_C.isna().all() and (f0.len_B == 15.0).all()
    f1 = extract(table.drop(columns=["v_Length"])).frames
    assert f1.len_C.isna().all() and f1.len_B.isna().all()
    assert np.allclose(f1.d_AC, f.d_AC)


def test_action_is_the_forward_difference_of_A_speed():
    # A's speed changes every frame; v_Acc (10 * id + frame / 100) must not be used
    speeds = {f: 50.0 + 0.05 * (f - 10) ** 2 for f in range(10, 25)}

    def tracks(a_last):
        return {1: [(f, 6, 100.0 + 5.0 * (f - 10), speeds[f]) for f in range(10, a_last + 1) if f != 14],
                2: [(f, 7 if f < 18 else 6, 130.0 + 4.0 * (f - 10), 40.0) for f in range(10, 25)]}

    # A's trajectory goes on past the merge frame: the window's last frame takes A's next frame
    f = extract_encounters(make_table(tracks(24)))
    # frame 14 (A missing) and 13 (its next speed unknown) have no row; 18 uses frame 19
    assert f.Frame_ID.tolist() == [10, 11, 12, 15, 16, 17, 18]
    expected = [(speeds[k + 1] - speeds[k]) / 0.1 for k in f.Frame_ID]
    np.testing.assert_allclose(f.acc_A, expected)
    np.testing.assert_allclose(f.acc_A, 2 * 0.05 * (f.Frame_ID - 10) / 0.1 + 0.05 / 0.1)
    # A's trajectory ends at the merge frame: that frame has no action and is dropped
    f = extract_encounters(make_table(tracks(18)))
    assert f.Frame_ID.tolist() == [10, 11, 12, 15, 16, 17]


def test_window_parameter():
    fr = range(0, 51)
    tracks = {1: straight(fr, 6, 0.0, 50.0),
              2: [(f, 7 if f < 40 else 6, 100.0 + 4.0 * f, 40.0) for f in fr],
              3: straight(fr, 6, 300.0, 50.0)}
    t = make_table(tracks)
    assert extract_encounters(t).Frame_ID.tolist() == list(range(0, 41))
    assert extract_encounters(t, window=EncounterWindow(max_frames_before=5)).Frame_ID.tolist() == list(range(35, 41))
    after = extract_encounters(t, window=EncounterWindow(max_frames_before=0, frames_after=3))
    assert after.Frame_ID.tolist() == [40, 41, 42, 43]
    with pytest.raises(ValueError, match="max_frames_before"):
        EncounterWindow(max_frames_before=-1)


def test_window_starts_when_both_are_in_the_section():
    tracks = {1: straight(range(15, 31), 6, 0.0, 50.0),  # A appears at frame 15
              2: [(f, 7 if f < 25 else 6, 100.0 + 4.0 * (f - 5), 40.0) for f in range(5, 31)]}
    f = extract_encounters(make_table(tracks))
    assert f.Frame_ID.min() == 15 and f.Frame_ID.max() == 25


def test_merge_straight_from_an_internal_lane_and_missing_neighbours():
    tracks = {
        # B1: seen in lane 7 at frames 0..2, missing 3..5 (junction), then straight in lane 6
        1: [(f, 7, 50.0 + 4 * f, 40.0) for f in range(0, 3)] + [(f, 6, 50.0 + 4 * f, 40.0) for f in range(6, 12)],
        # B2 merges with nobody behind it in lane 6 (no A) but a vehicle ahead
        2: [(f, 7 if f < 8 else 6, 500.0 + 4 * f, 40.0) for f in range(0, 12)],
        # a lane-6 car between B1 and B2: B1's C, B2's nothing (it is behind B2 -> B2's A!)
        3: straight(range(0, 12), 6, 200.0, 40.0),
        # vehicle going 6 -> 7 -> never back: not a merge
        4: [(f, 6 if f < 4 else 7, 900.0 + 4 * f, 40.0) for f in range(0, 12)],
        # a main-road car that is in lane 6 first, then 7, then 6 again: merges at its second lane-6 entry
        5: [(f, 6 if f < 3 or f >= 9 else 7, 1500.0 + 4 * f, 40.0) for f in range(0, 12)],
    }
    enc = extract(make_table(tracks))
    m = enc.merges.set_index("B_id")
    assert sorted(m.index) == [1, 2, 5]
    assert (m.loc[1, "merge_frame"], m.loc[1, "A_id"], m.loc[1, "C_id"]) == (6, 0, 3)
    assert (m.loc[2, "merge_frame"], m.loc[2, "A_id"], m.loc[2, "C_id"]) == (8, 3, 0)
    assert (m.loc[5, "merge_frame"], m.loc[5, "A_id"], m.loc[5, "C_id"]) == (9, 2, 0)
    # without A: a summary row, no per-frame rows; without C: NaN d_AC / v_AC
    assert m.loc[1, "n_frames"] == 0 and 1 not in set(enc.frames.B_id)
    f2 = enc.frames[enc.frames.B_id == 2]
    assert len(f2) == m.loc[2, "n_frames"] == 9 and f2.d_AC.isna().all() and f2.v_AC.isna().all()
    assert np.allclose(f2.d_AB, 300.0)
    assert enc.merges.encounter_id.tolist() == [1, 2, 3]


def test_no_merges_gives_empty_tables_with_schema():
    enc = extract(make_table({1: straight(range(5), 6, 0.0, 40.0)}))
    assert enc.frames.empty and list(enc.frames.columns) == list(ENCOUNTER_COLUMNS)
    assert enc.merges.empty and list(enc.merges.columns) == list(MERGE_COLUMNS)


@pytest.mark.sumo
def test_every_ramp_vehicle_reaching_lane_6_yields_one_encounter(tmp_path):
    res = short_run(tmp_path, duration_s=200.0)
    t = res.table
    enc = extract(t)
    # ramp vehicles are the SUMO flow "R7"; those recorded on the ramp lane that later drive in lane 6
    ramp_ids = {i + 1 for i, s in enumerate(res.sumo_ids) if s.startswith("R7.")}
    first7 = t[t.Lane_ID == 7].groupby("Vehicle_ID").Frame_ID.min()
    merged = {v for v in ramp_ids if v in first7.index
              and ((t.Vehicle_ID == v) & (t.Lane_ID == 6) & (t.Frame_ID > first7[v])).any()}
    assert len(merged) >= 5
    assert sorted(enc.merges.B_id) == sorted(merged)
    assert enc.merges.B_id.is_unique
    key = t.set_index(["Vehicle_ID", "Frame_ID"])
    with_a = enc.merges[(enc.merges.A_id != 0)]
    assert len(with_a) >= 3
    for _, m in enc.merges.iterrows():
        yb = key.loc[(m.B_id, m.merge_frame), "Local_Y"]
        assert key.loc[(m.B_id, m.merge_frame), "Lane_ID"] == 6
        for role, sign in (("A_id", -1), ("C_id", 1)):
            if m[role]:
                r = key.loc[(m[role], m.merge_frame)]
                assert r.Lane_ID == 6 and sign * (r.Local_Y - yb) > 0
        # nobody in lane 6 between A and B or between B and C
        lane6 = t[(t.Frame_ID == m.merge_frame) & (t.Lane_ID == 6) & (t.Vehicle_ID != m.B_id)]
        lo = key.loc[(m.A_id, m.merge_frame), "Local_Y"] if m.A_id else -np.inf
        hi = key.loc[(m.C_id, m.merge_frame), "Local_Y"] if m.C_id else np.inf
        assert not ((lane6.Local_Y > lo) & (lane6.Local_Y < hi)).any()
    # per-frame rows: at the merge frame d_AB > 0 (A behind B) and d_AC > d_AB (C ahead of B)
    last = enc.frames[enc.frames.Frame_ID == enc.frames.merge_frame]
    assert len(last) == len(with_a)
    assert (last.d_AB > 0).all() and ((last.d_AC > last.d_AB) | last.d_AC.isna()).all()
    # the action at frame t is A's forward speed difference (v(t+1) - v(t)) / 0.1 s, from the table
    f = enc.frames
    v_now = key.loc[list(zip(f.A_id, f.Frame_ID)), "v_Vel"].to_numpy()
    v_next = key.loc[list(zip(f.A_id, f.Frame_ID + 1)), "v_Vel"].to_numpy()
    np.testing.assert_allclose(f.acc_A.to_numpy(), (v_next - v_now) / 0.1, rtol=0, atol=1e-9)
    # ... which is SUMO's backward-difference v_Acc of the NEXT frame, not of frame t
    acc_next = key.loc[list(zip(f.A_id, f.Frame_ID + 1)), "v_Acc"].to_numpy()
    acc_now = key.loc[list(zip(f.A_id, f.Frame_ID)), "v_Acc"].to_numpy()
    assert np.mean(np.abs(f.acc_A.to_numpy() - acc_next) < 1e-3) > 0.95
    assert np.mean(np.abs(f.acc_A.to_numpy() - acc_now) < 1e-3) < np.mean(np.abs(f.acc_A.to_numpy() - acc_next) < 1e-3)


def _gap_tracks(b_missing=(), a_missing=()):
    fr = range(10, 31)
    return {
        1: [p for p in straight(fr, 6, 100.0, 50.0) if p[0] not in a_missing],  # A
        2: [(f, 7 if f < 22 else 6, 130.0 + 4.0 * (f - 10), 40.0) for f in fr if f not in b_missing],  # B: 22
        3: straight(fr, 6, 250.0, 45.0),  # C
    }


def test_a_merge_first_seen_after_a_gap_is_flagged_not_dated_silently():
    """Missing frames: B's rows 18..21 (its last ramp frames) are missing, so B is first seen in
    lane 6 at frame 22 but may have merged at 18: merge_observed is False, 4 frames missing."""
    full = extract(make_table(_gap_tracks()))
    assert full.merges.merge_observed.all() and (full.merges.merge_gap_frames == 0).all()
    assert full.frames.merge_observed.all() and (full.merges.frame_gaps == 0).all()
    enc = extract(make_table(_gap_tracks(b_missing=range(18, 22))))
    m = enc.merges
    assert (m.merge_frame[0], bool(m.merge_observed[0]), m.merge_gap_frames[0]) == (22, False, 4)
    assert (~enc.frames.merge_observed).all()
    assert m.frame_gaps[0] == 1  # the window's frames 18..21 are missing (B is not there)
    assert list(enc.frames.Frame_ID) == [*range(10, 18), 22]
    # A missing mid-window: a gap in the frames, the merge itself observed
    enc = extract(make_table(_gap_tracks(a_missing=(14, 15))))
    assert bool(enc.merges.merge_observed[0]) and enc.merges.frame_gaps[0] == 1
    assert 14 not in set(enc.frames.Frame_ID) and 13 not in set(enc.frames.Frame_ID)  # no A at t+1: no action


def test_encounters_cli_reports_gaps_in_its_load_report(tmp_path, capsys):
    """The NGSIM case file with rows cut out: `merge-irl encounters` says what the gaps did."""
    from pathlib import Path

    from analysis.cli.main import main
    from sim.merges.encounters import find_merges
    from sim.ngsim.io import read_ngsim

    src = Path(__file__).resolve().parents[2] / "data" / "cases" / "ngsim-noisy-duplicates" / "clean.csv"
    table = read_ngsim(src).table
    merge = find_merges(table).iloc[0]
    b, mf = int(merge.B_id), int(merge.merge_frame)
    lines = src.read_text().splitlines()
    cut = [ln for ln in lines[1:] if not (int(ln.split(",")[0]) == b and mf - 6 <= int(ln.split(",")[1]) < mf)]
    gappy = tmp_path / "gappy.csv"
    gappy.write_text("\n".join([lines[0], *cut]) + "\n")
    assert main(["encounters", str(gappy), "--out", str(tmp_path / "enc.parquet")]) == 0
    err = capsys.readouterr().err
    assert "vehicles with frame gaps: 1 (1 gaps, 6 missing frames" in err
    assert "frame gaps: 1 encounter(s) with 1 gap(s) in their frames" in err
    assert "merges not observed: 1 B first seen in the merge lane after missing frames (up to 6 frames late" in err
    report = (tmp_path / "enc.load-report.txt").read_text()
    assert "merges not observed: 1" in report and "frame gaps: 1 encounter(s)" in report
    merges = pd.read_parquet(tmp_path / "enc.merges.parquet")
    assert merges.merge_observed.tolist() == [False] and merges.merge_gap_frames.tolist() == [6]
