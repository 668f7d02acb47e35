"""Habits as gates, run by ``.ci/checks``: no new function over complexity 10 (ruff C901, outside
the legacy list ``tools/complexity_legacy.txt``, which only shrinks), and commit subjects of at
most 72 characters on every commit after :data:`GATE_COMMIT` (details go in the body).

Usage: ``python tools/check_habits.py`` from the checkout; exit 1 with one line per offence."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LEGACY = ROOT / "tools" / "complexity_legacy.txt"
MAX_SUBJECT = 72
#: The last commit before the subject-length gate; every later commit is checked.
GATE_COMMIT = "9227fcd3672415befbec2e36be142e5ae18f6a5f"


def complexity_offences() -> list[str]:
    """Functions over C901 10 not in the legacy list, and legacy entries no longer over it."""
    out = subprocess.run(["ruff", "check", "--select", "C901", "--output-format", "json", "--exit-zero", "."],
                         cwd=ROOT, capture_output=True, text=True, check=True).stdout
    found = set()
    for d in json.loads(out):
        name = d["message"].split("`")[1]
        found.add(f"{Path(d['filename']).relative_to(ROOT).as_posix()} {name}")
    listed = {line.strip() for line in LEGACY.read_text().splitlines() if line.strip() and not line.startswith("#")}
    return ([f"{f}: complexity over 10 (split it; the legacy list only shrinks)" for f in sorted(found - listed)]
            + [f"{f}: no longer over 10, take it out of {LEGACY.name}" for f in sorted(listed - found)])


def subject_offences() -> list[str]:
    """Commits after :data:`GATE_COMMIT` whose subject is over :data:`MAX_SUBJECT` characters."""
    has = subprocess.run(["git", "cat-file", "-e", GATE_COMMIT], cwd=ROOT, capture_output=True)
    if has.returncode != 0:  # a shallow clone without the gate commit: nothing to compare with
        return []
    log = subprocess.run(["git", "log", "--format=%h %s", f"{GATE_COMMIT}..HEAD"], cwd=ROOT,
                         capture_output=True, text=True, check=True).stdout
    return [f"commit {line[:line.index(' ')]}: subject of {len(line) - line.index(' ') - 1} characters "
            f"(at most {MAX_SUBJECT}; details in the body)"
            for line in log.splitlines() if len(line) - line.index(" ") - 1 > MAX_SUBJECT]


def main() -> int:
    offences = complexity_offences() + subject_offences()
    for o in offences:
        print(o, file=sys.stderr)
    return 1 if offences else 0


if __name__ == "__main__":
    sys.exit(main())
