"""NGSIM reader / writer: known values, every bad-input class, defects reported, round trip."""

from __future__ import annotations

import re
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from merge_irl.units import M_PER_FT
from sim.errors import TrajectoryFormatError
from sim.ngsim.format import NGSIM_HEADER
from sim.ngsim.io import read_ngsim, read_trajectories, write_ngsim_csv
from sim.ngsim.smooth import SmoothingConfig
from sim.ngsim.write import quantize_ngsim
from sim.runtime.schema import COLUMNS, sort_table
from tests.ngsim_testdata import synthetic_table

# Header as in the combined NGSIM release: lower-case v_length and extra columns in between.
SNIPPET = textwrap.dedent("""\
    Vehicle_ID,Frame_ID,Total_Frames,Global_Time,Local_X,Local_Y,Global_X,Global_Y,v_length,v_Width,v_Class,v_Vel,v_Acc,Lane_ID,O_Zone,D_Zone,Int_ID,Section_ID,Direction,Movement,Preceding,Following,Space_Headway,Time_Headway,Location
    2,13,437,1118846981300,16.467,35.381,6451137.641,1873344.962,14.5,4.9,2,40.00,0.00,2,,,,,,,0,0,0.00,0.00,i-80
    2,14,437,1118846981400,16.447,39.381,6451137.616,1873348.941,14.5,4.9,2,40.00,0.00,2,,,,,,,0,0,0.00,0.00,i-80
    3,13,500,1118846981300,5.5,100.25,6451140.1,1873409.0,16.0,6.5,3,20.5,-1.25,1,,,,,,,0,4,50.10,2.44,i-80
    """)

TXT = (
    "    2    13   437 1118846981300   16.467   35.381  6451137.641  1873344.962  14.5   4.9  2  40.00   0.00  2     0     0     0.00     0.00\n"
    "    2    14   437 1118846981400   16.447   39.381  6451137.616  1873348.941  14.5   4.9  2  40.00   0.00  2     0     0     0.00     0.00\n"
    "    3    13   500 1118846981300    5.500  100.250  6451140.100  1873409.000  16.0   6.5  3  20.50  -1.25  1     0     4    50.10     2.44\n"
)


def _expected() -> pd.DataFrame:
    rows = [
        [2, 13, 437, 1118846981300, 16.467, 35.381, 6451137.641, 1873344.962, 14.5, 4.9, 2, 40.0, 0.0, 2, 0, 0, 0.0, 0.0],
        [2, 14, 437, 1118846981400, 16.447, 39.381, 6451137.616, 1873348.941, 14.5, 4.9, 2, 40.0, 0.0, 2, 0, 0, 0.0, 0.0],
        [3, 13, 500, 1118846981300, 5.5, 100.25, 6451140.1, 1873409.0, 16.0, 6.5, 3, 20.5, -1.25, 1, 0, 4, 50.1, 2.44],
    ]
    return pd.DataFrame(rows, columns=list(COLUMNS)).astype(COLUMNS)


def test_csv_snippet_known_values(tmp_path: Path) -> None:
    p = tmp_path / "trajectories-0400-0415.csv"
    p.write_text(SNIPPET)
    load = read_ngsim(p)
    pd.testing.assert_frame_equal(load.table, _expected())
    assert dict(load.table.dtypes.astype(str)) == COLUMNS
    r = load.report
    assert (r.layout, r.rows_read, r.rows_kept, r.vehicles) == ("csv", 3, 3, 2)
    assert set(r.extra_columns_dropped) == {"O_Zone", "D_Zone", "Int_ID", "Section_ID", "Direction", "Movement", "Location"}
    assert r.duplicate_rows_dropped == 0 and r.vehicles_with_gaps == ()


def test_txt_snippet_known_values(tmp_path: Path) -> None:
    p = tmp_path / "trajectories-0400-0415.txt"
    p.write_text(TXT)
    load = read_ngsim(p)
    assert load.report.layout == "txt"
    pd.testing.assert_frame_equal(load.table, _expected())
    pd.testing.assert_frame_equal(read_trajectories(p), _expected())


