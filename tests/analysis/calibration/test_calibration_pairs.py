"""Pair files: reading, the errors a bad file gives, and byte-identical copies named in a warning."""

from __future__ import annotations

import shutil
import warnings

import numpy as np
import pandas as pd
import pytest

from analysis.calibration import load_pairs, read_pair, split_by_follower, split_in_time
from analysis.calibration.pairs import DuplicatePairWarning, duplicate_files, pair_files
from scenarios.errors import SpecError


def write_pair(path, n=50, v=30.0, gap=60.0, seed=0):
    """A leader at constant speed ``v`` (ft/s), the follower ``gap`` ft behind with a little noise."""
    rng = np.random.default_rng(seed)
    t = np.round(np.arange(n) * 0.1, 1)
    x_l = 500.0 + v * t
    x_f = x_l - 15.0 - gap + rng.normal(0, 0.5, n)
    pd.DataFrame({"t": t, "x_follower": x_f, "v_follower": np.full(n, v), "a_follower": 0.0, "x_leader": x_l,
                  "v_leader": np.full(n, v), "a_leader": 0.0, "leader_length": 15.0,
                  "spacing": x_l - x_f - 15.0, "dv": 0.0}).to_csv(path, index=False)
    return path


def test_pair_is_read_in_metres(tmp_path):
    p = read_pair(write_pair(tmp_path / "ngsim_p1_runp1_f10_l9_00001.csv"))
    assert p.group == "p1/10"
    np.testing.assert_allclose(p.v_leader, 30.0 * 0.3048)
    assert p.leader_length == pytest.approx(15.0 * 0.3048)


def test_bad_pair_files_name_file_and_line(tmp_path):
    f = write_pair(tmp_path / "a.csv")
    df = pd.read_csv(f)
    df.loc[7, "t"] = 0.75
    df.to_csv(f, index=False)
    with pytest.raises(SpecError, match=r"a\.csv: column t lines 8-9: step 0\.15 s"):  # row 7 is line 9
        read_pair(f)
    df["t"] = np.round(np.arange(len(df)) * 0.01, 2)  # 0.01 s steps throughout: the first step is named
    df.to_csv(f, index=False)
    with pytest.raises(SpecError, match=r"a\.csv: column t lines 2-3: step 0\.01 s"):
        read_pair(f)
    with pytest.raises(SpecError, match=r"a\.csv: a file; expected a folder of pair CSVs"):
        load_pairs(f)
    g = write_pair(tmp_path / "b.csv")
    pd.read_csv(g).drop(columns="v_leader").to_csv(g, index=False)
    with pytest.raises(SpecError, match=r"b\.csv: missing column\(s\) \['v_leader'\]"):
        read_pair(g)


def test_byte_identical_copies_are_named_and_still_loaded(tmp_path):
    a = write_pair(tmp_path / "ngsim_p1_runp1_f10_l9_00001.csv", seed=1)
    write_pair(tmp_path / "ngsim_p1_runp1_f11_l10_00002.csv", seed=2)
    shutil.copy(a, tmp_path / "ngsim_p1_runp1_f10_l9_00007.csv")
    assert [(c.name, o.name) for c, o in duplicate_files(pair_files(tmp_path))] == [
        ("ngsim_p1_runp1_f10_l9_00007.csv", "ngsim_p1_runp1_f10_l9_00001.csv")]
    with pytest.warns(DuplicatePairWarning, match=r"1 of 3 pair files .*f10_l9_00007\.csv = .*f10_l9_00001\.csv"):
        pairs = load_pairs(tmp_path)
    assert len(pairs) == 3  # the result does not change: the warning says what to do


def test_distinct_files_give_no_warning(tmp_path):
    write_pair(tmp_path / "x1.csv", seed=1)
    write_pair(tmp_path / "x2.csv", seed=2)
    with warnings.catch_warnings():
        warnings.simplefilter("error", DuplicatePairWarning)
        assert len(load_pairs(tmp_path)) == 2


def test_split_in_time_cuts_at_the_fraction_and_the_rest_starts_where_the_first_part_ends(tmp_path):
    p = read_pair(write_pair(tmp_path / "ngsim_p1_runp1_f10_l9_00001.csv", n=101))
    first, rest = split_in_time(p, 0.4)
    assert len(first) == 40 and len(rest) == 62  # 101 steps, one shared
    assert first.t[-1] == rest.t[0] and rest.t[-1] == p.t[-1]
    np.testing.assert_array_equal(np.concatenate([first.spacing, rest.spacing[1:]]), p.spacing)
    assert (first.name, first.group, first.leader_length) == (p.name, p.group, p.leader_length)


