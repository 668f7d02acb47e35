"""Real data as users bring it: the field cases of ``tests/data/cases/`` (made-up
inputs in public formats, with the expected values of their README) and inputs of the same
kinds built here: several recordings in one file, lane coding per site, the loader's report on
the command line, invisible bytes, units, SUMO's teleports and unserved demand."""

from __future__ import annotations

import dataclasses
import json
import tomllib
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from analysis.cli.main import main as cli
from analysis.recording.log import RerunLogger
from irl.domains.merge import mdp as merge_mdp
from irl.domains.merge.bins import DegenerateBinsWarning, fit_quantile_bins
from irl.errors import DemonstrationError
from irl.problems import RawAccelerationWarning, load_merge_demos
from scenarios.loader import load_scenario
from scenarios.spec.parse import with_overrides
from sim.errors import TrajectoryFormatError
from sim.merges.encounters import extract
from sim.merges.generate import RUN_REPORT, generate
from sim.ngsim.io import read_ngsim, write_ngsim_csv
from sim.runtime.run import run_scenario
from sim.runtime.sites import I80, US101, SiteProfile, load_site

CASES = Path(__file__).parent / "data" / "cases"
MIXED = CASES / "ngsim-mixed-locations"
US101_SCENE = CASES / "ngsim-us101-lanes" / "us101_scene.csv"
NOISY = CASES / "ngsim-noisy-duplicates"
EXCEL = CASES / "ngsim-excel-export"
TELEPORT = CASES / "teleport-short-aux" / "teleport.toml"


def _merges(table: pd.DataFrame, **kw) -> list[tuple[int, int, int, int]]:
    m = extract(table, **kw).merges
    return [(int(r.B_id), int(r.A_id), int(r.C_id), int(r.n_frames)) for r in m.itertuples()]


def _i80() -> pd.DataFrame:
    return read_ngsim(MIXED / "i80_only.csv").table


# --- kind 1: several recordings in one file -------------------------------------------------

def test_mixed_sites_refused_naming_column_and_sites() -> None:
    with pytest.raises(TrajectoryFormatError) as ei:
        read_ngsim(MIXED / "combined.csv")
    msg = str(ei.value)
    assert "combined.csv" in msg and "column Location" in msg and "'i-80'" in msg and "'us-101'" in msg


def test_mixed_sites_restricted_to_i80_equals_i80_only() -> None:
    got = read_ngsim(MIXED / "combined.csv", location="I-80")
    ref = read_ngsim(MIXED / "i80_only.csv")
    pd.testing.assert_frame_equal(got.table, ref.table)
    assert _merges(got.table) == [(20, 10, 11, 71)]
    pd.testing.assert_frame_equal(extract(got.table).frames, extract(ref.table).frames)
    assert got.report.location == "i-80" and got.report.rows_read == 900 and got.report.rows_kept == 400


def test_unknown_location_lists_sites() -> None:
    with pytest.raises(TrajectoryFormatError, match=r"column Location: no rows of site 'i-5'.*'i-80'.*'us-101'"):
        read_ngsim(MIXED / "combined.csv", location="i-5")


def test_location_on_file_without_column_is_an_error() -> None:
    with pytest.raises(TrajectoryFormatError, match=r"no Location column"):
        read_ngsim(US101_SCENE, location="us-101")


def _two_periods(tmp_path: Path, shift_frames: int) -> Path:
    """i80_only's scene twice: the same vehicle ids an hour apart (a second period)."""
    t = _i80()
    t2 = t.copy()
    t2["Frame_ID"] += shift_frames
    t2["Global_Time"] += 3_600_000  # one hour later
    both = pd.concat([t, t2], ignore_index=True)
    return write_ngsim_csv(both, tmp_path / "two_periods.csv")


@pytest.mark.parametrize("shift_frames", [0, 5000])
def test_periods_told_apart_by_global_time(tmp_path: Path, shift_frames: int) -> None:
    p = _two_periods(tmp_path, shift_frames)
    with pytest.raises(TrajectoryFormatError) as ei:
        read_ngsim(p)
    msg = str(ei.value)
    assert "column Global_Time: 2 recordings" in msg and "#1" in msg and "#2" in msg
    one = read_ngsim(p, recording=1)
    two = read_ngsim(p, recording=2)
    assert _merges(one.table) == _merges(two.table) == [(20, 10, 11, 71)]
    assert len(one.table) == len(two.table) == 400
    assert two.table["Frame_ID"].min() == 1000 + shift_frames
    with pytest.raises(TrajectoryFormatError, match=r"recording 3 not found"):
        read_ngsim(p, recording=3)