def _csv(tmp_path: Path, rows: list[str], name: str = "bad.csv") -> Path:
    p = tmp_path / name
    p.write_text(NGSIM_HEADER + "\n" + "\n".join(rows) + "\n")
    return p


GOOD = "1,{f},3,1113433136{f:03d},10.0,{y},1.0,2.0,15.0,6.0,2,30.0,0.5,{lane},0,0,0.0,0.0"


def _rows(n: int = 3, vid: int = 1, lane: int = 2) -> list[str]:
    return [GOOD.replace("1,{f}", f"{vid},{{f}}", 1).format(f=f, y=10.0 + f, lane=lane) for f in range(1, n + 1)]


@pytest.mark.parametrize(
    "mutate, line, column, words",
    [
        (lambda r: r.__setitem__(1, r[1].replace(",30.0,", ",fast,")), 3, "v_Vel", "not a number"),
        (lambda r: r.__setitem__(2, r[2].replace(",30.0,", ",,")), 4, "v_Vel", "missing value"),
        (lambda r: r.__setitem__(1, r[1].replace(",15.0,", ",-15.0,")), 3, "v_Length", "negative"),
        (lambda r: r.__setitem__(0, r[0].replace(",2,30.0", ",2.5,30.0")), 2, "v_Class", "not an integer"),
        (lambda r: r.insert(3, r[0].replace(",30.0,", ",31.0,")), 5, "v_Vel", "appears again"),
        (lambda r: r.append(r[2].replace(",30.0,", ",31.0,")), 5, "v_Vel", "appears again"),
    ],
    ids=["non-numeric", "missing-value", "negative-length", "non-integer-class", "late-conflicting-frame",
         "duplicate-frame"],
)
def test_bad_input_named_error(tmp_path: Path, mutate, line: int, column: str, words: str) -> None:
    rows = _rows(3)
    mutate(rows)
    p = _csv(tmp_path, rows)
    with pytest.raises(TrajectoryFormatError) as ei:
        read_ngsim(p, chunksize=2)
    msg = str(ei.value)
    assert str(p) in msg and f"line {line}" in msg and column in msg and words in msg, msg


def test_missing_column_named(tmp_path: Path) -> None:
    p = tmp_path / "nolane.csv"
    header = NGSIM_HEADER.replace(",Lane_ID", "")
    p.write_text(header + "\n" + "1,1,3,1,1,1,1,1,15,6,2,30,0,0,0,0,0\n")
    with pytest.raises(TrajectoryFormatError, match=r"nolane\.csv: line 1 .*Lane_ID"):
        read_ngsim(p)


def test_wrong_field_count_named(tmp_path: Path) -> None:
    rows = _rows(3)
    rows[1] = rows[1] + ",99"
    p = _csv(tmp_path, rows)
    with pytest.raises(TrajectoryFormatError, match=r"line 3: 19 fields; expected 18"):
        read_ngsim(p)


def test_metric_units_rejected(tmp_path: Path) -> None:
    t = synthetic_table(5, 20)
    t["v_Length"] = t["v_Length"] * M_PER_FT
    t["v_Width"] = t["v_Width"] * M_PER_FT
    p = write_ngsim_csv(t, tmp_path / "metric.csv")
    with pytest.raises(TrajectoryFormatError, match=r"metric\.csv: column v_Length.*metres"):
        read_ngsim(p)


def test_defects_reported_duplicates_dropped_gaps_kept(tmp_path: Path) -> None:
    rows = _rows(6, vid=1) + _rows(4, vid=2)
    rows.insert(3, rows[2])  # exact duplicate of vehicle 1 frame 3
    del rows[6]  # vehicle 1 ends at frame 5 (no gap)
    rows = [r for r in rows if not r.startswith("2,2,")]  # vehicle 2 loses frame 2: a gap
    p = _csv(tmp_path, rows)
    load = read_ngsim(p, chunksize=3)
    r = load.report
    assert r.duplicate_rows_dropped == 1
    assert r.vehicles_with_gaps == (2,) and r.gap_events == 1 and r.missing_frames == 1 and r.max_gap_frames == 1
    assert not load.table.duplicated(["Vehicle_ID", "Frame_ID"]).any()
    assert len(load.table) == len(rows) - 1
    assert "duplicate rows dropped: 1" in r.summary() and "frame gaps: 1" in r.summary()


