"""docs/environment.md's Python examples run as written (each as a script in its own process,
as a reader would run it: libsumo allows one SUMO per process, the vector example spawns workers)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests.doc_blocks import blocks

pytest.importorskip("gymnasium")  # the [gym] extra; CI installs it with [test]

pytestmark = pytest.mark.sumo

ROOT = Path(__file__).resolve().parents[3]
PAGE = ROOT / "docs" / "environment.md"
BLOCKS = [b.body for b in blocks(PAGE) if b.language == "python" and b.runs]  # not the not-run ones (SB3)


def test_the_page_has_its_examples():
    assert len(BLOCKS) == 6


@pytest.mark.parametrize("index", range(len(BLOCKS)))
def test_example_runs(index, tmp_path):
    script = tmp_path / f"example_{index}.py"
    script.write_text(BLOCKS[index], encoding="utf-8")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]),
           "MERGE_IRL_CACHE": str(tmp_path / "cache")}
    out = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=300, env=env,
                         cwd=tmp_path)
    assert out.returncode == 0, out.stderr[-3000:]
    if index == 0:  # the episode ended with a release reason and a time
        reason, time_s = out.stdout.split()[-2:]
        assert reason in ("merge_done", "collision", "left_section", "left_lane", "b_lost", "timeout") and float(time_s) > 60
    if index == 4:
        assert "vehicles at 70.0 s;" in out.stdout
    if index == 5:  # an observation and a reward added by registration, in the environment
        assert out.stdout.split("\n")[-2] == "(2,) ['reward'] True"
    if index == 2:  # two episodes, each its own recording
        assert out.stdout.split() == ["episodes/episode-0.rrd", "episodes/episode-1.rrd"]
        assert all((tmp_path / "episodes" / f"episode-{k}.rrd").stat().st_size > 1000 for k in (0, 1))
    if index == 3:  # the multi-agent run released its agents, some after a merge
        n, reasons = out.stdout.split(" agents released: ")
        assert int(n.split()[-1]) >= 2 and "merge_done" in reasons
