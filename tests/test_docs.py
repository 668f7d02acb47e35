"""The README and the docs pages stay true to the code they show.

Every Python example must parse and import only names that exist; every ``merge-irl ...`` line
of a shell example must be accepted by the command-line parser (parsing only, nothing runs).
Modules get renamed; these tests make a stale example fail here instead of for a user.
"""

from __future__ import annotations

import ast
import importlib
import importlib.util
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest
from doc_blocks import NOT_RUN_KINDS, RUNNABLE, blocks, stray_markers
from shared_data import RAILUSM

from analysis.cli.main import build_parser

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
PAGES = sorted((ROOT / "docs").glob("*.md"))
OUR_PACKAGES = ("merge_irl", "irl", "sim", "scenarios", "analysis")
#: a synopsis, not a command: [optional], a|b, <name>, ...
PLACEHOLDER = re.compile(r"^\[|\]$|\||<[A-Za-z_-]+>|\.\.\.")
FENCE = re.compile(r"^```(\w*)[^\n]*\n(.*?)^```", re.DOTALL | re.MULTILINE)


def code_blocks(path: Path, languages: tuple[str, ...]) -> list[str]:
    """The bodies of the fenced blocks of ``path`` whose language is one of ``languages``."""
    return [body for lang, body in FENCE.findall(path.read_text(encoding="utf-8")) if lang in languages]


def documents() -> list[Path]:
    return [README, *PAGES]


def test_readme_is_short_and_starts_with_the_two_set_up_commands():
    lines = README.read_text(encoding="utf-8").splitlines()
    assert len(lines) <= 250, f"README.md: {len(lines)} lines, at most 250 (detail goes to docs/)"
    first = FENCE.search(README.read_text(encoding="utf-8"))
    assert first is not None and first.group(1) == "bash"
    commands = first.group(2).strip().splitlines()
    assert len(commands) == 2
    assert commands[0].endswith("pip install -e . && merge-irl demo")
    assert commands[1].endswith("pip install -e '.[test]' && python -m pytest -q")


@pytest.mark.parametrize("path", documents(), ids=lambda p: p.name)
def test_python_examples_import_names_that_exist(path: Path):
    checked = 0
    for block in code_blocks(path, ("python",)):
        tree = ast.parse(block, filename=str(path))  # a SyntaxError names the page
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                if node.module.split(".")[0] not in OUR_PACKAGES:
                    continue
                module = importlib.import_module(node.module)
                for alias in node.names:
                    assert hasattr(module, alias.name) or _is_submodule(node.module, alias.name), (
                        f"{path.name}: 'from {node.module} import {alias.name}': no such name"
                    )
                    checked += 1
            elif isinstance(node, ast.Import):
                for alias in node.names:
                    if alias.name.split(".")[0] in OUR_PACKAGES:
                        importlib.import_module(alias.name)
                        checked += 1
    if path == README:
        assert checked >= 8, "the README's job scripts should import from the project"


def _is_submodule(package: str, name: str) -> bool:
    try:
        importlib.import_module(f"{package}.{name}")
    except ModuleNotFoundError:
        return False
    return True


def shell_commands(path: Path) -> list[str]:
    """``merge-irl`` invocations of the shell blocks, continuation lines joined, comments cut."""
    out = []
    for block in code_blocks(path, ("bash", "sh", "shell")):
        joined = re.sub(r"\\\n\s*", " ", block)
        for line in joined.splitlines():
            line = line.split(" #", 1)[0].strip()
            if not line.startswith("merge-irl "):
                continue
            if not any(PLACEHOLDER.search(token) for token in shlex.split(line)):
                out.append(line)
    return out


@pytest.mark.parametrize("path", documents(), ids=lambda p: p.name)
def test_shell_examples_are_accepted_by_the_command_line(path: Path):
    parser = build_parser()
    for line in shell_commands(path):
        argv = shlex.split(line)[1:]
        try:
            parser.parse_args(argv)
        except SystemExit as e:  # argparse reports a bad option by exiting 2
            pytest.fail(f"{path.name}: `{line}` is rejected by the parser (exit {e.code})")
    if path == README:
        assert len(shell_commands(path)) >= 4


# --- every example runs, or says why not -------------------------------------------------------


@pytest.mark.parametrize("path", documents(), ids=lambda p: p.name)
def test_every_example_runs_or_says_why_not(path: Path):
    """A shell or Python block is run by test_examples_run below unless a marker above it gives a
    kind from NOT_RUN_KINDS and a reason; a not-run block's commands are still checked."""
    assert stray_markers(path) == [], f"{path.name}: docs-test markers not right above a fence"
    for block in blocks(path):
        if block.marker != "not-run":
            continue
        assert block.language in RUNNABLE, f"{block.where()}: a not-run marker on a {block.language!r} block"
        assert block.kind in NOT_RUN_KINDS, (
            f"{block.where()}: not-run kind {block.kind!r}, expected one of {sorted(NOT_RUN_KINDS)}")
        assert len(block.reason.split()) >= 3, f"{block.where()}: say why the block is not run"
        if block.language == "python":
            compile(block.body, block.where(), "exec")
        else:
            _check_not_run_shell(block)