def test_filters_on_the_way_in(tmp_path: Path) -> None:
    t = synthetic_table(30, 40, seed=3)
    p = write_ngsim_csv(t, tmp_path / "t.csv")
    full = read_ngsim(p, chunksize=100).table
    lanes = read_ngsim(p, lanes=(6, 7), chunksize=100).table
    pd.testing.assert_frame_equal(lanes, full[full.Lane_ID.isin([6, 7])].reset_index(drop=True))
    fr = read_ngsim(p, frames=(50, 120), chunksize=100).table
    pd.testing.assert_frame_equal(fr, full[full.Frame_ID.between(50, 120)].reset_index(drop=True))
    veh = read_ngsim(p, vehicles=[3, 5], chunksize=100)
    assert set(veh.table.Vehicle_ID) == {3, 5}
    assert veh.report.rows_read == len(full) and veh.report.rows_kept == len(veh.table)


def test_round_trip_ngsim_and_exact_precision(tmp_path: Path) -> None:
    t = synthetic_table(25, 50, seed=1).sample(frac=1.0, random_state=0)  # any row order
    p = write_ngsim_csv(t, tmp_path / "rt.csv")
    text = p.read_text().splitlines()
    assert text[0] == NGSIM_HEADER
    first = text[1].split(",")
    assert len(first) == 18 and re.fullmatch(r"-?\d+\.\d{3}", first[4]) and re.fullmatch(r"\d+\.\d", first[8])
    back = read_ngsim(p, chunksize=97).table
    pd.testing.assert_frame_equal(back, sort_table(quantize_ngsim(t)))
    assert np.abs(back["Local_Y"].to_numpy() - sort_table(t)["Local_Y"].to_numpy()).max() <= 0.0005 + 1e-9
    p2 = write_ngsim_csv(t, tmp_path / "rt_exact.csv", precision="exact")
    pd.testing.assert_frame_equal(read_ngsim(p2, chunksize=97).table, sort_table(t))


def test_writer_is_atomic_and_rejects_bad_tables(tmp_path: Path) -> None:
    t = synthetic_table(2, 5)
    with pytest.raises(TrajectoryFormatError, match="missing columns"):
        write_ngsim_csv(t.drop(columns=["Lane_ID"]), tmp_path / "x.csv")
    bad = t.copy()
    bad.loc[3, "v_Vel"] = np.nan
    with pytest.raises(TrajectoryFormatError, match="v_Vel"):
        write_ngsim_csv(bad, tmp_path / "x.csv")
    assert list(tmp_path.iterdir()) == []


def test_smoothing_reduces_acceleration_noise(tmp_path: Path) -> None:
    n = 200
    fr = np.arange(1, n + 1)
    tt = fr * 0.1
    y_true = 20 * tt + 0.5 * 2.0 * tt**2  # constant 2 ft/s^2
    rng = np.random.default_rng(0)
    t = synthetic_table(1, n)
    t["Frame_ID"] = fr
    t["Local_Y"] = y_true + rng.normal(0, 0.05, n)
    t["v_Vel"] = 20 + 2.0 * tt  # consistent with Local_Y (the reader checks units kinematically)
    t["v_Acc"] = 2.0 + rng.normal(0, 4.0, n)
    p = write_ngsim_csv(t, tmp_path / "noisy.csv", precision="exact")
    load = read_ngsim(p, smooth=SmoothingConfig(window_frames=31, polyorder=2))
    a = load.table["v_Acc"].to_numpy()
    v = load.table["v_Vel"].to_numpy()
    assert np.abs(np.median(a) - 2.0) < 0.3
    assert np.abs(v[50:150] - (20 + 2.0 * tt[50:150])).max() < 0.5
    r = load.report
    assert r.smoothing.startswith("Savitzky-Golay") and r.jerk_rms_smoothed_ft_s3 < 0.1 * r.jerk_rms_ft_s3


