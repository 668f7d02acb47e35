"""merge_irl.moved: an old import path fails in one line naming its new home, never imports, and
leaves every real module alone."""

import importlib
import importlib.machinery
import re
import subprocess
import sys
from pathlib import Path

import pytest

from merge_irl.moved import CHECKOUT_ONLY, MOVED, MOVED_PACKAGES, MovedModuleFinder, install, message

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("merge_irl", "sim", "irl", "scenarios", "analysis")


def _real_modules() -> set[str]:
    out = set()
    for pkg in PACKAGES:
        for p in (ROOT / pkg).rglob("*.py"):
            parts = list(p.relative_to(ROOT).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts.pop()
            out.add(".".join(parts))
    return out


REAL = _real_modules()


def _first_moved(old: str) -> str:
    """The outermost path of ``old`` (itself or a package holding it) that the table moves:
    Python imports parents first, so that is the one the error names."""
    parts = old.split(".")
    return next(".".join(parts[:i]) for i in range(1, len(parts) + 1) if ".".join(parts[:i]) in MOVED)


@pytest.mark.parametrize("old", sorted(MOVED))
def test_an_old_path_fails_in_one_line_naming_its_new_home(old):
    sys.modules.pop(old, None)
    with pytest.raises(ModuleNotFoundError) as err:
        importlib.import_module(old)
    first = _first_moved(old)
    assert str(err.value) == message(first)
    assert err.value.name == first
    assert "\n" not in str(err.value)
    assert f"{first} moved to {MOVED[first]}" in str(err.value)
    assert old not in sys.modules  # no silent alias


@pytest.mark.parametrize("old", sorted(MOVED))
def test_the_new_home_is_real(old):
    new = MOVED[old]
    if new.split(".")[0] in CHECKOUT_ONLY:
        # benchmarks/, studies/ and tools/ are folders of the checkout, not installed
        path = ROOT.joinpath(*new.split("."))
        assert path.with_suffix(".py").is_file() or (path / "__init__.py").is_file()
    else:
        assert new in REAL
        importlib.import_module(new)


@pytest.mark.parametrize("old", sorted(MOVED))
def test_no_old_path_is_a_real_module(old):
    assert old not in REAL
    parent = old.rpartition(".")[0]
    if parent in MOVED:  # a module of a moved package: the package's own entry stands for it
        return
    assert parent in REAL
    assert importlib.machinery.PathFinder.find_spec(old, importlib.import_module(parent).__path__) is None


def test_modules_of_a_moved_package_moved_with_it():
    for old, new in MOVED.items():
        package = old.rpartition(".")[0]
        if package in MOVED:
            assert package in MOVED_PACKAGES and new == MOVED[package] + old[len(package):]
    assert all(MOVED[p] == new for p, new in MOVED_PACKAGES.items())


def test_the_paths_users_reported_are_in_the_table():
    for old in ("sim.ngsim_io", "irl.merge_mdp", "analysis.rrd_read", "sim.controller", "sim.policy"):
        assert old in MOVED


def test_real_modules_and_unknown_names_are_left_alone():
    import sim  # noqa: F401  (installs the finder)

    finders = [f for f in sys.meta_path if isinstance(f, MovedModuleFinder)]
    # after the real finders (the import system's PathFinder), so a real module always wins; a
    # finder another library appends later (importlib_metadata's) may follow it
    from importlib.machinery import PathFinder

    assert len(finders) == 1 and sys.meta_path.index(finders[0]) > sys.meta_path.index(PathFinder)
    install()
    install()
    assert sum(isinstance(f, MovedModuleFinder) for f in sys.meta_path) == 1
    for name in ("sim.closed_loop.controller", "irl.domains.merge.mdp", "scenarios.spec", "no_such_package"):
        assert finders[0].find_spec(name, None) is None
    assert importlib.import_module("sim.closed_loop.controller").Controller
    with pytest.raises(ModuleNotFoundError, match=r"^No module named 'sim\.no_such_module'$"):
        importlib.import_module("sim.no_such_module")


def test_the_changelog_lists_every_move():
    text = (ROOT / "docs" / "changelog.md").read_text(encoding="utf-8")
    rows = dict(re.findall(r"^\| `([\w.]+)` \| `([\w.]+)` \|", text, re.MULTILINE))
    assert {old: rows.get(old) for old in MOVED} == MOVED


@pytest.mark.parametrize("statement", ["import sim.controller", "from sim.controller import Controller"])
def test_the_command_line_sees_the_one_line(statement):
    out = subprocess.run([sys.executable, "-c", statement], capture_output=True, text=True, cwd=ROOT)
    assert out.returncode == 1
    assert out.stderr.strip().splitlines()[-1] == f"ModuleNotFoundError: {message('sim.controller')}"


def test_the_table_imports_nothing_of_ours_and_sim_still_not_sumo():
    code = (
        "import sys, merge_irl.moved\n"
        "ours = [m for m in sys.modules if m.split('.')[0] in ('sim', 'irl', 'scenarios', 'analysis')]\n"
        "assert not ours, ours\n"
        "import sim\n"
        "bad = [m for m in sys.modules if m.split('.')[0] in ('libsumo', 'traci', 'sumolib')]\n"
        "assert not bad, bad\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True, cwd=ROOT)
