"""The package import graph, read from the source (ast): no circles, and the floors of
docs/architecture.md, with no exception. Every import counts, at module top or inside a function.
No package imports the script folders (``benchmarks``, ``studies``); tests import of them only
``studies.support``, what the studies share and the tests check, which the packages do not ship."""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("merge_irl", "sim", "irl", "scenarios", "analysis")
SUMO = ("libsumo", "traci", "sumolib")
#: The floors (docs/architecture.md): the packages of ours each package may import besides itself.
FLOORS = {
    "merge_irl": set(),
    "irl": {"merge_irl"},
    "scenarios": {"merge_irl"},
    "sim": {"merge_irl", "irl", "scenarios"},
    "analysis": {"merge_irl", "irl", "scenarios", "sim"},
}


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for pkg in PACKAGES for p in sorted((ROOT / pkg).rglob("*.py"))}


MODULES = _modules()


def _imported_names(name: str, path: Path) -> list[tuple[str, int]]:
    """Every ``(module, line)`` that ``name`` imports, anywhere in the file."""
    is_pkg = path.name == "__init__.py"
    out = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
        if isinstance(node, ast.Import):
            out += [(a.name, node.lineno) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:  # relative: resolve against this module's package
                base = name.split(".") if is_pkg else name.split(".")[:-1]
                base = base[: len(base) - (node.level - 1)]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module
            out.append((mod, node.lineno))
            # ``from pkg import submodule`` imports the submodule
            out += [(f"{mod}.{a.name}", node.lineno) for a in node.names if f"{mod}.{a.name}" in MODULES]
    return out


def _resolve(mod: str) -> str | None:
    """The project module ``mod`` names (a module, or the package holding the name), or None."""
    while mod:
        if mod in MODULES:
            return mod
        mod = mod.rpartition(".")[0]
    return None


def _graph() -> tuple[dict[str, set[str]], dict[tuple[str, str], int], dict[str, set[str]]]:
    edges: dict[str, set[str]] = {m: set() for m in MODULES}
    where: dict[tuple[str, str], int] = {}
    third: dict[str, set[str]] = {m: set() for m in MODULES}
    for name, path in MODULES.items():
        for mod, line in _imported_names(name, path):
            target = _resolve(mod) if mod.split(".")[0] in PACKAGES else None
            if target is None:
                third[name].add(mod.split(".")[0])
            elif target != name:
                edges[name].add(target)
                where.setdefault((name, target), line)
    return edges, where, third


EDGES, WHERE, THIRD_PARTY = _graph()


def _cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(edges[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(edges):
        if v not in index:
            visit(v)
    return out


def _is_package_init(importer: str, target: str) -> bool:
    """A package's ``__init__`` importing its own submodules (and those importing siblings
    through it) is how packages re-export; the submodule files themselves must not circle."""
    return MODULES[importer].name == "__init__.py" and target.startswith(importer + ".")


def test_the_graph_sees_function_level_imports():
    assert "sim" in EDGES and "irl.fit" in EDGES and len(EDGES) > 80
    # analysis.cli.main imports the command package at top; commands import the API inside functions
    assert "analysis.experiments.learn" in EDGES["analysis.cli.commands.learn"]
    assert "analysis.recording.log" in EDGES["analysis.evaluation.episode"]  # an import inside run_episode


def test_no_import_circles():
    edges = {m: {t for t in ts if not _is_package_init(m, t)} for m, ts in EDGES.items()}
    cycles = _cycles(edges)
    detail = ["; ".join(f"{a} -> {b} (line {WHERE[(a, b)]})" for a in c for b in sorted(edges[a]) if b in c)
              for c in cycles]
    assert cycles == [], "\n".join(detail)


def _ours(module: str, targets: set[str]) -> set[str]:
    return {t for t in targets if t.split(".")[0] != module.split(".")[0]}


@pytest.mark.parametrize("layer", sorted(FLOORS))
def test_floors(layer):
    bad = {}
    for m, targets in EDGES.items():
        if m.split(".")[0] != layer:
            continue
        wrong = {t for t in _ours(m, targets) if t.split(".")[0] not in FLOORS[layer]}
        if wrong:
            bad[m] = sorted(f"{t} (line {WHERE[(m, t)]})" for t in wrong)
    assert bad == {}


def test_every_package_has_a_floor():
    assert set(FLOORS) == set(PACKAGES)


def test_irl_never_imports_sumo():
    bad = {m: sorted(THIRD_PARTY[m] & set(SUMO)) for m in EDGES if m.split(".")[0] == "irl"}
    assert {m: v for m, v in bad.items() if v} == {}


#: The script folders at the top of the checkout (not installed): nothing of the packages imports
#: them, and the tests import only :data:`STUDY_SUPPORT`, the modules the studies share that the
#: tests check (the packages do not ship them); a test may run a script as a subprocess.
SCRIPT_FOLDERS = ("benchmarks", "studies")
STUDY_SUPPORT = "studies.support"


def _script_imports(path: Path, allowed: tuple[str, ...] = ()) -> list[str]:
    """The imports of a script folder in ``path``, other than of ``allowed`` and its modules."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
        names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                 else [node.module or ""] if isinstance(node, ast.ImportFrom) and not node.level else [])
        found += [f"{n} (line {node.lineno})" for n in names if n.split(".")[0] in SCRIPT_FOLDERS
                  and not any(n == a or n.startswith(a + ".") for a in allowed)]
    return found


def test_no_package_imports_the_script_folders():
    paths = list(MODULES.values())
    assert len(paths) > 200
    bad = {p.relative_to(ROOT).as_posix(): hits for p in paths if (hits := _script_imports(p))}
    assert bad == {}


def test_tests_import_only_the_study_support():
    paths = sorted((ROOT / "tests").rglob("*.py"))
    assert len(paths) > 100
    bad = {p.relative_to(ROOT).as_posix(): hits for p in paths if (hits := _script_imports(p, (STUDY_SUPPORT,)))}
    assert bad == {}
    users = [p for p in paths if _script_imports(p) and not _script_imports(p, (STUDY_SUPPORT,))]
    assert users, "no test imports studies.support: the exception is not needed"


def test_the_script_check_sees_an_import(tmp_path):
    f = tmp_path / "t.py"
    f.write_text("import os\ndef g():\n    from studies.x import y\nimport benchmarks.z as z\n"
                 "from studies.support.ceiling import c\nimport studies.supportive\n", encoding="utf-8")
    assert sorted(_script_imports(f)) == ["benchmarks.z (line 4)", "studies.support.ceiling (line 5)",
                                          "studies.supportive (line 6)", "studies.x (line 3)"]
    assert sorted(_script_imports(f, (STUDY_SUPPORT,))) == ["benchmarks.z (line 4)", "studies.supportive (line 6)",
                                                             "studies.x (line 3)"]


def test_the_floor_is_really_used():
    """merge_irl is the floor the packages stand on (the check above is not vacuous)."""
    users = {m.split(".")[0] for m, ts in EDGES.items() for t in ts if t.startswith("merge_irl")}
    assert {"sim", "irl", "analysis"} <= users


def test_the_check_catches_a_circle():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _cycles({"a": {"b"}, "b": set()}) == []


#: The floors inside ``sim`` (docs/architecture.md): the sub-packages of ``sim`` each may import.
SIM_FLOORS = {
    "errors": set(),
    "runtime": {"errors"},
    "ngsim": {"errors", "runtime"},
    "drivers": {"errors", "runtime"},
    "closed_loop": {"errors", "runtime", "drivers"},
    "merges": {"errors", "runtime", "ngsim", "drivers", "closed_loop"},
    "env": {"errors", "runtime", "drivers", "closed_loop"},
}


def _sim_room(module: str) -> str | None:
    parts = module.split(".")
    return parts[1] if parts[0] == "sim" and len(parts) > 1 else None


def test_sim_sub_floors():
    rooms = {_sim_room(m) for m in MODULES} - {None}
    assert rooms == set(SIM_FLOORS), "a sim sub-package without a floor (or a floor without a package)"
    bad = {}
    for m, targets in EDGES.items():
        room = _sim_room(m)
        if room is None:
            continue
        wrong = {t for t in targets if t == "sim" or (_sim_room(t) not in (None, room) and _sim_room(t) not in SIM_FLOORS[room])}
        if wrong:
            bad[m] = sorted(f"{t} (line {WHERE[(m, t)]})" for t in wrong)
    assert bad == {}


def test_sim_top_level_is_small():
    """At most 10 rooms (sub-packages and modules) at sim's top level, over at most 6 floors."""
    assert len(SIM_FLOORS) <= 10
    depth: dict[str, int] = {}

    def floor(room: str) -> int:
        if room not in depth:
            depth[room] = 1 + max((floor(r) for r in SIM_FLOORS[room]), default=0)
        return depth[room]

    assert max(floor(r) for r in SIM_FLOORS) <= 6
