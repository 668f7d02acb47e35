"""The house's figures, printed as a table: the sizes and habits the renovations aim at.

Rows: the line count of ``evaluate()``; functions over 100 lines in the packages; functions over
complexity 10 (ruff C901) and how many of them are outside ``tools/complexity_legacy.txt``; import
circles; CLI options with two meanings; names re-exported by non-``__init__`` modules; register APIs;
files citing the design or reference notes; issue numbers; commit-subject lengths since the habit gate.

Usage: ``python tools/house_figures.py`` from the checkout (needs ruff and git); prints one
``figure | value | detail`` row per figure. Read-only: it writes nothing."""

from __future__ import annotations

import argparse
import ast
import json
import re
import shutil
import statistics
import subprocess
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("merge_irl", "sim", "irl", "scenarios", "analysis")
#: The trees the citation count reads (``docs/_build`` is skipped).
CITATION_TREES = ("merge_irl", "sim", "irl", "scenarios", "analysis", "benchmarks", "studies", "tools", "tests",
                  "docs", "README.md")
#: The notes users do not have; split so that this file does not cite them itself.
NOTES = ("DESIGN" + ".md", "REFERENCE" + ".md")
LONG_FUNCTION = 100


def _package_files() -> Iterator[Path]:
    for pkg in PACKAGES:
        yield from sorted((ROOT / pkg).rglob("*.py"))


def _rel(path: Path) -> str:
    return path.relative_to(ROOT).as_posix()


def _functions(tree: ast.AST) -> Iterator[ast.FunctionDef | ast.AsyncFunctionDef]:
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            yield node


def _lines(node: ast.AST) -> int:
    return int(node.end_lineno or node.lineno) - node.lineno + 1  # type: ignore[attr-defined]


def evaluate_lines() -> tuple[int, str]:
    """Lines of ``analysis.evaluation.evaluate.evaluate`` (from ``def`` to its last line)."""
    tree = ast.parse((ROOT / "analysis/evaluation/evaluate.py").read_text(encoding="utf-8"))
    for f in _functions(tree):
        if f.name == "evaluate":
            return _lines(f), f"{len(f.args.args) + len(f.args.kwonlyargs)} parameters"
    return 0, "not found"


def long_functions() -> tuple[int, str]:
    """Functions (and methods) over :data:`LONG_FUNCTION` lines in the packages."""
    found = []
    for path in _package_files():
        for f in _functions(ast.parse(path.read_text(encoding="utf-8"))):
            if _lines(f) > LONG_FUNCTION:
                found.append(f"{_rel(path)}:{f.name} ({_lines(f)})")
    return len(found), ", ".join(found)


def _ruff() -> str:
    local = Path(sys.executable).with_name("ruff")
    return str(local) if local.exists() else (shutil.which("ruff") or "ruff")


def complex_functions() -> tuple[str, str]:
    """Functions over C901 10 in the checkout, and how many are outside the legacy list."""
    out = subprocess.run([_ruff(), "check", "--select", "C901", "--output-format", "json", "--exit-zero", "."],
                         cwd=ROOT, capture_output=True, text=True, check=True).stdout
    found = {f"{_rel(Path(d['filename']))} {d['message'].split('`')[1]}" for d in json.loads(out)}
    legacy_file = ROOT / "tools" / "complexity_legacy.txt"
    legacy = {ln.strip() for ln in legacy_file.read_text().splitlines() if ln.strip() and not ln.startswith("#")}
    outside = sorted(found - legacy)
    return f"{len(found)} ({len(outside)} outside the legacy list)", ", ".join(outside)


def import_circles() -> tuple[int, str]:
    """Import circles between the packages' modules, by the import-graph test's own reading."""
    sys.path.insert(0, str(ROOT))
    try:
        from tests import test_import_graph as graph
    finally:
        sys.path.remove(str(ROOT))
    edges = {m: {t for t in ts if not graph._is_package_init(m, t)} for m, ts in graph.EDGES.items()}
    cycles = graph._cycles(edges)
    return len(cycles), "; ".join(" <-> ".join(c) for c in cycles)


def _subparsers(parser: argparse.ArgumentParser, prefix: str) -> Iterator[tuple[str, argparse.ArgumentParser]]:
    yield prefix, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _subparsers(sub, f"{prefix} {name}".strip())


def _meaning(action: argparse.Action) -> tuple[str, str, str, str]:
    kind = getattr(action.type, "__name__", repr(action.type)) if action.type is not None else "-"
    return action.dest, kind, type(action).__name__, repr(action.default)


def two_meaning_options() -> tuple[int, str]:
    """Option strings whose dest, type, action or default differ between the CLI's commands."""
    sys.path.insert(0, str(ROOT))
    try:
        from analysis.cli.main import build_parser
        parser = build_parser()
    finally:
        sys.path.remove(str(ROOT))
    meanings: dict[str, dict[tuple[str, str, str, str], list[str]]] = {}
    for command, sub in _subparsers(parser, ""):
        for action in sub._actions:
            if isinstance(action, (argparse._HelpAction, argparse._SubParsersAction)):
                continue
            for opt in action.option_strings:
                meanings.setdefault(opt, {}).setdefault(_meaning(action), []).append(command or "merge-irl")
    two = sorted(opt for opt, m in meanings.items() if len(m) > 1)
    return len(two), ", ".join(f"{opt} ({len(meanings[opt])})" for opt in two)


def _used_names(tree: ast.Module) -> set[str]:
    used = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Name):
            used.add(node.id)
        elif isinstance(node, ast.Constant) and isinstance(node.value, str):  # string annotations
            used.update(re.findall(r"[A-Za-z_][A-Za-z0-9_]*", node.value))
    return used


