"""Resampling encounters by time where a recording has missing frames."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
from irl_testdata import encounter_table as table

from irl.domains.merge import mdp as m
from irl.domains.merge.actions import N_ACTIONS, ZERO_ACTION, actions_of
from irl.domains.merge.bins import MergeBins, fit_quantile_bins
from irl.domains.merge.car_following import car_following_decisions
from irl.planning.decisions import encounter_decisions

CASES = Path(__file__).resolve().parents[3] / "data" / "cases"


def row_by_row(df, bins, k, encoding):
    """Today's rule before the fix, written out: runs cut only where the id changes or Frame_ID
    does not increase; decisions every k rows (the test's own code, for the gap-free identity)."""
    ids, fr = df["encounter_id"].to_numpy(), df["Frame_ID"].to_numpy()
    brk = np.r_[True, (ids[1:] != ids[:-1]) | (fr[1:] <= fr[:-1])]
    run = np.cumsum(brk)
    paper = bins.encode(df)
    acc = df["acc_A"].to_numpy(np.float64)
    states, actions, rows = [], [], []
    for r in np.unique(run):
        idx = np.flatnonzero(run == r)
        n = idx.size // k
        if n == 0:
            continue
        step = actions_of(acc[idx[: n * k]].reshape(n, k).mean(axis=1))
        at = idx[: n * k: k]
        s = paper[at]
        if encoding == "driver":
            prev = step[:-1] if n >= 2 else np.array([ZERO_ACTION])
            if n >= 2:
                s, step, at = s[1:], step[1:], at[1:]
            s = s * N_ACTIONS + prev
        states.append(s)
        actions.append(step)
        rows.append(at)
    return states, actions, np.concatenate(rows)


def ngsim_case_encounters():
    from sim.merges.encounters import extract
    from sim.ngsim.io import read_ngsim

    return extract(read_ngsim(CASES / "ngsim-noisy-duplicates" / "clean.csv").table).frames


@pytest.mark.parametrize("source", ["synthetic", "ngsim-case"])
@pytest.mark.parametrize("encoding", ["paper", "driver"])
@pytest.mark.parametrize("step", [0.1, 0.3, 0.5])
def test_tables_without_gaps_resample_exactly_as_before(source, encoding, step):
    df = table() if source == "synthetic" else ngsim_case_encounters()
    assert len(df) > 30
    bins = fit_quantile_bins(df) if source == "synthetic" else MergeBins.assumed_authors()
    with warnings.catch_warnings():
        warnings.simplefilter("error", m.FrameGapWarning)  # no gap, no warning
        got = m.resample_encounters(df, bins, encoding=encoding, decision_step_s=step)
    states, actions, rows = row_by_row(df, bins, m.frames_per_step(step), encoding)
    assert len(got.demos.states) == len(states)
    for a, b in zip(got.demos.states, states):
        np.testing.assert_array_equal(a, b)
    for a, b in zip(got.demos.actions, actions):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(got.rows, rows)
    assert got.gaps == 0 and got.gap_rows_dropped == 0


def test_a_gap_splits_the_encounter_and_no_step_spans_it():
    df = table(n=2, rows=60)
    # encounter 1 loses 14 frames (1.4 s) in the middle, encounter 2 a 2-frame stretch near its end
    gap1 = (df.encounter_id == 1) & df.Frame_ID.between(1020, 1033)
    gap2 = (df.encounter_id == 2) & df.Frame_ID.between(1056, 1057)
    gapped = df[~(gap1 | gap2)].reset_index(drop=True)
    bins = fit_quantile_bins(df)
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        got = m.resample_encounters(gapped, bins, decision_step_s=0.3)
    # split at the gaps, each part on its own time grid
    assert got.demos.names == ("encounter 1", "encounter 1 from frame 1034 (after 14 missing frames)", "encounter 2")
    assert len(rec) == 1 and rec[0].category is m.FrameGapWarning
    msg = str(rec[0].message)
    assert "2 encounter(s) have missing frames (2 gap(s), 16 frames)" in msg
    assert "1 part(s) shorter than one step left out (2 rows)" in msg  # encounter 2's last 2 frames
    assert got.gaps == 2 and got.gap_rows_dropped == 2
    # every decision's k frames are consecutive: no step spans missing frames
    fr = gapped["Frame_ID"].to_numpy()
    k = 3
    assert np.all(fr[got.rows + k - 1] - fr[got.rows] == k - 1)
    # and the decisions are the gap-free table's decisions at those frames, each part on its own grid
    first = m.resample_encounters(df[(df.encounter_id == 1) & (df.Frame_ID < 1020)].reset_index(drop=True), bins)
    np.testing.assert_array_equal(got.demos.states[0], first.demos.states[0])
    np.testing.assert_array_equal(got.demos.actions[0], first.demos.actions[0])
    assert [s.size for s in got.demos.states] == [20 // 3, 26 // 3, 56 // 3]


def test_car_following_and_planning_decisions_do_not_span_a_gap():
    df = table(n=1, rows=60)
    gapped = df[~df.Frame_ID.between(1020, 1033)].reset_index(drop=True)
    with pytest.warns(m.FrameGapWarning):
        cf = car_following_decisions(gapped, decision_step_s=0.3)
    with pytest.warns(m.FrameGapWarning) as said:
        plan = encounter_decisions(gapped, decision_step_s=0.3)
    assert len(said) == 1  # said once, not once per reading of the same rows
    # driver encoding: each part's first decision is its row k, its previous action from rows 0..k-1
    assert cf.n == (20 // 3 - 1) + (26 // 3 - 1)
    assert len(np.unique(plan.groups)) == 2  # the two parts are two groups
    # the previous step is never taken across the gap: the first decision after it starts anew
    assert np.isfinite(plan.prev_acc).all()
    fr = gapped["Frame_ID"].to_numpy()
    with pytest.warns(m.FrameGapWarning):
        rows = m.resample_encounters(gapped, MergeBins.assumed_authors(), encoding="driver", decision_step_s=0.3).rows
    assert np.all(fr[rows] - fr[rows - 3] == 3)  # the previous step's frames are consecutive too


def test_every_part_shorter_than_a_step_is_one_line():
    df = table(n=1, rows=6)
    gapped = df[df.Frame_ID.isin([1000, 1001, 1003, 1004])].reset_index(drop=True)
    with pytest.raises(m.DemonstrationError, match="part between missing frames"), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        m.resample_encounters(gapped, MergeBins.assumed_authors(), decision_step_s=0.3)
