"""Inputs that must be refused (issue 13, item 6): negative NGSIM speeds, lane numbers below 1,
implausible road sizes, and a 2 GB sparse file refused with bounded memory."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
import time

import pytest
from ngsim_testdata import synthetic_table

from scenarios.errors import SpecError
from scenarios.spec.parse import spec_from_toml
from sim.errors import TrajectoryFormatError
from sim.ngsim.io import read_ngsim, write_ngsim_csv


@pytest.fixture
def table():
    return synthetic_table(n_vehicles=5, n_frames=30, seed=3)


def test_negative_speed_is_refused_naming_line_and_column(tmp_path, table):
    table.loc[17, "v_Vel"] = -157.0
    path = write_ngsim_csv(table, tmp_path / "neg.csv")
    with pytest.raises(TrajectoryFormatError, match=r"line 19, column v_Vel: v_Vel -157; expected a speed >= 0"):
        read_ngsim(path)


@pytest.mark.parametrize("lane", [0, -1])
def test_lane_number_below_one_is_refused(tmp_path, table, lane):
    table.loc[40, "Lane_ID"] = lane
    path = write_ngsim_csv(table, tmp_path / "lane.csv")
    with pytest.raises(TrajectoryFormatError, match=rf"line 42, column Lane_ID: Lane_ID {lane}; expected a lane"):
        read_ngsim(path)


@pytest.mark.parametrize("key,value,field", [
    ("lane_width_m", 0.1, "road.lane_width_m: 0.1 m is implausible; expected 2.5 to 5 m"),
    ("main_length_m", 1.0, "road.main_length_m: 1 m is implausible"),
    ("ramp_length_m", 0.3, "road.ramp_length_m: 0.3 m is implausible"),
    ("speed_limit_mps", 300.0, "road.speed_limit_mps: 300 m/s is implausible"),
])
def test_implausible_road_sizes_are_refused(key, value, field):
    with pytest.raises(SpecError, match=r"^x\.toml: " + field.replace(".", r"\.")):
        spec_from_toml(f'name = "x"\n[road]\n{key} = {value}\n', source="x.toml")


def test_one_metre_road_with_a_short_ramp_is_refused():
    text = 'name = "tiny"\n[road]\nmain_length_m = 1.0\nmerge_position_m = 0.4\naux_length_m = 0.5\nramp_length_m = 0.3\n'
    with pytest.raises(SpecError, match="is implausible"):
        spec_from_toml(text, source="tiny.toml")


def test_huge_sparse_file_is_refused_with_bounded_memory(tmp_path, table):
    """A valid start followed by 2 GB of NUL bytes (a sparse file): refused in one line, with
    memory well under the file's size (the bad-line finder never reads the whole 'line')."""
    path = write_ngsim_csv(table, tmp_path / "sparse.csv")
    os.truncate(path, 2 * 1024**3)
    script = textwrap.dedent(f"""
        import resource, sys
        from sim.errors import TrajectoryFormatError
        from sim.ngsim.io import read_ngsim
        try:
            read_ngsim({str(path)!r})
        except TrajectoryFormatError as e:
            print(e)
        print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss // 1024)
    """)
    t0 = time.time()
    r = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    elapsed = time.time() - t0
    assert r.returncode == 0, r.stderr
    message, peak_mb = r.stdout.strip().splitlines()
    assert "longer than 65536 characters without a line end" in message, message
    # ~120-150 MB; bounded well below the file's 2 GB (4.4 GB before the bad-line finder; 5 GB
    # under heavy load while pyarrow still read ahead on its own threads)
    assert int(peak_mb) < 1024, f"peak memory {peak_mb} MB for a 2 GB file"
    print(f"2 GB sparse file refused in {elapsed:.1f} s, peak {peak_mb} MB")
