"""Tiny data says only what it has: a preset of 32 driver types resampled from one fitted pair says
it holds one distinct driver, and learn-driver on one pair names --no-selection and how many
followers the selection needs, not an internal function."""

from __future__ import annotations

import shutil
import subprocess
import sys

from tests.shared_data import PAIRS_DIR


def _cli(*args: str, cwd) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "analysis", *args], capture_output=True, text=True, cwd=cwd,
                          timeout=300)


def _one_pair(tmp_path):
    folder = tmp_path / "one"
    folder.mkdir()
    shutil.copy(sorted((PAIRS_DIR / "train").glob("*.csv"))[0], folder)
    return folder


def test_preset_of_32_types_from_one_fit_says_one_distinct_driver(tmp_path) -> None:
    one = _one_pair(tmp_path)
    r = _cli("calibrate", "fit", "--pairs", str(one), "--out", "p.toml", "--no-progress", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    r = _cli("calibrate", "preset", "--params", "p.toml", "--out", "one.toml", "--drivers", "32", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "32 calibrated car driver type" not in r.stderr
    assert "32 car driver types drawn with replacement from 1 per-pair fit(s): 1 distinct driver(s), 31 repeat(s)" \
        in r.stderr
    assert "warning: --drivers 32 asks for more driver types than p.toml has per-pair fits (1)" in r.stderr
    assert "at most 1 distinct" in (tmp_path / "one.toml").read_text().splitlines()[1]
    # as many types as fits: no warning, the usual line
    r = _cli("calibrate", "preset", "--params", "p.toml", "--out", "all.toml", cwd=tmp_path)
    assert r.returncode == 0 and "1 calibrated car driver type(s)" in r.stderr and "warning" not in r.stderr


def test_learn_driver_on_one_pair_says_what_it_needs(tmp_path) -> None:
    one = _one_pair(tmp_path)
    # the likelihood fit selects its settings on a split of the followers
    r = _cli("learn-driver", "--demos", str(one), "--fit", "likelihood", "--out", "d.json", "--no-progress",
             cwd=tmp_path)
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert "split_groups" not in r.stderr
    assert "at least 2 followers" in r.stderr and "got 1" in r.stderr and "--no-selection" in r.stderr
    assert not (tmp_path / "d.json").exists()
    r = _cli("learn-driver", "--demos", str(one), "--fit", "likelihood", "--out", "d.json", "--no-progress",
             "--no-selection", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "d.json").is_file()
    # the replay fit (the default for pairs) holds followers out only when asked: one cannot be split
    r = _cli("learn-driver", "--demos", str(one), "--holdout", "0.3", "--out", "r.json", "--no-progress", cwd=tmp_path)
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert "1 follower(s) cannot be split" in r.stderr and not (tmp_path / "r.json").exists()
