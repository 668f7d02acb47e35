"""tools/house_figures.py runs on this checkout and prints every figure as a table row."""

import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
ROWS = ("evaluate() lines", "functions over 100 lines", "functions over complexity 10", "import circles",
        "options with two meanings", "re-exports from non-__init__ modules", "register APIs",
        "files citing the design/reference notes", "issue numbers in code and docs", "commit subjects since the gate")


def test_the_figures_script_prints_each_row():
    out = subprocess.run([sys.executable, "tools/house_figures.py"], cwd=ROOT, capture_output=True, text=True,
                         check=True, timeout=300).stdout
    rows = {line.split(" | ")[0].lstrip("| "): line.split(" | ")[1] for line in out.splitlines()[2:]}
    assert list(rows) == list(ROWS)
    for title in ROWS[:-1]:  # each count starts with a number
        assert re.match(r"\d+", rows[title]), (title, rows[title])
    assert int(rows["evaluate() lines"]) > 0  # the function was found
    assert rows["import circles"] == "0"  # the import-graph test's reading, which that test holds at 0