def test_unsorted_rows_load_as_sorted(tmp_path: Path) -> None:
    t = _i80()
    shuffled = t.sample(frac=1.0, random_state=np.random.default_rng(3).integers(1 << 31))
    p = write_ngsim_csv(shuffled, tmp_path / "shuffled.csv")
    pd.testing.assert_frame_equal(read_ngsim(p).table, t)


def test_cli_location_and_ambiguous_exit_2(tmp_path: Path, capsys) -> None:
    assert cli(["encounters", str(MIXED / "combined.csv"), "--out", str(tmp_path / "e.parquet")]) == 2
    assert "column Location" in capsys.readouterr().err
    assert cli(["encounters", str(MIXED / "combined.csv"), "--location", "i-80",
                "--out", str(tmp_path / "e.parquet")]) == 0
    m = pd.read_parquet(tmp_path / "e.merges.parquet")
    assert m[["B_id", "A_id", "C_id", "n_frames"]].values.tolist() == [[20, 10, 11, 71]]


def _varied_frames(n_enc: int = 10, n: int = 20, seed: int = 12) -> pd.DataFrame:
    """An encounter table with spread in every variable: ``n_enc`` encounters of ``n`` frames."""
    rng = np.random.default_rng(seed)
    m = n_enc * n
    return pd.DataFrame({
        "encounter_id": np.repeat(np.arange(1, n_enc + 1), n), "Frame_ID": np.tile(np.arange(1000, 1000 + n), n_enc),
        "d_AC": rng.uniform(10, 200, m), "d_AB": rng.uniform(-50, 50, m), "v_AC": rng.normal(0, 5, m),
        "v_AB": rng.normal(0, 5, m), "B_is_truck": rng.random(m) < 0.1, "acc_A": rng.normal(0, 2, m),
    })


