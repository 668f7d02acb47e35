"""Parquet output of simulation tables, written atomically (see :mod:`merge_irl.atomic`)."""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from merge_irl.atomic import write_atomic


def write_parquet(table: pd.DataFrame, path: str | Path) -> Path:
    """``table`` to Parquet at ``path``, atomically (mode 0666 minus the umask)."""
    return write_atomic(path, lambda p: table.to_parquet(p, index=False))
