"""Inputs that must be refused: negative NGSIM speeds, lane numbers below 1,
implausible road sizes, and a 2 GB sparse file refused with bounded memory."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest
from ngsim_testdata import synthetic_table

from scenarios.errors import SpecError
from scenarios.spec.parse import spec_from_toml
from sim.errors import SimError, TrajectoryFormatError
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
        import sys
        from sim.errors import SimError, TrajectoryFormatError
        from sim.ngsim.io import read_ngsim
        try:
            read_ngsim({str(path)!r})
        except TrajectoryFormatError as e:
            print(e)
        with open("/proc/self/status") as fh:  # VmHWM: this process image's peak RSS (kB)
            print(next(int(l.split()[1]) for l in fh if l.startswith("VmHWM:")) // 1024)
    """)
    t0 = time.time()
    r = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    elapsed = time.time() - t0
    assert r.returncode == 0, r.stderr
    message, peak_mb = r.stdout.strip().splitlines()
    assert "longer than 65536 characters without a line end" in message, message
    # VmHWM, not ru_maxrss: the latter carries the forking pytest's peak across exec (1.2 GB after
    # the whole suite). ~120-150 MB; bounded well below the file's 2 GB (4.4 GB before the bad-line finder; 5 GB
    # under heavy load while pyarrow still read ahead on its own threads)
    assert int(peak_mb) < 1024, f"peak memory {peak_mb} MB for a 2 GB file"
    print(f"2 GB sparse file refused in {elapsed:.1f} s, peak {peak_mb} MB")


@pytest.mark.parametrize("text,field", [
    ("[road]\nspeed_limit_mps = 65\n", r"road\.speed_limit_mps: 65 m/s is implausible \(234 km/h; 65 mph would be 29\.1 m/s\)"),
    ("[demand]\nramp_veh_h = 1e12\n", r"demand\.ramp_veh_h: 1e\+12 veh/h is implausible"),
    ("[demand]\nmain_veh_h = [1200, 1e12, 1000]\n", r"demand\.main_veh_h\[1\]: 1e\+12 veh/h is implausible"),
    ("[simulation]\nduration_s = 1e9\n", r"simulation\.duration_s: 1e\+09 s is implausible; expected 0 to 21600 s"),
])
def test_absurd_but_parseable_settings_are_refused_unless_meant(text, field):
    """Scenario bounds with the field named, and a way past them for those who mean it."""
    with pytest.raises(SpecError, match=r"^x\.toml: " + field) as e:
        spec_from_toml(f'name = "x"\n{text}', source="x.toml")
    assert "\n" not in str(e.value) and "allow_implausible = true" in str(e.value)
    meant = spec_from_toml(f'name = "x"\nallow_implausible = true\n{text}', source="x.toml")
    assert meant.allow_implausible and spec_from_toml(meant.to_toml()) == meant  # kept in the written spec
    assert spec_from_toml(meant.to_toml()).allow_implausible
    # the same through the loader's switch (--allow-implausible), and a plausible spec writes no key
    assert spec_from_toml(f'name = "x"\n{text}', allow_implausible=True).allow_implausible
    assert "allow_implausible" not in spec_from_toml('name = "x"\n').to_toml()
    with pytest.raises(SpecError, match="allow_implausible: must be true or false"):
        spec_from_toml('name = "x"\nallow_implausible = "yes"\n')


def test_overrides_are_bounded_and_named_and_the_switch_lets_them_through():
    from scenarios.loader import load_scenario
    from scenarios.spec.parse import with_overrides

    i80 = load_scenario("i80")
    with pytest.raises(SpecError, match=r"simulation\.duration_s: overridden \(e\.g\. --duration\) with 1e\+09 s "
                                        r"is implausible"):
        with_overrides(i80, duration_s=1e9)
    with pytest.raises(SpecError, match=r"demand\.main_veh_h\[0\]: .* is implausible.*\(after demand_scale 1e\+09\)$"):
        with_overrides(i80, demand_scale=1e9)
    assert with_overrides(i80, duration_s=1e9, allow_implausible=True).simulation.duration_s == 1e9
    assert with_overrides(load_scenario("i80", allow_implausible=True), duration_s=1e9).simulation.duration_s == 1e9
    # oversaturating on purpose stays possible: 3x the synthetic demand, 3900 veh/h in a lane
    assert with_overrides(load_scenario("synthetic"), demand_scale=3.0).demand.main_veh_h[0] == 3900.0


def test_cli_refuses_an_implausible_duration_in_one_line_and_allow_implausible_passes_it(tmp_path, capsys,
                                                                                          monkeypatch):
    from analysis.cli.main import main
    from analysis.experiments import dagger

    # a subprocess with a timeout: before the bound, this started a run of 1e9 simulated seconds
    r = subprocess.run([sys.executable, "-m", "analysis", "generate", "--duration", "1e9", "--out", str(tmp_path / "g")],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2, r.stderr
    err = r.stderr
    assert err.count("\n") == 1 and "simulation.duration_s: overridden (e.g. --duration) with 1e+09 s is implausible" in err
    assert "--allow-implausible" in err and not (tmp_path / "g").exists()
    # with the switch the duration reaches the runs (stopped by the test before SUMO starts)
    seen = {}

    def stop(model, spec, seeds, config, executor, duration_s):
        seen.update(duration_s=duration_s, allow=spec.allow_implausible)
        raise SimError("stopped by the test")

    monkeypatch.setattr(dagger, "label_runs", stop)
    import pandas as pd

    rng = np.random.default_rng(0)
    n = 120
    pd.DataFrame({"encounter_id": np.repeat([1, 2], n // 2), "d_AC": rng.uniform(40, 300, n),
                  "v_AC": rng.normal(0, 5, n), "d_AB": rng.uniform(-50, 100, n), "v_AB": rng.normal(0, 5, n),
                  "B_is_truck": False, "acc_A": 9.0, "v_A": rng.uniform(20, 80, n)}).to_parquet(tmp_path / "t.parquet")
    args = ["dagger", "--train", str(tmp_path / "t.parquet"), "--rounds", "1", "--episodes-per-round", "1",
            "--duration", "1e9", "--no-progress", "--out", str(tmp_path / "d")]
    assert main(args) == 2
    assert "simulation.duration_s: overridden (e.g. --duration) with 1e+09 s is implausible" in capsys.readouterr().err
    assert main([*args, "--allow-implausible"]) == 2
    assert "stopped by the test" in capsys.readouterr().err
    assert seen == {"duration_s": 1e9, "allow": True}


@pytest.mark.parametrize("duration", [-5.0, -1e9])
def test_a_negative_duration_override_is_refused_as_impossible_not_as_implausible(duration):
    """A negative --duration cannot be run at all: the message must not offer --allow-implausible
    (which then only led to 'must be positive')."""
    from scenarios.loader import load_scenario
    from scenarios.spec.parse import with_overrides

    for allow in (False, True):
        with pytest.raises(SpecError, match=r"simulation\.duration_s: must be positive") as e:
            with_overrides(load_scenario("synthetic"), duration_s=duration, allow_implausible=allow)
        assert "allow" not in str(e.value)
