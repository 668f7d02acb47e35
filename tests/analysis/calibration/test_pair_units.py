"""Car-following pairs in other units than the declared feet (metres, km/h, mixed) are refused in
one line naming the file and the likely unit, by the reader and so by ``calibrate fit`` and
``learn-driver``; the real I-80 pairs pass."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from analysis.calibration import load_pairs, read_pair
from scenarios.errors import SpecError
from tests.shared_data import PAIRS_DIR

M = 0.3048
LENGTHS = ("x_follower", "x_leader", "leader_length", "spacing")
SPEEDS = ("v_follower", "v_leader", "dv")
ACCS = ("a_follower", "a_leader")


def _real_files(n: int) -> list[Path]:
    return sorted((PAIRS_DIR / "train").glob("*.csv"))[:n]


def _converted(src: Path, dst: Path, *, lengths: float = 1.0, speeds: float = 1.0, accs: float = 1.0,
               leader_length: float | None = None) -> Path:
    df = pd.read_csv(src)
    for cols, k in ((LENGTHS, lengths), (SPEEDS, speeds), (ACCS, accs)):
        for c in cols:
            df[c] = df[c] * k
    if leader_length is not None:
        df["leader_length"] = leader_length
        df["spacing"] = df["x_leader"] - df["x_follower"] - leader_length
    df.to_csv(dst, index=False)
    return dst


def test_real_pairs_pass() -> None:
    assert len(load_pairs(PAIRS_DIR)) >= 30


@pytest.mark.parametrize("kw, words", [
    (dict(lengths=M, speeds=M, accs=M), "leader_length: .* looks like metres"),
    (dict(lengths=M), "column x_follower: advances 0.305 times .* positions in metres with speeds in ft/s"),
    (dict(speeds=1.09728), "speeds in km/h with positions in feet"),
    (dict(speeds=M), "speeds in m/s with positions in feet"),
    (dict(accs=20.0), "column a_follower: 99th percentile"),
])
def test_a_file_in_other_units_is_named_with_its_likely_unit(tmp_path, kw, words) -> None:
    f = _converted(_real_files(1)[0], tmp_path / "pair.csv", **kw)
    with pytest.raises(SpecError, match=words) as e:
        read_pair(f)
    assert str(f) in str(e.value) and "convert the file" in str(e.value) and "\n" not in str(e.value)


def test_a_metre_folder_of_truck_leaders_is_refused_as_a_whole(tmp_path) -> None:
    # 12 (m) is a plausible truck in feet, file by file; a folder whose median leader is that short is metres
    roomy = [f for f in _real_files(36) if pd.read_csv(f)["spacing"].min() * M > 6.0][:5]
    assert len(roomy) >= 3
    for src in roomy:  # 8 (m): a van or a short truck, plausible in feet file by file
        _converted(src, tmp_path / src.name, lengths=M, speeds=M, accs=M, leader_length=8.0)
    with pytest.raises(SpecError, match=r"median leader is 8.0 long .* look like metres"):
        load_pairs(tmp_path)


@pytest.mark.parametrize("command", [["calibrate", "fit", "--out", "p.toml", "--pairs"],
                                     ["learn-driver", "--out", "d.json", "--demos"]])
def test_cli_refuses_pairs_in_metres(tmp_path, command) -> None:
    folder = tmp_path / "pairs"
    folder.mkdir()
    for src in _real_files(4):
        _converted(src, folder / src.name, lengths=M, speeds=M, accs=M)
    r = subprocess.run([sys.executable, "-m", "analysis", *command, str(folder)], capture_output=True, text=True,
                       cwd=tmp_path, timeout=300)
    assert r.returncode == 2, r.stderr
    assert r.stderr.count("\n") == 1 and "looks like metres" in r.stderr and "convert the file" in r.stderr
    assert not (tmp_path / "p.toml").exists() and not (tmp_path / "d.json").exists()
    shutil.rmtree(folder)