def _check_not_run_shell(block) -> None:
    """The commands of a shell block no test runs: ``python -m M`` names a module that exists,
    ``python FILE`` a file of the checkout (``merge-irl`` lines: the parser test above)."""
    joined = re.sub(r"\\\n\s*", " ", block.body)
    for line in joined.splitlines():
        words = shlex.split(line.split(" #", 1)[0]) if line.strip() and not line.lstrip().startswith("#") else []
        if words[:2] == ["python", "-m"] and words[2] not in ("pytest", "sphinx"):
            assert importlib.util.find_spec(words[2]) is not None, f"{block.where()}: no module {words[2]}"
        elif words[:1] == ["python"] and len(words) > 1 and words[1].endswith(".py"):
            assert (ROOT / words[1]).is_file(), f"{block.where()}: no file {words[1]}"


def test_the_readme_tables_have_short_cells():
    """README cells stay readable: the detail goes to the docs pages."""
    for line in README.read_text(encoding="utf-8").splitlines():
        if line.startswith("|") and not line.startswith("|---"):
            for cell in line.strip("|").split(" | "):
                assert len(cell.split()) <= 40, f"README.md: a table cell of {len(cell.split())} words: {cell[:80]}..."


def test_the_closed_loop_page_leads_with_what_holds_now():
    """The first section is the current table with its command and its date; the dated
    measurements are the page's last section, the changes the changelog page's (in the contents)."""
    text = (ROOT / "docs" / "closed-loop.md").read_text(encoding="utf-8")
    first = text.split("\n## ", 2)[1]
    assert first.startswith("What holds now")
    assert re.search(r"20\d\d-\d\d-\d\d", first) and "python -m studies." in first
    assert "| planner, history-free reward" in first and "| `sumo-in-lane`" in first
    for baseline in ("markov", "marginal", "bc", "uniform", "SUMO's free driver"):
        assert re.search(rf"^\| {re.escape(baseline)}", first, re.MULTILINE), baseline
    assert "changelog" in (ROOT / "docs" / "index.md").read_text(encoding="utf-8")
    assert text.splitlines().index("## What holds now") < 10  # the answer first, not at line 745
    assert not re.search(r"^## .*(20\d\d-\d\d-\d\d)", text, re.MULTILINE)  # no dated log sections
    assert re.findall(r"^## .*", text, re.MULTILINE)[-1] == "## Measurement history"  # history last


@pytest.fixture(scope="session")
def small_demo(tmp_path_factory) -> Path:
    """A small demo's output (the layout of ``merge-irl demo``'s ``runs/demo``), made once."""
    from analysis.demo.config import DemoConfig
    from analysis.demo.pipeline import run_demo

    out = tmp_path_factory.mktemp("docs-demo") / "demo"
    cfg = DemoConfig(train_seeds=(11,), heldout_seed=12, data_duration_s=240.0, eval_episodes=1,
                     eval_duration_s=110.0, methods=("qavg",), dagger_rounds=0)
    run_demo(out, cfg, quiet=True, progress=False)
    return out


def _pages_with_runnable_blocks() -> list[Path]:
    return [p for p in documents() if any(b.runs for b in blocks(p))]


@pytest.mark.sumo
@pytest.mark.parametrize("path", _pages_with_runnable_blocks(), ids=lambda p: p.name)
def test_examples_run(path: Path, small_demo: Path, tmp_path: Path):
    """Every runnable block of the page, in order, in a fresh folder whose ``runs/demo`` is a
    small demo's output (``railusm/`` the authors' data where present), as a reader runs them."""
    (tmp_path / "runs").mkdir()
    (tmp_path / "runs" / "demo").symlink_to(small_demo, target_is_directory=True)
    if RAILUSM.is_dir():
        (tmp_path / "railusm").symlink_to(RAILUSM, target_is_directory=True)
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    env["PATH"] = os.pathsep.join([str(Path(sys.executable).parent), env.get("PATH", "")])
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")])
    env["MPLBACKEND"] = "Agg"
    proc = subprocess.run([sys.executable, str(ROOT / "tests" / "doc_blocks.py"), str(path)], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, f"{path.name}: {proc.stderr[-3000:]}\n{proc.stdout[-2000:]}"
    ran = proc.stdout.count("--- ")
    assert ran >= 1


def _cells(line: str) -> list[str]:
    return re.split(r"\s{2,}", line.strip())


def test_docs_table_3_is_what_reproduce_prints(railusm):
    """The Table 3 printed in docs/learn.md has the layout ``merge-irl reproduce`` prints today, and
    its Q-Avg row is what reproduce prints on the authors' data (the cheap method: the others take
    minutes per trial; the page says when and how the whole table was made)."""
    from analysis.experiments.reproduce import ReproduceConfig, reproduce
    from analysis.experiments.reproduce_report import format_report

    (block,) = [b for b in code_blocks(ROOT / "docs" / "learn.md", ("",)) if b.startswith("Table 3:")]
    doc = block.splitlines()
    report = reproduce(3, ReproduceConfig(railusm, methods=("qavg",), executor="serial"))
    printed = format_report(report).splitlines()
    assert printed[0] == doc[0]  # title: data, trial count, settings, seed
    assert _cells(printed[1]) == _cells(doc[1])  # the columns
    head = _cells(doc[1])
    skip = {head.index("p vs MLIRL"), head.index("s/trial")}  # MLIRL not run here; times vary

    def row(lines: list[str], label: str) -> list[str]:
        (line,) = [x for x in lines if x.startswith(label + " ")]
        return [c for i, c in enumerate(_cells(line)) if i not in skip]

    for label in ("Q-Avg", "uniform", "marginal", "markov", "bc"):
        if any(x.startswith(label + " ") for x in doc):
            assert row(printed, label) == row(doc, label), label
    assert "REIRL" in block and "verdict" in doc[1]
