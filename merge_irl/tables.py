"""Reading a table from a path: a Parquet file, a Parquet dataset folder, or a CSV file.

A *Parquet dataset folder* is what dask, Spark, pyarrow or pandas (``to_parquet(partition_cols=
...)``) write for one table: part files (``part.0.parquet``, ``part-00000-<id>.snappy.parquet``,
``<id>-0.parquet``), possibly in hive partition folders (``encounter_id=3/``) whose names carry a
column's value, beside bookkeeping files (``_SUCCESS``, ``_metadata``, ``.crc``) that are skipped.
:func:`read_table` reads the part files in natural order of their paths (``part.2`` before
``part.10``, ``encounter_id=2/`` before ``encounter_id=10/``) and adds the partition columns back
(integers as int64, other values as strings), so a table written sorted by its partition column
reads back in its order.

Every reader of a table in the project reads through :func:`read_table` (encounter tables,
trajectory tables, decision logs); the caller passes its own error class, as with
:mod:`merge_irl.json_file`.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import pandas as pd

#: Suffixes of a Parquet file.
PARQUET_SUFFIXES = (".parquet", ".pq")

_DIGITS = re.compile(r"(\d+)")


def _natural(path: Path) -> tuple:
    return tuple(tuple(int(p) if p.isdigit() else p for p in _DIGITS.split(part)) for part in path.parts)


def _skipped(part: str) -> bool:
    """Bookkeeping names of dataset writers: ``_SUCCESS``, ``_metadata``, ``.part.crc``."""
    return part.startswith(("_", "."))


def parquet_parts(folder: str | os.PathLike) -> list[Path]:
    """The part files of the Parquet dataset folder ``folder`` (relative to it), in natural
    order; empty when ``folder`` is no folder or holds no ``*.parquet`` / ``*.pq`` file."""
    folder = Path(folder)
    if not folder.is_dir():
        return []
    parts = [p.relative_to(folder) for p in folder.rglob("*")
             if p.suffix.lower() in PARQUET_SUFFIXES and p.is_file()]
    return sorted((p for p in parts if not any(_skipped(s) for s in p.parts)), key=_natural)


def is_parquet_dataset(path: str | os.PathLike) -> bool:
    """Whether ``path`` is a folder of the part files of one table (:func:`parquet_parts`): all of
    them readable Parquet with the same columns. A folder of different tables (a run folder's
    ``encounters.parquet`` beside its ``trajectories.parquet``) is not one."""
    import pyarrow.parquet as pq

    parts = parquet_parts(path)
    if not parts:
        return False
    try:
        names = {tuple(pq.read_schema(Path(path) / p).names) for p in parts}
    except Exception:  # pyarrow raises several types for a file that is not Parquet
        return False
    return len(names) == 1


def is_parquet(path: str | os.PathLike) -> bool:
    """Whether ``path`` is read as Parquet: a ``.parquet`` / ``.pq`` file or a dataset folder."""
    path = Path(path)
    return path.suffix.lower() in PARQUET_SUFFIXES if not path.is_dir() else is_parquet_dataset(path)


def _dataset(folder: Path, error: type[Exception]):
    import pyarrow.dataset as pads

    parts = parquet_parts(folder)
    if not is_parquet_dataset(folder):
        raise error(f"{folder}: a folder, not a table file or a Parquet dataset folder (part files of one "
                    "table, all with the same columns)")
    return pads.dataset([str(folder / p) for p in parts], format="parquet", partitioning="hive",
                        partition_base_dir=str(folder))


def table_columns(path: str | os.PathLike, *, error: type[Exception] = ValueError) -> list[str]:
    """The column names of the table at ``path`` (Parquet file or dataset folder: from the schema;
    CSV: the header), without reading its rows.

    Raises:
        error: a folder without Parquet part files.
    """
    import pyarrow.parquet as pq

    path = Path(path)
    if path.is_dir():
        return list(_dataset(path, error).schema.names)
    if path.suffix.lower() in PARQUET_SUFFIXES:
        return list(pq.read_schema(path).names)
    return list(pd.read_csv(path, nrows=0).columns)


def read_table(path: str | os.PathLike, *, columns: list[str] | None = None,
               error: type[Exception] = ValueError) -> pd.DataFrame:
    """The table at ``path``: a Parquet file (``.parquet``/``.pq``), a Parquet dataset folder
    (see the module docstring) or a CSV file (any other suffix).

    Args:
        path: the file or folder.
        columns: read only these columns (None: all).
        error: the exception class raised for a folder without Parquet part files.

    Returns:
        The table, rows in file order (a dataset folder: its part files in natural order, partition
        columns last).

    Raises:
        error: a folder without Parquet part files.
        Whatever pandas / pyarrow raise for an unreadable file (callers turn it into one line).
    """
    path = Path(path)
    if path.is_dir():
        import pyarrow as pa

        table = _dataset(path, error).to_table(columns=columns)
        keys = {s.split("=", 1)[0] for p in parquet_parts(path) for s in p.parts[:-1] if "=" in s}
        for i, field in enumerate(table.schema):
            if field.name not in keys:
                continue
            kind = field.type.value_type if pa.types.is_dictionary(field.type) else field.type
            kind = pa.int64() if pa.types.is_integer(kind) else kind  # hive values: int64 or strings
            table = table.set_column(i, field.name, table.column(i).cast(kind))
        return table.to_pandas()
    if path.suffix.lower() in PARQUET_SUFFIXES:
        return pd.read_parquet(path, columns=columns)
    return pd.read_csv(path, usecols=columns)
