"""The fenced examples of README.md and docs/*.md, and how tests/test_docs.py runs them.

A shell (``bash``, ``sh``, ``shell``) or ``python`` block is run by the tests unless the line right
above its fence is a marker saying why not::

    <!-- docs-test: not-run KIND: reason -->

``KIND`` is one of :data:`NOT_RUN_KINDS`; the reason is free text and must say something. A block
marked not-run still has its ``merge-irl`` commands parsed by the command-line parser and its
Python compiled and its imports checked. ``<!-- docs-test: after-demo -->`` documents that a block
reads ``runs/demo`` (the tests run every block in a folder where ``runs/demo`` is a small demo's
output); ``<!-- docs-test: authors-data -->`` one that reads the authors' demonstrations from
``railusm/``: it runs only where that folder is present (the tests link it there when
``tests/shared_data.RAILUSM`` exists) and is otherwise only parsed; ``<!-- docs-test: file NAME -->``
a block that is the contents of a file the page's later blocks use (``rules.py``): it is written to
``NAME`` instead of being run.

Run as a script (``python tests/doc_blocks.py PAGE``) it executes the page's runnable blocks in
order in the current folder, the Python blocks in one namespace (a later block may use an earlier
one's names, as a reader does), the shell blocks with ``bash -e -o pipefail``; it stops at the
first failing block and names its page and line.
"""

from __future__ import annotations

import re
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

#: why a block may be left out: each needs its reason
NOT_RUN_KINDS = {
    "long": "takes longer than a test may (minutes or more)",
    "external": "needs something a test cannot have (the authors' data, a download, a git host, a CI service)",
    "install": "installs packages",
    "fragment": "not a whole program (a synopsis, lines meant to be pasted into another block)",
}
SHELL = ("bash", "sh", "shell")
RUNNABLE = (*SHELL, "python")
MARKER = re.compile(r"^<!-- docs-test: (?P<what>not-run|after-demo|authors-data|file)(?: (?P<kind>[a-z-]+):)?(?P<reason>[^>]*)-->\s*$")
FENCE = re.compile(r"^```(\w*)[^\n]*\n(.*?)^```", re.DOTALL | re.MULTILINE)


@dataclass(frozen=True)
class Block:
    """One fenced block: ``language``, ``body``, the 1-based ``line`` of its opening fence, and
    its marker (``marker`` None, ``"not-run"`` or ``"after-demo"``; ``kind`` and ``reason`` of a
    not-run marker)."""

    page: str
    line: int
    language: str
    body: str
    marker: str | None = None
    kind: str | None = None
    reason: str = ""

    @property
    def runs(self) -> bool:
        return self.language in RUNNABLE and self.marker != "not-run"

    def where(self) -> str:
        return f"{self.page}:{self.line}"


def blocks(path: Path) -> list[Block]:
    """Every fenced block of ``path`` with the marker on the line above it."""
    text = path.read_text(encoding="utf-8")
    lines = text.splitlines()
    out = []
    for m in FENCE.finditer(text):
        line = text.count("\n", 0, m.start()) + 1
        above = lines[line - 2].strip() if line >= 2 else ""
        mk = MARKER.match(above)
        out.append(Block(path.name, line, m.group(1), m.group(2),
                         mk.group("what") if mk else None,
                         mk.group("kind") if mk else None,
                         (mk.group("reason") or "").strip() if mk else ""))
    return out


def stray_markers(path: Path) -> list[int]:
    """Line numbers of ``docs-test`` markers that are malformed or not right above a fence."""
    lines = path.read_text(encoding="utf-8").splitlines()
    bad = []
    for i, line in enumerate(lines):
        if "docs-test" in line:
            if not MARKER.match(line.strip()) or i + 1 >= len(lines) or not lines[i + 1].startswith("```"):
                bad.append(i + 1)
    return bad


def run_page(path: Path) -> None:
    """Run the runnable blocks of ``path`` in order in the current folder (see the module docstring).

    Raises:
        SystemExit: a block failed (the message names the page and line).
    """
    namespace: dict = {"__name__": "__main__"}
    for block in blocks(path):
        if not block.runs:
            continue
        if block.marker == "file":
            Path(block.reason).write_text(block.body, encoding="utf-8")
            print(f"--- {block.where()}: written to {block.reason}", flush=True)
            continue
        if block.marker == "authors-data" and not Path("railusm").is_dir():
            print(f"--- {block.where()}: not run (no railusm/ here: the authors' data)", flush=True)
            continue
        print(f"--- {block.where()} ({block.language})", flush=True)
        if block.language == "python":
            try:
                exec(compile(block.body, block.where(), "exec"), namespace)  # noqa: S102 (the docs' own example)
            except SystemExit as e:  # an example may end as a script does
                if e.code not in (None, 0):
                    raise SystemExit(f"{block.where()}: the Python example exited {e.code}") from e
            except BaseException as e:  # noqa: BLE001 (any failure of an example is the test's failure)
                raise SystemExit(f"{block.where()}: the Python example failed: {type(e).__name__}: {e}") from e
        else:
            proc = subprocess.run(["bash", "-e", "-o", "pipefail", "-c", block.body])
            if proc.returncode != 0:
                raise SystemExit(f"{block.where()}: the shell example exited {proc.returncode}")


if __name__ == "__main__":
    run_page(Path(sys.argv[1]))
