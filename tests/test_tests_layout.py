"""The tests mirror the code: each folder under ``tests/`` is a package folder of the checkout
(``tests/irl/domains/merge`` for ``irl/domains/merge``, ``tests/studies/support`` for
``studies/support``), and no two test files share a basename (the test folders are not
packages, so pytest needs rootdir-unique module names)."""

from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TESTS = ROOT / "tests"
#: Folders of test data and fixtures, not of tests.
NOT_MIRRORS = ("data",)


def _test_folders() -> list[Path]:
    return sorted(d for d in TESTS.rglob("*") if d.is_dir() and d.name != "__pycache__"
                  and d.relative_to(TESTS).parts[0] not in NOT_MIRRORS)


def test_each_test_folder_mirrors_a_package_folder():
    folders = _test_folders()
    assert {"irl/methods", "irl/planning", "irl/domains/merge", "sim/runtime"} <= {
        d.relative_to(TESTS).as_posix() for d in folders}
    missing = [d.relative_to(TESTS).as_posix() for d in folders
               if not (ROOT / d.relative_to(TESTS) / "__init__.py").is_file()]
    assert missing == []


def test_test_basenames_are_unique():
    names = Counter(p.name for p in TESTS.rglob("test_*.py"))
    assert [n for n, k in names.items() if k > 1] == []
