"""docs/architecture.md is the map of the code: its Folders block names every package folder of
ours, and every module of a folder on that folder's lines."""

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("merge_irl", "sim", "irl", "scenarios", "analysis")


def _folders_block() -> dict[str, str]:
    text = (ROOT / "docs" / "architecture.md").read_text(encoding="utf-8")
    block = text.split("## Folders", 1)[1].split("```", 2)[1]
    out: dict[str, str] = {}
    current = None
    for line in block.splitlines():
        m = re.match(r"^([a-z_]+(?:/[a-z_]+)*/)\s", line + " ")
        if m and not line.startswith(" "):
            current = m.group(1).rstrip("/")
            out[current] = line[len(m.group(1)):]
        elif current is not None:
            out[current] += " " + line.strip()
    return out


def _package_folders() -> dict[str, list[str]]:
    out = {}
    for pkg in PACKAGES:
        for init in sorted((ROOT / pkg).rglob("__init__.py")):
            folder = init.parent
            rel = folder.relative_to(ROOT).as_posix()
            out[rel] = sorted(p.stem for p in folder.glob("*.py") if p.stem != "__init__")
    return out


def test_every_folder_is_on_the_map():
    block = _folders_block()
    missing = sorted(set(_package_folders()) - set(block))
    assert missing == [], f"folders not in docs/architecture.md's Folders block: {missing}"


def test_every_module_is_named_on_its_folders_lines():
    block = _folders_block()
    missing = {}
    for folder, modules in _package_folders().items():
        words = set(re.findall(r"[A-Za-z_]+", block.get(folder, "")))
        gone = [m for m in modules if m not in words]
        if gone:
            missing[folder] = gone
    assert missing == {}


def test_the_map_names_no_folder_that_is_gone():
    block = _folders_block()
    ghosts = sorted(f for f in block if f.split("/")[0] in PACKAGES and not (ROOT / f).is_dir())
    assert ghosts == []
