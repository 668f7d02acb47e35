"""Per-pair fits that sit on their bounds are warned about (which parameter, which bound, how
many), and ``calibrate check --heldout-only`` compares with the pairs whose follower the fit did
not see."""

from __future__ import annotations

import shutil
import subprocess
import sys

import pytest

from analysis.calibration import load_result
from analysis.calibration.check import heldout_pairs, run_calibration_check
from analysis.calibration.fit import BOUNDS, fits_on_bounds
from analysis.calibration.pairs import load_pairs
from scenarios.errors import SpecError
from sim.ngsim.io import read_ngsim
from tests.shared_data import PAIRS_DIR, VENDORED

CASES_DIR = VENDORED / "cases"


def _cli(*args, cwd):
    return subprocess.run([sys.executable, "-m", "analysis", *args], capture_output=True, text=True, cwd=cwd,
                          timeout=300)


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("fit")
    (tmp / "pairs").mkdir()
    for f in sorted((PAIRS_DIR / "train").glob("*.csv"))[:6]:
        shutil.copy(f, tmp / "pairs")
    all_in = _cli("calibrate", "fit", "--pairs", "pairs", "--out", "all.toml", "--no-progress", cwd=tmp)
    held = _cli("calibrate", "fit", "--pairs", "pairs", "--out", "held.toml", "--holdout", "0.5", "--seed", "1",
                "--no-progress", cwd=tmp)
    assert all_in.returncode == 0 and held.returncode == 0, all_in.stderr + held.stderr
    return tmp, all_in


def test_fits_on_their_bounds_are_warned_about(fitted) -> None:
    tmp, r = fitted
    result = load_result(tmp / "all.toml")
    hits = fits_on_bounds(result.per_pair, result.fitted)
    assert hits, "six real pairs fitted with 5 parameters each: some sit on a bound"
    line = [ln for ln in r.stderr.splitlines() if "warning" in ln]
    assert len(line) == 1 and line[0].startswith("merge-irl calibrate fit: warning: 6 per-pair fits: ")
    for name, side, n in hits:
        bound = BOUNDS[name][0 if side == "lower" else 1]
        assert f"{name} at its {side} bound {bound:g} in {n}" in line[0]
        values = [getattr(f.params, name) for f in result.per_pair]
        assert sum(abs(v - bound) <= 1e-3 * (BOUNDS[name][1] - BOUNDS[name][0]) for v in values) == n


def test_check_against_the_pairs_the_fit_did_not_see(fitted) -> None:
    tmp, _ = fitted
    pairs = list(load_pairs(tmp / "pairs"))
    held = load_result(tmp / "held.toml")
    unseen = heldout_pairs(pairs, held, "held.toml", "pairs")
    assert 0 < len(unseen) < len(pairs) and not {p.group for p in unseen} & set(held.train_followers)
    table = read_ngsim(CASES_DIR / "ngsim-noisy-duplicates" / "clean.csv").table  # compared, not simulated
    r = run_calibration_check(params_path=tmp / "held.toml", pairs_dir=tmp / "pairs", table=table,
                              heldout_only=True)
    assert r.n_pairs == len(unseen)
    with pytest.raises(SpecError, match="every pair of .* has a follower .* was fitted on.*--holdout"):
        heldout_pairs(pairs, load_result(tmp / "all.toml"), "all.toml", "pairs")
    out = _cli("calibrate", "check", "--params", "all.toml", "--pairs", "pairs", "--heldout-only", cwd=tmp)
    assert out.returncode == 2 and out.stderr.count("\n") == 1 and "--heldout-only" in out.stderr
