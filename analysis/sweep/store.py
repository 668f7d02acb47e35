"""Resumable result storage: one JSON file per finished task, written atomically."""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
from pathlib import Path
from typing import Any

from merge_irl.atomic import write_json_atomic
from merge_irl.run_folder import remove_temporaries

#: Dataclass field metadata that leaves a field out of the task digest (e.g. an absolute output
#: path, so that a sweep folder moved elsewhere still finds its finished tasks).
NOT_IN_DIGEST = {"digest": False}


def _canonical(value: Any) -> Any:
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {"__type__": type(value).__qualname__, **{
            f.name: _canonical(getattr(value, f.name)) for f in dataclasses.fields(value)
            if f.metadata.get("digest", True)}}
    if isinstance(value, dict):
        return {str(k): _canonical(v) for k, v in sorted(value.items(), key=lambda kv: str(kv[0]))}
    if isinstance(value, (list, tuple)):
        return [_canonical(v) for v in value]
    if isinstance(value, Path):
        return str(value)
    if hasattr(value, "tolist"):  # numpy scalars and arrays
        return value.tolist()
    return value


def task_digest(func_name: str, config: Any, seed: int) -> str:
    """Hex digest identifying a task by its function, full config and seed (dataclass fields
    marked :data:`NOT_IN_DIGEST` left out)."""
    payload = json.dumps(
        {"func": func_name, "config": _canonical(config), "seed": int(seed)},
        sort_keys=True, default=str,
    )
    return hashlib.sha256(payload.encode("utf-8")).hexdigest()[:32]


class ResultStore:
    """A directory of finished task results, ``<digest>.json``.

    A file is only ever created by an atomic rename of a complete temporary file, so a sweep
    killed midway never leaves a truncated result that reads as complete; a file that does not
    parse is treated as missing (and reported by :meth:`get` returning ``None``).
    """

    def __init__(self, root: str | os.PathLike, *, create: bool = True) -> None:
        """``create``: make the folder (and its parents) if missing; False: only read (:meth:`get`
        finds nothing in a missing folder)."""
        self.root = Path(root)
        if create:
            self.root.mkdir(parents=True, exist_ok=True)

    def remove_temporaries(self) -> int:
        """Remove hidden temporary files left by writes that were killed; returns how many.
        Only while no other process writes into this store (e.g. under the sweep's lock)."""
        return len(remove_temporaries(self.root))

    def path(self, digest: str) -> Path:
        return self.root / f"{digest}.json"

    def get(self, digest: str) -> dict[str, Any] | None:
        p = self.path(digest)
        try:
            data = json.loads(p.read_text())
        except (FileNotFoundError, json.JSONDecodeError, UnicodeDecodeError):
            return None
        if not isinstance(data, dict) or "result" not in data:
            return None
        return data

    def put(self, digest: str, record: dict[str, Any]) -> Path:
        return write_json_atomic(self.path(digest), record, indent=None)
