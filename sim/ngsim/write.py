"""Write a trajectory table in NGSIM's exact CSV text format.

The output is what NGSIM's ``trajectories-*.csv`` files look like: the header line of
:data:`sim.ngsim.format.NGSIM_HEADER`, the 18 columns in schema order, rows sorted by
``(Vehicle_ID, Frame_ID)``, integers as integers and floats with NGSIM's fixed number of
decimals (:data:`sim.ngsim.format.DECIMALS`). ``precision="exact"`` writes the shortest
round-trip representation of every float instead (bit-exact round trip).

Formatting is vectorised with pyarrow (a few million values per second per column) and the
file is written atomically (temporary file in the same directory, then ``os.replace``).
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path
from typing import Literal

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.csv as pacsv

from merge_irl.atomic import write_atomic
from sim.errors import TrajectoryFormatError
from sim.ngsim.format import DECIMALS, NGSIM_COLUMNS, NGSIM_HEADER
from sim.runtime.schema import COLUMNS, conform, sort_table

Precision = Literal["ngsim", "exact"]

_ROWS_PER_BLOCK = 500_000


def quantize_ngsim(table: pd.DataFrame) -> pd.DataFrame:
    """The table as NGSIM's text format stores it: floats rounded to :data:`DECIMALS`.

    Reading back a file written by :func:`write_ngsim_csv` (``precision="ngsim"``) gives
    exactly ``sort_table(quantize_ngsim(table))``.
    """
    out = conform(table).copy()
    for col, d in DECIMALS.items():
        scale = 10.0**d
        out[col] = np.rint(out[col].to_numpy() * scale) / scale
    return out


def _fixed(values: np.ndarray, decimals: int) -> pa.Array:
    """float64[N] -> N strings with exactly ``decimals`` decimals (round half to even)."""
    scale = 10**decimals
    q = np.rint(values * scale).astype(np.int64)
    neg = q < 0
    a = np.abs(q)
    ip = pc.cast(pa.array(a // scale), pa.string())
    fp = pc.utf8_lpad(pc.cast(pa.array(a % scale), pa.string()), decimals, "0")
    s = pc.binary_join_element_wise(ip, fp, ".")
    if neg.any():
        s = pc.if_else(pa.array(neg), pc.binary_join_element_wise(pa.scalar("-"), s, ""), s)
    return s


def _format_block(block: pd.DataFrame, precision: Precision) -> pa.Table:
    cols: dict[str, pa.Array] = {}
    for c in NGSIM_COLUMNS:
        v = block[c].to_numpy(dtype=COLUMNS[c])
        if COLUMNS[c] == "int64":
            cols[c] = pa.array(v)
        elif precision == "exact":
            cols[c] = pc.cast(pa.array(v), pa.string())
        else:
            cols[c] = _fixed(v, DECIMALS[c])
    return pa.table(cols)


def write_ngsim_csv_blocks(
    blocks: Iterable[pd.DataFrame], path: str | os.PathLike, *, precision: Precision = "ngsim"
) -> Path:
    """Write a large table given as consecutive blocks (each in schema, each already in NGSIM's
    order and following the previous one in that order), streaming; atomic like
    :func:`write_ngsim_csv`. For files too big to hold as one table (benchmarks)."""
    return _write_blocks((_format_block(conform(b), precision) for b in blocks), Path(path))


def write_ngsim_csv(
    table: pd.DataFrame, path: str | os.PathLike, *, precision: Precision = "ngsim"
) -> Path:
    """Write ``table`` (trajectory schema) to ``path`` in NGSIM's CSV format; returns the path.

    Args:
        table: a trajectory table (``sim.runtime.schema.COLUMNS``; extra columns are ignored).
        path: output file; its directory must exist. Written atomically.
        precision: ``"ngsim"`` (NGSIM's decimals, see :func:`quantize_ngsim`) or ``"exact"``
            (shortest round-trip float text).

    Raises:
        TrajectoryFormatError: ``table`` lacks schema columns or has non-finite values.
    """
    path = Path(path)
    if precision not in ("ngsim", "exact"):
        raise ValueError(f"precision must be 'ngsim' or 'exact', got {precision!r}")
    try:
        t = sort_table(conform(table))
    except (KeyError, ValueError, TypeError) as e:
        raise TrajectoryFormatError(f"cannot write {path}: {e}") from e
    floats = [c for c in NGSIM_COLUMNS if COLUMNS[c] == "float64"]
    bad = ~np.isfinite(t[floats].to_numpy())
    if bad.any():
        r, c = np.argwhere(bad)[0]
        raise TrajectoryFormatError(
            f"cannot write {path}: column {floats[c]} row {r} is {t[floats[c]].iloc[r]}; "
            "NGSIM files hold finite numbers only"
        )
    blocks = (_format_block(t.iloc[start : start + _ROWS_PER_BLOCK], precision)
              for start in range(0, len(t), _ROWS_PER_BLOCK))
    return _write_blocks(blocks, path)


def _write_blocks(blocks: Iterable[pa.Table], path: Path) -> Path:
    """The header line, then each formatted block, streamed into ``path`` atomically."""

    def write(tmp: Path) -> None:
        with open(tmp, "wb") as fh:
            fh.write((NGSIM_HEADER + "\n").encode())
            opts = pacsv.WriteOptions(include_header=False, quoting_style="none")
            for block in blocks:
                pacsv.write_csv(block, fh, opts)

    return write_atomic(path, write)
