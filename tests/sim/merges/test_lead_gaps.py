"""A gap in the lead car C's rows (a recording that misses C for a few frames) is not read as
"no lead car": those frames are left out of the encounter as gaps in A and B are, counted
(``lead_gap_frames``), warned about, and split at by learning and by exported transitions."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from irl.domains.merge import mdp
from irl.domains.merge.bins import MergeBins
from sim.merges.encounters import LeadGapWarning, extract
from sim.merges.transitions import from_encounters
from sim.ngsim.io import read_ngsim

CASES = Path(__file__).resolve().parents[2] / "data" / "cases"


@pytest.fixture(scope="module")
def table():
    return read_ngsim(CASES / "ngsim-noisy-duplicates" / "clean.csv").table


def _with_c_gap(table, n_missing: int = 5):
    """The table without C's rows over ``n_missing`` frames in the middle of an encounter with C;
    returns (table, encounter id, missing frames, encounters before)."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", LeadGapWarning)
        before = extract(table)
    frames, merges = before.frames, before.merges
    for _, m in merges[(merges["C_id"] > 0) & (merges["n_frames"] >= 40)].iterrows():
        e = frames[frames["encounter_id"] == m["encounter_id"]]
        seen = e[np.isfinite(e["d_AC"])]
        if len(seen) < 30:
            continue
        mid = seen["Frame_ID"].to_numpy()[len(seen) // 2]
        missing = np.arange(mid, mid + n_missing)
        c = int(m["C_id"])
        drop = (table["Vehicle_ID"] == c) & table["Frame_ID"].isin(missing)
        assert drop.sum() == n_missing
        return table.loc[~drop].reset_index(drop=True), int(m["encounter_id"]), missing, before
    pytest.skip("no encounter with a lead car long enough in the case file")


def test_gap_in_c_is_left_out_counted_and_warned(table) -> None:
    gapped, eid, missing, before = _with_c_gap(table)
    with pytest.warns(LeadGapWarning, match=r"5 frame\(s\) of 1 encounter\(s\) had the lead car C missing"):
        after = extract(gapped)
    e = after.frames[after.frames["encounter_id"] == eid]
    assert not np.isin(e["Frame_ID"], missing).any()  # not rows with d_AC NaN ("no lead car")
    was = before.frames[before.frames["encounter_id"] == eid]
    assert len(e) == len(was) - len(missing)
    # every other frame is as it was
    keep = ~np.isin(was["Frame_ID"], missing)
    np.testing.assert_array_equal(e["d_AC"].to_numpy(), was["d_AC"].to_numpy()[keep])
    m_after = after.merges.set_index("encounter_id").loc[eid]
    m_before = before.merges.set_index("encounter_id").loc[eid]
    assert m_after["lead_gap_frames"] == 5 and m_before["lead_gap_frames"] == 0
    assert m_after["frame_gaps"] == m_before["frame_gaps"] + 1
    assert (after.merges["lead_gap_frames"].drop(index=after.merges.index[after.merges["encounter_id"] == eid])
            == 0).all()


def test_learning_and_transitions_split_at_the_gap(table) -> None:
    gapped, eid, missing, _ = _with_c_gap(table)
    with pytest.warns(LeadGapWarning):
        frames = extract(gapped).frames
    e = frames[frames["encounter_id"] == eid].reset_index(drop=True)
    runs = mdp.encounter_runs(e)
    assert np.unique(runs.run).size == 2  # split where C's rows are missing
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        d = mdp.resample_encounters(e, MergeBins.assumed_authors(), decision_step_s=0.1)
    assert len(d.demos.actions) == 2
    t = from_encounters(e, decision_step_s=0.1)
    assert np.isfinite(t.obs[:, 0]).all() and np.isfinite(t.next_obs[:, 0]).all()  # d_AC: C known throughout
