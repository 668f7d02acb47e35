"""One home per name: a module that is not a package's ``__init__`` does not re-export what it
imports, except the declared facades below.

A re-export is a name a module imports at its top and either lists in its ``__all__`` or never
uses (no ``Name`` of it in the code, quoted annotations included): it is there only so that
importers of ``this_module.Name`` keep working. Such names were left by file splits; their
importers now import them from their home. The moved-path finder (``merge_irl.moved``) answers
for modules, not for names, so the few re-exports the docs show users stay, declared here with
the docs page that shows them; a test checks that each is still a re-export and still shown.
Read from the source (ast)."""

import ast
import re
from pathlib import Path

from tools.house_figures import all_names, top_imports  # one reading of top imports and __all__

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("merge_irl", "sim", "irl", "scenarios", "analysis")

#: Declared facades: module -> the names it re-exports for users (the docs or the README show them).
FACADES: dict[str, frozenset[str]] = {
    # the NGSIM file entry points (docs/trajectories.md's examples import them from here)
    "sim.ngsim.io": frozenset({"read_ngsim", "read_trajectories", "write_ngsim_csv"}),
    # the method registry beside the entry point fit() (docs/architecture.md, docs/sweeps.md)
    "irl.fit": frozenset({"REGISTRY", "Method", "method_names", "register"}),
}


def _module_name(path: Path) -> str:
    return ".".join(path.relative_to(ROOT).with_suffix("").parts)


def _annotation_strings(tree: ast.Module) -> set[str]:
    """The names inside quoted annotations (``x: "Foo"``)."""
    annotations = [n.annotation for n in ast.walk(tree) if isinstance(n, (ast.arg, ast.AnnAssign)) and n.annotation]
    annotations += [n.returns for n in ast.walk(tree) if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef))
                    and n.returns]
    found = set()
    for ann in annotations:
        for c in ast.walk(ann):
            if isinstance(c, ast.Constant) and isinstance(c.value, str):
                found.update(re.findall(r"[A-Za-z_]\w*", c.value))
    return found


def _used_names(tree: ast.Module) -> set[str]:
    return {n.id for n in ast.walk(tree) if isinstance(n, ast.Name)} | _annotation_strings(tree)


def re_exports(source: str) -> set[str]:
    """The names ``source`` (a module's text) imports at its top and lists in ``__all__`` or never uses."""
    tree = ast.parse(source)
    used, listed = _used_names(tree), all_names(tree) or set()
    return {n for n in top_imports(tree) if n in listed or n not in used}


def _found() -> dict[str, set[str]]:
    out = {}
    for pkg in PACKAGES:
        for path in sorted((ROOT / pkg).rglob("*.py")):
            if path.name != "__init__.py" and (names := re_exports(path.read_text(encoding="utf-8"))):
                out[_module_name(path)] = names
    return out


FOUND = _found()


def test_no_re_exports_outside_the_declared_facades():
    outside = {m: sorted(names - FACADES.get(m, frozenset())) for m, names in FOUND.items()}
    assert {m: names for m, names in outside.items() if names} == {}


def test_each_facade_is_still_a_re_export_and_shown_in_the_docs():
    pages = [*sorted((ROOT / "docs").glob("*.md")), ROOT / "README.md"]
    text = "\n".join(p.read_text(encoding="utf-8") for p in pages)
    for module, names in FACADES.items():
        assert names <= FOUND.get(module, set()), f"{module}: a declared facade name is no longer re-exported"
        for name in names:
            assert re.search(rf"{re.escape(module)}(\.| import [^\n]*\b){name}\b", text), (module, name)


def test_the_count_sees_both_kinds():
    source = ("from __future__ import annotations\n"
              "from a import Listed, Unused, Used, Quoted\n"
              "import b.c\n"
              "__all__ = ['Listed', 'f']\n"
              "def f(x: 'Quoted') -> Used:\n"
              "    return b.c\n")
    assert re_exports(source) == {"Listed", "Unused"}