def test_chunking_is_used_and_memory_bounded(tmp_path: Path) -> None:
    t = synthetic_table(400, 1000, seed=2)  # 400k rows, ~50 MB of text
    p = write_ngsim_csv(t, tmp_path / "big.csv")
    load = read_ngsim(p, chunksize=5_000, lanes=(7,))
    assert load.report.chunks >= 40
    assert load.report.rows_read == len(t)
    # peak RSS (VmHWM; ru_maxrss would include the forking pytest's) of a child that reads, minus that of a child that only imports the same modules
    code = textwrap.dedent(f"""
        import sys
        import numpy, pandas, pyarrow, pyarrow.csv
        from sim.ngsim.io import read_ngsim
        if sys.argv[1] == "ngsim":
            read_ngsim({str(p)!r}, chunksize=20_000, lanes=(7,))
        elif sys.argv[1] == "pandas":
            pandas.read_csv({str(p)!r})
        with open("/proc/self/status") as fh:  # VmHWM: peak RSS of this process image (kB)
            print(next(int(l.split()[1]) for l in fh if l.startswith("VmHWM:")))
    """)
    peak = {}
    for mode in ("none", "ngsim", "pandas"):
        out = subprocess.run([sys.executable, "-c", code, mode], capture_output=True, text=True, check=True)
        peak[mode] = int(out.stdout.split()[-1])
    growth = {m: peak[m] - peak["none"] for m in ("ngsim", "pandas")}
    assert growth["pandas"] > 30_000, (growth, peak)  # kB: pandas holds the ~58 MB table
    assert growth["ngsim"] < 0.5 * growth["pandas"], growth


def test_simulated_run_round_trip(tmp_path: Path) -> None:
    """A short real SUMO run of the synthetic preset, written as NGSIM CSV, loads back equal."""
    parquet = tmp_path / "run.parquet"
    code = textwrap.dedent(f"""
        from scenarios.loader import load_preset
        from sim.runtime.run import run_scenario
        res = run_scenario(load_preset("synthetic"), seed=3, duration_s=80.0)  # 60 s warm-up + 20 s recorded
        res.table.to_parquet({str(parquet)!r})
    """)
    subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True, timeout=300)
    table = pd.read_parquet(parquet)
    assert len(table) > 100
    csv = write_ngsim_csv(table, tmp_path / "run.csv")
    back = read_ngsim(csv)
    pd.testing.assert_frame_equal(back.table, sort_table(quantize_ngsim(table)))
    exact = write_ngsim_csv(table, tmp_path / "run_exact.csv", precision="exact")
    pd.testing.assert_frame_equal(read_trajectories(exact), sort_table(table))


def test_txt_bad_value_named(tmp_path: Path) -> None:
    p = tmp_path / "old.txt"
    p.write_text(TXT.replace("  40.00   0.00  2", "  4O.00   0.00  2", 1))  # letter O
    with pytest.raises(TrajectoryFormatError, match=r"old\.txt: line 1, column v_Vel: value '4O\.00' is not a number"):
        read_ngsim(p)


def test_read_trajectories_by_suffix(tmp_path: Path) -> None:
    t = synthetic_table(3, 10)
    t.to_parquet(tmp_path / "t.parquet")
    pd.testing.assert_frame_equal(read_trajectories(tmp_path / "t.parquet"), t)
    (tmp_path / "t.json").write_text("{}")
    with pytest.raises(TrajectoryFormatError, match="expected .parquet, .csv or .txt"):
        read_trajectories(tmp_path / "t.json")
    with pytest.raises(FileNotFoundError):
        read_ngsim(tmp_path / "missing.csv")


def test_header_aliases_and_crlf(tmp_path: Path) -> None:
    p = tmp_path / "alias.csv"
    text = SNIPPET.replace("Space_Headway,Time_Headway", "Space_Hdwy,Time_Hdwy").replace("\n", "\r\n")
    p.write_bytes(text.encode())
    pd.testing.assert_frame_equal(read_ngsim(p).table, _expected())