def all_names(tree: ast.Module) -> set[str] | None:
    """The names of the module's ``__all__``, or None where it declares none."""
    for n in tree.body:
        if isinstance(n, ast.Assign) and any(isinstance(t, ast.Name) and t.id == "__all__" for t in n.targets):
            return set(ast.literal_eval(n.value))
    return None


def top_imports(tree: ast.Module) -> list[str]:
    names = []
    for node in tree.body:
        if isinstance(node, ast.ImportFrom) and node.module != "__future__":
            names += [a.asname or a.name for a in node.names if a.name != "*"]
        elif isinstance(node, ast.Import):
            names += [a.asname or a.name.split(".")[0] for a in node.names]
    return names


def re_exports() -> tuple[str, str]:
    """Names a non-``__init__`` module imports at its top for its importers: listed in its
    ``__all__`` (a declared facade), or, where it declares none, never used in it."""
    declared: dict[str, int] = {}
    unused = []
    for path in _package_files():
        if path.name == "__init__.py":
            continue
        tree = ast.parse(path.read_text(encoding="utf-8"))
        imported, public = top_imports(tree), all_names(tree)
        if public is not None:
            if n := len(public & set(imported)):
                declared[_rel(path)] = n
        else:
            used = _used_names(tree)
            unused += [f"{_rel(path)}:{n}" for n in imported if n not in used]
    total = sum(declared.values())
    detail = ", ".join(f"{m} ({n})" for m, n in declared.items())
    return (f"{total + len(unused)} ({total} listed in a module's __all__, {len(unused)} unused imports)",
            f"through __all__: {detail or 'none'}; unused: {', '.join(unused) or 'none'}")


def register_apis() -> tuple[int, str]:
    """Distinct ways to register into a registry: module-level ``register*`` functions (outside the
    CLI's command modules, whose ``register(subparsers)`` adds a parser) and ``*Registry`` classes."""
    found = []
    for path in _package_files():
        if _rel(path).startswith("analysis/cli/"):
            continue
        for node in ast.parse(path.read_text(encoding="utf-8")).body:
            if isinstance(node, ast.FunctionDef) and node.name.startswith("register"):
                found.append(f"{_rel(path)}:{node.name}")
            elif isinstance(node, ast.ClassDef) and node.name.endswith("Registry"):
                found.append(f"{_rel(path)}:{node.name} (class)")
    return len(found), ", ".join(found)


def _citation_files() -> Iterator[Path]:
    for tree in CITATION_TREES:
        path = ROOT / tree
        if path.is_file():
            yield path
            continue
        for p in sorted(path.rglob("*")):
            if p.is_file() and "_build" not in p.parts and p.suffix in {".py", ".md", ".toml", ".txt", ".rst", ".cfg"}:
                yield p


def note_citations() -> tuple[int, str]:
    """Files citing the design or reference notes by file name."""
    found = [_rel(p) for p in _citation_files() if any(n in p.read_text(encoding="utf-8") for n in NOTES)]
    return len(found), ", ".join(found)


ISSUE_NUMBER = re.compile(r"\b[Ii]ssues?[ -]#?\d+")


def issue_numbers() -> tuple[str, str]:
    """Mentions of an issue by its number, in the forms ``tests/test_habits.py`` refuses."""
    hits = {_rel(p): len(ISSUE_NUMBER.findall(p.read_text(encoding="utf-8"))) for p in _citation_files()}
    hits = {p: n for p, n in hits.items() if n}
    return f"{sum(hits.values())} in {len(hits)} files", ", ".join(f"{p} ({n})" for p, n in hits.items())


def _subject_lengths(*revisions: str) -> list[int]:
    out = subprocess.run(["git", "log", "--format=%s", *revisions], cwd=ROOT, capture_output=True, text=True,
                         check=True).stdout
    return [len(s) for s in out.splitlines()]


def subject_lengths() -> tuple[str, str]:
    """Median and max subject length of the commits after the habit gate's base commit, and of the
    65 commits before it."""
    from tools.check_habits import GATE_COMMIT, MAX_SUBJECT
    before = _subject_lengths("-n", "65", GATE_COMMIT)
    since = _subject_lengths(f"{GATE_COMMIT}..HEAD")

    def summary(lengths: list[int]) -> str:
        if not lengths:
            return "no commits"
        over = sum(n > MAX_SUBJECT for n in lengths)
        return f"median {statistics.median(lengths):g}, max {max(lengths)}, {over}/{len(lengths)} over {MAX_SUBJECT}"

    return summary(since), f"the 65 before the gate: {summary(before)}"


FIGURES: tuple[tuple[str, Callable[[], tuple[object, str]]], ...] = (
    ("evaluate() lines", evaluate_lines),
    (f"functions over {LONG_FUNCTION} lines", long_functions),
    ("functions over complexity 10", complex_functions),
    ("import circles", import_circles),
    ("options with two meanings", two_meaning_options),
    ("re-exports from non-__init__ modules", re_exports),
    ("register APIs", register_apis),
    ("files citing the design/reference notes", note_citations),
    ("issue numbers in code and docs", issue_numbers),
    ("commit subjects since the gate", subject_lengths),
)


def main() -> int:
    sys.path.insert(0, str(ROOT))
    print("| figure | value | detail |")
    print("|---|---|---|")
    for title, figure in FIGURES:
        value, detail = figure()
        print(f"| {title} | {value} | {detail} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
