"""Provenance of an output: which code, which SUMO and which input files made it.

Every result file the CLI writes (``model.json``, ``metrics.json``, ``report.md``,
``summary.md``, ``sweep.csv``) carries the record :func:`provenance` builds::

    {"merge_irl": "0.1.0",              # installed package version
     "sumo": "1.28.0",                  # installed libsumo version (None if not installed)
     "git_commit": "8cda119...",        # only when the code runs from a git checkout
     "git_dirty": false,                # ditto: tracked files differ from that commit
     "inputs": {"demos": {"path": "enc.parquet", "sha256": "..."}},
     "models": {"qavg": {"path": "models/qavg.json", "sha256": "..."}, "sumo": null},
     # only when a policy loads files the user named (evaluate --policy-weights, --policy-vecnormalize)
     "policy_files": {"ppo": {"weights": {"path": "ppo.zip", "sha256": "..."},
                              "vecnormalize": {"path": "vn.pkl", "sha256": "..."}}}}

The record is a pure function of the code, the installed packages and the input files'
contents: two identical runs write it byte for byte the same. Wall-clock times are kept out of
results for the same reason; :func:`write_timings` puts them in a file of their own
(:func:`timings_path`), so results can be compared by hash.

Versions come from the installed distributions' metadata (``importlib.metadata``): importing
libsumo would cost about 0.8 s, which ``merge-irl --version`` should not pay.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.metadata
import os
import subprocess
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from merge_irl.atomic import write_json_atomic

#: The distribution name of this package.
DISTRIBUTION = "merge-irl"
#: Distributions whose version is the SUMO version, in order of preference.
SUMO_DISTRIBUTIONS = ("libsumo", "eclipse-sumo")
#: Root of the source tree (the folder holding ``analysis/``, ``irl/``, ...).
SOURCE_ROOT = Path(__file__).resolve().parent.parent
_CHUNK = 1 << 20


def package_version() -> str:
    """The installed ``merge-irl`` version, or ``"unknown"`` when it is not installed."""
    try:
        return importlib.metadata.version(DISTRIBUTION)
    except importlib.metadata.PackageNotFoundError:
        return "unknown"


def sumo_version() -> str | None:
    """The installed SUMO version (of the ``libsumo`` wheel, else ``eclipse-sumo``), or None.

    Read from package metadata; libsumo is not imported.
    """
    for dist in SUMO_DISTRIBUTIONS:
        try:
            return importlib.metadata.version(dist)
        except importlib.metadata.PackageNotFoundError:
            continue
    return None


@functools.lru_cache(maxsize=4)
def git_state(root: str | os.PathLike = SOURCE_ROOT) -> tuple[str, bool] | None:
    """``(commit, dirty)`` of the git checkout whose top folder is ``root``, or None.

    None when ``root`` is not the top of a git work tree (e.g. an installed wheel, even one
    inside some other repository), or when git is not installed. ``dirty``: tracked files
    differ from the commit (untracked files are ignored). Cached per process.
    """
    root = Path(root).resolve()

    def git(*args: str) -> str | None:
        try:
            r = subprocess.run(["git", "-C", str(root), *args], capture_output=True, text=True, timeout=20, check=False)
        except (OSError, subprocess.SubprocessError):
            return None
        return r.stdout.strip() if r.returncode == 0 else None

    top = git("rev-parse", "--show-toplevel")
    if top is None or Path(top).resolve() != root:
        return None
    commit = git("rev-parse", "HEAD")
    if not commit:
        return None
    status = git("status", "--porcelain", "--untracked-files=no")
    return commit, bool(status)


def file_sha256(path: str | os.PathLike) -> str:
    """Hex SHA-256 of a file's bytes.

    Raises:
        OSError: the file cannot be read.
    """
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while block := f.read(_CHUNK):
            h.update(block)
    return h.hexdigest()


def path_digest(path: str | os.PathLike) -> dict[str, Any]:
    """``{"path", "sha256"}`` of a file; of a folder, also ``"files"`` (how many).

    A folder's digest is the SHA-256 of the lines ``<relative path> <file sha256>`` of every
    file under it (recursively, sorted by relative path, ``/`` separators), so it changes when
    any file's name or content does.

    Raises:
        FileNotFoundError: ``path`` does not exist.
        OSError: a file cannot be read.
    """
    p = Path(path)
    if p.is_dir():
        files = sorted((f for f in p.rglob("*") if f.is_file()), key=lambda f: f.relative_to(p).as_posix())
        h = hashlib.sha256()
        for f in files:
            h.update(f"{f.relative_to(p).as_posix()} {file_sha256(f)}\n".encode())
        return {"path": str(path), "sha256": h.hexdigest(), "files": len(files)}
    if not p.exists():
        raise FileNotFoundError(f"{p}: no such input file")
    return {"path": str(path), "sha256": file_sha256(p)}


def text_digest(text: str) -> str:
    """Hex SHA-256 of ``text`` in UTF-8 (e.g. the TOML of the scenario actually simulated)."""
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def provenance(
    inputs: Mapping[str, str | os.PathLike | None] | None = None,
    models: Mapping[str, str | os.PathLike | None] | None = None,
    *,
    policy_files: Mapping[str, Mapping[str, str | os.PathLike]] | None = None,
    extra: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """The provenance record of an output (see the module docstring).

    Args:
        inputs: role -> path of each input file or folder the command read (None entries are
            left out); each becomes :func:`path_digest`.
        models: policy name -> its model file (digested like ``inputs``), or None for a policy
            without one (the SUMO and uniform baselines, a model passed as an object).
        policy_files: policy name -> role (``"weights"``, ``"vecnormalize"``, ...) -> a file the
            policy loads besides its model or module (its weights, its normalisation statistics),
            digested like ``inputs``; left out when empty.
        extra: further JSON-ready entries (e.g. ``{"scenario_sha256": ...}``), merged last.

    Raises:
        FileNotFoundError: an input or model path does not exist.
    """
    record: dict[str, Any] = {"merge_irl": package_version(), "sumo": sumo_version()}
    state = git_state()
    if state is not None:
        record["git_commit"], record["git_dirty"] = state
    record["inputs"] = {k: path_digest(v) for k, v in (inputs or {}).items() if v is not None}
    if models is not None:
        record["models"] = {k: None if v is None else path_digest(v) for k, v in models.items()}
    loads = {name: {role: path_digest(f) for role, f in files.items()} for name, files in (policy_files or {}).items()
             if files}
    if loads:
        record["policy_files"] = loads
    record.update(extra or {})
    return record


def version_line() -> str:
    """``merge-irl 0.1.0 (SUMO 1.28.0, git 8cda1190a5c3)`` for ``merge-irl --version``."""
    parts = [f"SUMO {sumo_version() or 'not installed'}"]
    state = git_state()
    if state is not None:
        parts.append(f"git {state[0][:12]}{' + local changes' if state[1] else ''}")
    return f"merge-irl {package_version()} ({', '.join(parts)})"


def provenance_markdown(record: Mapping[str, Any]) -> str:
    """A short Markdown section listing ``record`` (for ``report.md`` and ``summary.md``)."""
    lines = ["## Provenance", "", f"- merge-irl {record.get('merge_irl')}, SUMO {record.get('sumo')}"]
    if "git_commit" in record:
        lines.append(f"- git commit {record['git_commit']}{' (with local changes)' if record.get('git_dirty') else ''}")
    for role, d in record.get("inputs", {}).items():
        lines.append(f"- input {role}: `{d['path']}` sha256 {d['sha256']}")
    for name, d in (record.get("models") or {}).items():
        lines.append(f"- policy {name}: " + ("no model file" if d is None else f"`{d['path']}` sha256 {d['sha256']}"))
    for name, files in (record.get("policy_files") or {}).items():
        for role, d in files.items():
            lines.append(f"- policy {name} loads {role}: `{d['path']}` sha256 {d['sha256']}")
    for key, value in record.items():
        if key not in ("merge_irl", "sumo", "git_commit", "git_dirty", "inputs", "models", "policy_files"):
            lines.append(f"- {key}: {value}")
    return "\n".join(lines)


def timings_path(output: str | os.PathLike) -> Path:
    """Where the wall-clock times of ``output`` go: ``model.json`` -> ``model.timings.json``;
    a folder -> ``<folder>/timings.json``."""
    p = Path(output)
    if p.is_dir():
        return p / "timings.json"
    return p.with_name(f"{p.stem}.timings.json")


def write_timings(output: str | os.PathLike, timings: Mapping[str, Any]) -> Path:
    """Write ``timings`` (seconds, JSON-ready) next to ``output`` (see :func:`timings_path`),
    atomically; returns the path written.

    Raises:
        OSError: the file cannot be written.
    """
    return write_json_atomic(timings_path(output), dict(timings))
