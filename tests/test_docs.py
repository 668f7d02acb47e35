"""The README and the docs pages stay true to the code they show.

Every Python example must parse and import only names that exist; every ``merge-irl ...`` line
of a shell example must be accepted by the command-line parser (parsing only, nothing runs).
Modules get renamed; these tests make a stale example fail here instead of for a user.
"""

from __future__ import annotations

import ast
import importlib
import re
import shlex
from pathlib import Path

import pytest

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
