"""Q-Avg's Newton ascent stops early when its weights run away while the likelihood no longer rises
(irl.ascent.stalled), flagged not converged and unbounded, instead of spending its 500-iteration cap."""

import numpy as np
from irl_testdata import encounter_table

from analysis.cli.main import main
from irl.ascent import STALL_WINDOW, stalled
from irl.result import SavedModel


def test_stalled_tells_diverging_weights_from_a_stall_and_from_progress():
    flat = [-10.0] * (STALL_WINDOW + 2)
    growing = [np.array([2.0 ** i, 1.0]) for i in range(STALL_WINDOW + 2)]
    steady = [np.array([1.0, 1.0 + 1e-12 * i]) for i in range(STALL_WINDOW + 2)]
    assert "weights diverge" in stalled(flat, growing)
    assert stalled(flat, steady).startswith("stalled")
    rising = [-10.0 + 1e-3 * i for i in range(STALL_WINDOW + 2)]
    assert stalled(rising, growing) is None
    assert stalled(flat[:STALL_WINDOW], growing[:STALL_WINDOW]) is None  # too few steps to tell


def test_qavg_on_17_encounters_stops_early_flagged(tmp_path, capsys):
    """17 encounters of 30 frames (9 decisions each at 0.3 s): one driver feature barely varies
    between actions, Newton sent its weight to ~1e11 in its first steps and then took 490 steps
    that changed nothing."""
    table = tmp_path / "enc17.parquet"
    encounter_table(n=17, rows=30, seed=0).to_parquet(table)
    out = tmp_path / "m.json"
    assert main(["learn", "--method", "qavg", "--domain", "merge", "--demos", str(table), "--out", str(out),
                 "--no-progress"]) == 0
    said = capsys.readouterr()
    err = said.out + said.err
    m = SavedModel.load(out)
    assert m.info["n_steps"] == 153 and m.info["n_trajectories"] == 17
    assert m.info["n_iterations"] <= 30  # the cap is 500
    assert not m.converged and m.unbounded
    assert m.info["extra"]["diverged"] == 1.0
    assert "weights unbounded in practice" in err and "NOT converged" in err
    assert float(np.max(np.abs(m.theta))) > 1e6  # the run-away weight the flag is about
