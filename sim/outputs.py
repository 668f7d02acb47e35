"""Atomic file output: write to a hidden temporary name in the same folder, then ``os.replace``.

A crashed or killed run therefore leaves either the previous complete file, no file, or a
hidden ``.NAME.tmp-PID`` file, never a truncated file under the final name.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

import pandas as pd


def _tmp_name(path: Path) -> Path:
    return path.with_name(f".{path.name}.tmp-{os.getpid()}")


def write_atomic(path: str | Path, writer: Callable[[Path], object]) -> Path:
    """Call ``writer(tmp_path)`` and move the result to ``path``; the temp file is removed on error."""
    path = Path(path)
    tmp = _tmp_name(path)
    try:
        writer(tmp)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


def write_parquet(table: pd.DataFrame, path: str | Path) -> Path:
    """``table`` to Parquet at ``path``, atomically."""
    return write_atomic(path, lambda p: table.to_parquet(p, index=False))


def write_text(text: str, path: str | Path) -> Path:
    """``text`` (UTF-8) to ``path``, atomically."""
    return write_atomic(path, lambda p: Path(p).write_text(text, encoding="utf-8"))
