"""Code and docs say what they mean: no issue numbers and no citations of the design or
reference notes (files users do not have). Each such mention states the fact or target itself."""

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TREES = ("merge_irl", "sim", "irl", "scenarios", "analysis", "benchmarks", "studies", "tools", "tests", "docs",
         "README.md")
SUFFIXES = {".py", ".md", ".toml", ".txt", ".rst", ".cfg", ".ini", ".yaml", ".yml", ".sh"}
#: Written in pieces so that this file does not match itself.
CITATION = re.compile(r"\b[Ii]ssues?[ -]#?\d+|\b" + "DESIGN" + r"\.md\b|\b" + "REFERENCE" + r"\.md\b")


def _files() -> list[Path]:
    out = []
    for tree in TREES:
        path = ROOT / tree
        if path.is_file():
            out.append(path)
            continue
        out += [p for p in sorted(path.rglob("*")) if p.is_file() and p.suffix in SUFFIXES
                and "_build" not in p.relative_to(ROOT).parts and "__pycache__" not in p.parts]
    return out


def _citations(text: str) -> list[tuple[int, str]]:
    return [(n, m.group()) for n, line in enumerate(text.splitlines(), 1) for m in CITATION.finditer(line)]


def test_the_pattern_catches_each_form():
    text = "a\ni@ 14's target\n(I@ 29, item 6)\nthe i@-11 fields\ni@ #3\nsee DESIGN%md\nREFERENCE%md 2\ni@s 11 and 14\n"
    text = text.replace("@", "ssue").replace("%", ".")  # "@" and "%" keep this file free of the pattern
    assert [n for n, _ in _citations(text)] == [2, 3, 4, 5, 6, 7, 8]
    assert _citations("the tissue 4 layers; an issue is filed; DESIGN notes; reference.md") == []


def test_no_issue_numbers_or_note_citations():
    files = _files()
    assert len(files) > 300 and ROOT / "docs" / "changelog.md" in files  # the walk reads the trees, the log too
    found = [f"{p.relative_to(ROOT).as_posix()}:{n}: {hit}" for p in files
             for n, hit in _citations(p.read_text(encoding="utf-8", errors="replace"))]
    assert found == [], "say what the issue or note said instead:\n" + "\n".join(found)