def test_several_demo_tables_keep_encounters_apart(tmp_path: Path) -> None:
    frames = _varied_frames(1, 71)
    a, b = tmp_path / "a.parquet", tmp_path / "b.parquet"
    frames.to_parquet(a)
    frames.to_parquet(b)
    demos = load_merge_demos([a, b], None, decision_step_s=0.1)[0]
    assert len(demos.states) == 2 and all(len(s) == 71 for s in demos.states)
    assert [len(s) for s in load_merge_demos([a, b], None)[0].states] == [71 // 3] * 2  # 0.3 s decisions
    assert demos.names[0].startswith(str(a)) and demos.names[1].startswith(str(b))
    # one table concatenated from two runs reusing encounter id 1: still two trajectories
    bins = fit_quantile_bins(frames)
    cat = merge_mdp.discretize(pd.concat([frames, frames], ignore_index=True), bins, decision_step_s=0.1)
    assert [len(s) for s in cat.states] == [71, 71]


# --- kind 2: lane coding is the site's -------------------------------------------------------

def test_us101_scene_with_us101_coding() -> None:
    t = read_ngsim(US101_SCENE).table
    enc = extract(t, site=US101)
    assert _merges(t, site=US101) == [(20, 10, 11, 81)]
    mf = int(enc.merges["merge_frame"][0])
    at = t[t["Frame_ID"] == mf].set_index("Vehicle_ID")["Lane_ID"]
    assert at[10] == 5 and at[11] == 5 and at[20] == 5


def test_us101_scene_without_coding_is_an_error() -> None:
    t = read_ngsim(US101_SCENE).table
    with pytest.raises(TrajectoryFormatError) as ei:
        extract(t)
    msg = str(ei.value)
    assert "column Lane_ID" in msg and "8 (100 rows)" in msg and "i-80" in msg


def test_custom_site_from_toml_left_side_ramp(tmp_path: Path) -> None:
    # the I-80 scene recoded as a left-side on-ramp: ramp lane 0, merge into lane 1
    t = _i80()
    t["Lane_ID"] = t["Lane_ID"].map({6: 1, 7: 0})
    f = tmp_path / "left.toml"
    f.write_text('name = "left"\nmain_lanes = [1, 2, 3]\nmerge_lane = 1\nramp_lanes = [0]\n')
    site = load_site(f)
    assert site == SiteProfile("left", (1, 2, 3), 1, (0,))
    assert _merges(t, site=site) == [(20, 10, 11, 71)]
    with pytest.raises(TrajectoryFormatError, match=r"column Lane_ID: code\(s\) 0 "):
        extract(t)  # I-80 coding has no lane 0


def test_site_profiles_builtin_frozen_and_bad_files(tmp_path: Path) -> None:
    assert load_site("US-101") is US101 and load_site("i-80") is I80
    with pytest.raises(dataclasses.FrozenInstanceError):
        US101.merge_lane = 6  # type: ignore[misc]
    bad = tmp_path / "bad.toml"
    bad.write_text('main_lanes = [1, 2]\nramp_lanes = ["7"]\n')
    with pytest.raises(TrajectoryFormatError, match=r"bad\.toml: key ramp_lanes"):
        load_site(bad)
    bad.write_text('main_lanes = [1, 2]\nramp_lanes = [2]\n')
    with pytest.raises(TrajectoryFormatError, match=r"listed under two roles"):
        load_site(bad)
    with pytest.raises(TrajectoryFormatError, match=r"unknown; expected one of"):
        load_site("i-5")


def test_cli_site_option(tmp_path: Path) -> None:
    out = tmp_path / "u.parquet"
    assert cli(["encounters", str(US101_SCENE), "--out", str(out)]) == 2
    assert cli(["encounters", str(US101_SCENE), "--site", "us-101", "--out", str(out)]) == 0
    m = pd.read_parquet(tmp_path / "u.merges.parquet")
    assert m[["B_id", "A_id", "C_id"]].values.tolist() == [[20, 10, 11]]


# --- kind 3: the command line shows the loader's report and can smooth ------------------------

def test_cli_report_and_smoothing(tmp_path: Path, capsys) -> None:
    raw, smooth, clean = (tmp_path / f"{n}.parquet" for n in ("raw", "smooth", "clean"))
    assert cli(["encounters", str(NOISY / "noisy_with_dups.csv"), "--out", str(raw)]) == 0
    err = capsys.readouterr().err
    assert "duplicate rows dropped: 5" in err and "at the +-11.2 ft/s^2 cap" in err
    assert "warning: acc_A comes from the file's raw, unsmoothed speeds" in err and "--smooth" in err
    report = (tmp_path / "raw.load-report.txt").read_text()
    assert "duplicate rows dropped: 5" in report and "smoothing: none" in report
    assert cli(["encounters", str(NOISY / "noisy_with_dups.csv"), "--smooth", "--out", str(smooth)]) == 0
    err = capsys.readouterr().err
    assert "Savitzky-Golay" in err and "warning" not in err
    assert "Savitzky-Golay" in (tmp_path / "smooth.load-report.txt").read_text()
    assert cli(["encounters", str(NOISY / "clean.csv"), "--out", str(clean)]) == 0
    s_raw, s_smooth, s_clean = (pd.read_parquet(p)["acc_A"].std() for p in (raw, smooth, clean))
    # acc_A is the forward difference of v_Vel (the action taken in each frame), so raw speed noise
    # is amplified by 1/dt: the README's 10.3 / 0.6 ft/s^2 are the spreads of the file's v_Acc
    # column, which acc_A no longer reads. Measured here: raw 48.4, smoothed 2.5, clean 0.
    assert s_raw > 20.0 and s_smooth < 0.1 * s_raw and s_clean < 1.0
    hard = [float(np.mean(np.abs(pd.read_parquet(p)["acc_A"].to_numpy()) >= 4.8)) for p in (raw, smooth)]
    assert hard[0] > 0.8 and hard[1] < 0.1  # raw noise labels most steps hard brake / hard accel


def test_cli_parquet_rejects_ngsim_only_options(tmp_path: Path) -> None:
    p = tmp_path / "t.parquet"
    _i80().to_parquet(p)
    assert cli(["encounters", str(p), "--smooth", "--out", str(tmp_path / "e.parquet")]) == 2


# --- kind 4: invisible bytes ------------------------------------------------------------------

def test_excel_bom_crlf_loads_like_plain() -> None:
    a = read_ngsim(EXCEL / "excel_bom_crlf.csv").table
    b = read_ngsim(EXCEL / "crlf_only.csv").table
    pd.testing.assert_frame_equal(a, b)
    assert _merges(a) == [(20, 10, 11, 71)]


@pytest.mark.parametrize("prefix, sep", [("\u200b", ","), ("\u00a0", ","), ('"', '",')], ids=["zwsp", "nbsp", "quoted"])
def test_invisible_characters_in_header(tmp_path: Path, prefix: str, sep: str) -> None:
    text = (EXCEL / "crlf_only.csv").read_text(encoding="utf-8")
    header, body = text.split("\n", 1)
    names = header.rstrip("\r").split(",")
    if prefix == '"':
        header = ",".join(f'"{n}"' for n in names)
    else:
        header = ",".join(prefix + n for n in names)
    p = tmp_path / "odd.csv"
    p.write_bytes(("\ufeff" + header + "\r\n" + body).encode("utf-8"))
    pd.testing.assert_frame_equal(read_ngsim(p).table, read_ngsim(EXCEL / "crlf_only.csv").table)


def test_missing_column_error_names_only_missing(tmp_path: Path) -> None:
    text = (EXCEL / "excel_bom_crlf.csv").read_bytes().decode("utf-8-sig")
    rows = [r.split(",") for r in text.split("\r\n") if r]
    drop = rows[0].index("Lane_ID")
    p = tmp_path / "nolane.csv"
    p.write_bytes(b"\xef\xbb\xbf" + "\r\n".join(",".join(c for i, c in enumerate(r) if i != drop)
                                               for r in rows).encode())
    with pytest.raises(TrajectoryFormatError) as ei:
        read_ngsim(p)
    msg = str(ei.value)
    assert "missing column(s) ['Lane_ID']" in msg and "'Vehicle_ID']" not in msg.split("expected")[0]


def test_utf16_is_named(tmp_path: Path) -> None:
    p = tmp_path / "u16.csv"
    p.write_bytes((EXCEL / "crlf_only.csv").read_text(encoding="utf-8").encode("utf-16"))
    with pytest.raises(TrajectoryFormatError, match=r"u16\.csv: line 1: the file is UTF-16"):
        read_ngsim(p)


# --- kind 5: units of positions and speeds ----------------------------------------------------

@pytest.mark.parametrize(
    "change, column, words",
    [
        ({"Local_Y": 0.3048}, "Local_Y", "Local_Y in metres"),
        ({"v_Vel": 0.3048}, "v_Vel", "v_Vel in m/s"),
        ({"v_Vel": 1.09728}, "v_Vel", "km/h"),
        ({"v_Vel": 0.681818}, "v_Vel", "mph"),
        ({"Local_Y": 0.3048, "v_Vel": 0.3048 * 3.6}, "v_Vel", "km/h with Local_Y in metres"),
        ({"Local_Y": 0.3048, "v_Vel": 0.3048, "Local_X": 0.3048}, "Local_X", "metres"),
        ({"Local_Y": 6.0, "v_Vel": 6.0}, "v_Vel", "99th percentile"),
    ],
    ids=["y-metres", "v-mps", "v-kmh", "v-mph", "metres-kmh", "all-metric-positions", "fast"],
)
def test_units_of_positions_and_speeds(tmp_path: Path, change: dict, column: str, words: str) -> None:
    t = _i80()
    for c, k in change.items():  # feet and ft/s times k: the other unit
        t[c] = t[c] * k
    p = write_ngsim_csv(t, tmp_path / "units.csv")
    with pytest.raises(TrajectoryFormatError) as ei:
        read_ngsim(p)
    msg = str(ei.value)
    assert "units.csv" in msg and f"column {column}" in msg and words in msg, msg


def test_consistent_feet_pass() -> None:
    for f in (MIXED / "i80_only.csv", NOISY / "noisy_with_dups.csv", US101_SCENE):
        assert len(read_ngsim(f).table) > 0


# --- kind 6: SUMO's teleports are no merges ---------------------------------------------------

def test_position_jump_at_merge_is_left_out() -> None:
    t = _i80()
    b = (t["Vehicle_ID"] == 20) & (t["Frame_ID"] >= 1070)
    t.loc[b, "Local_Y"] += 41.0  # B put 41 ft ahead at its merge frame
    enc = extract(t)
    assert enc.merges.empty and enc.frames.empty
    assert enc.excluded[["B_id", "merge_frame"]].values.tolist() == [[20, 1070]]
    assert "jumps" in enc.excluded["reason"][0]


@pytest.mark.sumo
def test_teleported_ramp_cars_yield_no_encounter(tmp_path: Path) -> None:
    spec = load_scenario(TELEPORT)
    # the traffic as the scenario makes it (the default in-lane demonstrators hold A's lane while
    # observed, which changes the traffic: no teleport then)
    res = generate(spec, tmp_path / "run", progress=False, encounter_rule="take-over")
    sim = res.simulation
    assert sim.events.teleported_ids == {"R7.23", "R7.31"}  # README: seed 7, two teleports
    vids = sim.teleported_vehicle_ids
    assert len(vids) == 2
    assert not set(res.encounters.merges["B_id"]) & vids
    assert set(res.encounters.excluded["B_id"]) == vids
    # from the table alone (no SUMO list) the jump still keeps them out
    assert not set(extract(sim.table).merges["B_id"]) & vids
    report = tomllib.loads((tmp_path / "run" / RUN_REPORT).read_text())["run"]
    assert report["teleports"] == 2 and report["teleported_vehicles"] == ["R7.23", "R7.31"]
    assert report["collisions"] == 0 and len(report["merges_left_out"]) == 2
    assert report["insertion_backlog"] == 0 and report["demand_shortfall"] == 0.0


# --- kind 7: requested vs served demand -------------------------------------------------------

@pytest.mark.sumo
def test_unserved_demand_reported_and_warned() -> None:
    spec = with_overrides(load_scenario("synthetic"), demand_scale=3.0, duration_s=120.0)
    ev = run_scenario(spec).events
    assert ev.requested_veh_h == pytest.approx(3 * (sum(load_scenario("synthetic").demand.main_veh_h)
                                                    + load_scenario("synthetic").demand.ramp_veh_h))
    assert ev.backlog > 20 and ev.served_veh_h < 0.9 * ev.requested_veh_h
    assert ev.demand_shortfall > 0.05
    assert any("served demand" in w and "still waiting" in w for w in ev.warnings())
    assert ev.as_dict()["insertion_backlog"] == ev.backlog


# --- kind 8: an aborted run publishes nothing -------------------------------------------------

class _Boom:
    """A step hook that fails after a few frames."""

    def __init__(self, after: int) -> None:
        self.after, self.seen = after, 0

    def on_start(self, ctx) -> None:
        pass

    def on_step(self, ctx, frame) -> None:
        self.seen += 1
        if self.seen == self.after:
            raise RuntimeError("hook failed")

    def on_end(self, ctx) -> None:
        pass


@pytest.mark.sumo
def test_aborted_run_leaves_no_final_rrd(tmp_path: Path) -> None:
    path = tmp_path / "run.rrd"
    path.write_bytes(b"old run")  # a previous run's file must not survive as this run's
    spec = load_scenario("synthetic")
    with pytest.raises(RuntimeError, match="hook failed"):
        run_scenario(spec, duration_s=spec.simulation.warmup_s + 3.0, hooks=[RerunLogger(path), _Boom(10)])
    assert not path.exists()
    partial = list(tmp_path.glob(".run.rrd*.partial"))
    assert len(partial) == 1  # what was recorded stays under its temporary name
    partial[0].unlink()
    # the same run without the failure publishes its file
    run_scenario(spec, duration_s=spec.simulation.warmup_s + 3.0, hooks=[RerunLogger(path)])
    assert path.exists() and not list(tmp_path.glob("*.partial")) + list(tmp_path.glob(".*.partial"))


# --- kind 9: degenerate encounter columns are named, not binned silently ----------------------

def test_constant_column_refused_and_ties_warned() -> None:
    frames = _varied_frames()
    fit_quantile_bins(frames)  # varied data: no error
    const = frames.assign(v_AC=0.0)
    with pytest.raises(DemonstrationError, match=r"column 'v_AC': all 200 rows are 0"):
        fit_quantile_bins(const, where="const.parquet")
    tied = frames.copy()
    tied.loc[tied.index[: int(0.7 * len(tied))], "v_AB"] = 1.5  # 70 % ties: edges coincide
    with pytest.warns(DegenerateBinsWarning, match=r"column 'v_AB': .* coincide"):
        fit_quantile_bins(tied, where="tied.parquet")


def test_learn_cli_several_demos_and_raw_acceleration_warning(tmp_path: Path, capsys) -> None:
    a, b = tmp_path / "a.parquet", tmp_path / "b.parquet"
    _varied_frames(5, 30, 1).to_parquet(a)
    _varied_frames(5, 30, 2).to_parquet(b)
    out = tmp_path / "m.json"
    assert cli(["learn", "--method", "qavg", "--domain", "merge", "--demos", str(a), "--demos", str(b),
                "--out", str(out), "--no-progress"]) == 0
    info = json.loads(out.read_text())["info"]
    assert info["n_trajectories"] == 10 and str(a) in info["demos"] and str(b) in info["demos"]
    # raw NGSIM speeds differenced into action labels: a warning naming the column
    raw = tmp_path / "raw.parquet"
    cli(["encounters", str(NOISY / "noisy_with_dups.csv"), "--out", str(raw)])
    with pytest.warns(RawAccelerationWarning, match=r"raw\.parquet: column acc_A: .*\(0\.7 g\)"):
        load_merge_demos(raw, None)
