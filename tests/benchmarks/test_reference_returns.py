"""The reference-returns benchmark runs as a script (tests do not import the script folders): its
table on two seeds of the synthetic scenario without PPO, and its argument check."""

import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("gymnasium")  # the [gym] extra; CI installs it with [test]

ROOT = Path(__file__).resolve().parents[2]


def run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "benchmarks.reference_returns", *args], cwd=ROOT,
                          capture_output=True, text=True, timeout=600)


@pytest.mark.sumo
def test_the_table_has_a_row_per_driver_with_its_interval():
    r = run("--scenarios", "synthetic", "--seeds", "0", "1", "--skip-ppo")
    assert r.returncode == 0, r.stderr
    rows = [line.split("|")[1:-1] for line in r.stdout.splitlines() if line.startswith("| synthetic |")]
    assert [c[1].strip() for c in rows] == ["zero", "random", "sumo"]
    for c in rows:
        mean = float(c[2])
        lo, hi = (float(x) for x in c[3].strip(" []").split(","))
        assert lo <= mean <= hi and float(c[4]) >= 1 and c[5].strip().endswith("/2")


def test_a_budget_that_is_not_positive_exits_2():
    r = run("--ppo-budgets", "2048", "0")
    assert r.returncode == 2 and "--ppo-budgets: every budget must be a positive number of steps" in r.stderr