@pytest.mark.parametrize("fraction", [0.0, 1.0, -0.5, 0.05, 0.95])
def test_split_in_time_refuses_a_fraction_outside_0_1_or_a_part_too_short(tmp_path, fraction):
    p = read_pair(write_pair(tmp_path / "ngsim_p1_runp1_f10_l9_00001.csv", n=100))
    with pytest.raises(SpecError, match="fraction|at least 10"):
        split_in_time(p, fraction)


@pytest.mark.parametrize("edit, match", [
    (lambda df: df.astype({"v_follower": object}).assign(v_follower=lambda d: d.v_follower.where(d.index != 7, "abc")),
     r"column v_follower line 9: 'abc' is not a finite number"),
    (lambda df: df.astype({"t": object}).assign(t=lambda d: d.t.where(d.index != 3, "12:00")),
     r"column t line 5: '12:00' is not a finite number"),
    (lambda df: df.assign(v_follower=lambda d: d.v_follower.where(d.index != 4, -50.0)),
     r"column v_follower line 6: speed -50 < 0"),
    (lambda df: df.rename(columns={"x_leader": "x_follower", "x_follower": "x_leader"}),
     r"line \d+: bumper gap .* <= 0: the leader is not ahead of the follower"),
])
def test_implausible_or_non_numeric_pairs_are_refused_naming_file_and_line(tmp_path, edit, match):
    path = write_pair(tmp_path / "ngsim_p1_runp1_f10_l9_00001.csv")
    edit(pd.read_csv(path)).to_csv(path, index=False)
    with pytest.raises(SpecError, match=match):
        read_pair(path)


def test_an_empty_file_is_refused_and_a_manifest_under_train_is_skipped(tmp_path):
    (tmp_path / "empty.csv").write_bytes(b"")
    with pytest.raises(SpecError, match="empty.csv: empty file"):
        read_pair(tmp_path / "empty.csv")
    (tmp_path / "d" / "train").mkdir(parents=True)
    write_pair(tmp_path / "d" / "train" / "ngsim_p1_runp1_f10_l9_00001.csv")
    (tmp_path / "d" / "train" / "manifest.csv").write_text("name,lane\na,2\n")
    assert [p.name for p in load_pairs(tmp_path / "d")] == ["ngsim_p1_runp1_f10_l9_00001"]


def test_split_by_follower_refuses_bad_fractions_and_keeps_a_follower_on_each_side(tmp_path):
    pairs = [read_pair(write_pair(tmp_path / f"ngsim_p1_runp1_f{f}_l9_00001.csv", seed=f)) for f in range(10, 14)]
    for bad in (0, 1, 1.5, -0.3, float("nan"), "0.3", True):
        with pytest.raises(SpecError, match="held-out fraction: expected a number in \\(0, 1\\)"):
            split_by_follower(pairs, bad, seed=0)
    train, test = split_by_follower(pairs, 0.99, seed=0)
    assert len(train) == 1 and len(test) == 3
    with pytest.raises(SpecError, match="1 follower\\(s\\) cannot be split"):
        split_by_follower(pairs[:1], 0.3, seed=0)


def test_load_split_loads_then_splits_and_is_quiet_only_about_copies(tmp_path):
    from analysis.calibration.pairs import load_split

    for f in range(10, 14):
        write_pair(tmp_path / f"ngsim_p1_runp1_f{f}_l9_00001.csv", seed=f)
    shutil.copy(tmp_path / "ngsim_p1_runp1_f10_l9_00001.csv", tmp_path / "ngsim_p1_runp1_f10_l9_00002.csv")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        pairs, train, test = load_split(tmp_path, 0.5, 0)
    def names(ps):
        return [p.name for p in ps]

    with pytest.warns(DuplicatePairWarning):
        assert names(pairs) == names(load_pairs(tmp_path)) and len(pairs) == 5
    want_train, want_test = split_by_follower(pairs, 0.5, 0)
    assert (names(train), names(test)) == (names(want_train), names(want_test)) and train and test
    with pytest.warns(DuplicatePairWarning):
        load_split(tmp_path, 0.5, 0, quiet_duplicates=False)
