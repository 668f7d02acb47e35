"""Hostile input for the NGSIM reader (``sim.ngsim.io.read_ngsim`` / ``read_trajectories``):
random bytes, random text, and a valid file with cells, lines or the header damaged. Only a
schema-conforming table or a ``SimError`` (``TrajectoryFormatError``) naming the file is allowed."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sim.errors import SimError
from sim.ngsim.format import NGSIM_COLUMNS, NGSIM_HEADER
from sim.ngsim.io import read_ngsim, read_trajectories
from sim.runtime.schema import COLUMNS

pytestmark = pytest.mark.hostile

SETTINGS = settings(max_examples=120, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])


def _rows() -> list[list[str]]:
    rows = []
    for vid, lane in ((1, 6), (2, 7)):
        for k in range(5):
            f = 100 + k
            rows.append([str(vid), str(f), "5", str(1113433135300 + 100 * k), "17.500", f"{30.0 + 4 * k + vid:.3f}",
                         "6042842.100", "2133117.200", "14.5", "6.0", "2", "40.00", "0.50", str(lane),
                         "0", "0", "0.00", "0.00"])
    return rows


ROWS = _rows()
CSV = NGSIM_HEADER + "\n" + "\n".join(",".join(r) for r in ROWS) + "\n"
TXT = "\n".join("  ".join(r) for r in ROWS) + "\n"

tokens = st.one_of(
    st.sampled_from(["", " ", "nan", "NaN", "inf", "-inf", "1e308", "1e400", "-1", "0", "3.5", "abc", '"7"',
                     "1,2", "9" * 30, "0x10", "\x00", "-0", "+5"]),
    st.integers(-(2**70), 2**70).map(str),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.text(max_size=6),
)


def _check(path, **kw):
    try:
        load = read_ngsim(path, **kw)
    except SimError as e:
        assert str(path) in str(e) or path.name in str(e)
        return None
    t = load.table
    assert list(t.columns) == list(COLUMNS)
    assert {c: str(t[c].dtype) for c in t.columns} == COLUMNS
    assert all(np.isfinite(t[c]).all() for c in t.columns if t[c].dtype.kind == "f")
    assert load.report.rows_kept == len(t)
    return load


def test_the_base_files_load(tmp_path):
    for name, text in (("a.csv", CSV), ("a.txt", TXT)):
        (tmp_path / name).write_text(text)
        load = _check(tmp_path / name)
        assert load is not None and len(load.table) == len(ROWS)


@SETTINGS
@given(st.binary(max_size=400), st.sampled_from(["x.csv", "x.txt"]))
def test_random_bytes(tmp_path, data, name):
    p = tmp_path / name
    p.write_bytes(data)
    _check(p)


@SETTINGS
@given(st.text(max_size=300), st.booleans())
def test_random_text_after_a_header(tmp_path, text, header):
    p = tmp_path / "x.csv"
    p.write_text((NGSIM_HEADER + "\n" if header else "") + text, encoding="utf-8", errors="surrogatepass")
    _check(p)


@SETTINGS
@given(st.lists(st.tuples(st.integers(0, len(ROWS) - 1), st.integers(0, len(NGSIM_COLUMNS) - 1), tokens),
                min_size=1, max_size=4),
       st.sampled_from(["csv", "txt"]))
def test_damaged_cells(tmp_path, edits, layout):
    rows = [list(r) for r in ROWS]
    for i, j, tok in edits:
        rows[i][j] = tok
    if layout == "csv":
        text = NGSIM_HEADER + "\n" + "\n".join(",".join(r) for r in rows) + "\n"
    else:
        text = "\n".join("  ".join(r) for r in rows) + "\n"
    p = tmp_path / f"x.{layout}"
    p.write_text(text, encoding="utf-8", errors="surrogatepass")
    _check(p)


@SETTINGS
@given(st.lists(st.sampled_from(["drop", "dup", "swap", "blank", "cut"]), min_size=1, max_size=4), st.data())
def test_damaged_lines(tmp_path, ops, data):
    lines = CSV.splitlines()
    for op in ops:
        i = data.draw(st.integers(0, len(lines) - 1))
        if op == "drop" and len(lines) > 1:
            del lines[i]
        elif op == "dup":
            lines.insert(i, lines[i])
        elif op == "swap":
            j = data.draw(st.integers(0, len(lines) - 1))
            lines[i], lines[j] = lines[j], lines[i]
        elif op == "blank":
            lines.insert(i, "")
        elif op == "cut":
            lines[i] = lines[i][: data.draw(st.integers(0, len(lines[i])))]
    p = tmp_path / "x.csv"
    p.write_text("\n".join(lines) + "\n")
    _check(p)


@SETTINGS
@given(st.lists(st.sampled_from(list(NGSIM_COLUMNS) + ["v_length", "O_Zone", "x", "", "Vehicle_ID"]),
                min_size=1, max_size=22))
def test_random_headers(tmp_path, header):
    p = tmp_path / "x.csv"
    p.write_text(",".join(header) + "\n" + "\n".join(",".join(r) for r in ROWS) + "\n")
    _check(p)


@settings(SETTINGS, max_examples=30)
@given(st.binary(max_size=300))
def test_random_parquet(tmp_path, data):
    p = tmp_path / "x.parquet"
    p.write_bytes(data)
    try:
        t = read_trajectories(p)
    except SimError as e:
        assert "x.parquet" in str(e)
    else:
        assert list(t.columns) == list(COLUMNS)


def test_parquet_with_wrong_columns(tmp_path):
    p = tmp_path / "y.parquet"
    pd.DataFrame({"a": [1, 2]}).to_parquet(p)
    with pytest.raises(SimError, match="y.parquet"):
        read_trajectories(p)
    pd.DataFrame({c: ["x"] for c in COLUMNS}).to_parquet(p)
    with pytest.raises(SimError, match="y.parquet"):
        read_trajectories(p)


@pytest.mark.parametrize("token", ["inf", "-inf", "1e400"])
def test_infinite_values_are_rejected(tmp_path, token):
    rows = [list(r) for r in ROWS]
    rows[3][4] = token  # Local_X
    p = tmp_path / "inf.csv"
    p.write_text(NGSIM_HEADER + "\n" + "\n".join(",".join(r) for r in rows) + "\n")
    with pytest.raises(SimError, match="inf.csv"):
        read_ngsim(p)


@pytest.mark.parametrize("col,token", [(0, str(2**70)), (13, str(-(2**63) - 4096))])
def test_integers_beyond_int64_are_rejected(tmp_path, col, token):
    rows = [list(r) for r in ROWS]
    rows[0][col] = token  # Vehicle_ID / Lane_ID
    p = tmp_path / "big.csv"
    p.write_text(NGSIM_HEADER + "\n" + "\n".join(",".join(r) for r in rows) + "\n")
    with pytest.raises(SimError, match="big.csv"):
        read_ngsim(p)


def test_a_recording_past_year_9999_is_described_by_its_global_time():
    """Found by test_damaged_cells: a Global_Time of 253402300800000 ms (year 10000) broke the
    message naming the recordings of a file."""
    from sim.ngsim.recordings import Recording

    far = Recording(2, 0.0, 0.0, 100, 100, 253402300800000.0, 1)
    assert far.describe() == "#2: frames 100-100 from Global_Time 253402300800000 ms, 1 rows"
    assert "2005-04-13" in Recording(1, 0.0, 0.0, 1, 2, 1113433135300.0, 3).describe()
