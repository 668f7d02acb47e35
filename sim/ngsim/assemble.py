"""Building the trajectory table from the rows :func:`sim.ngsim.read.read_ngsim` kept: the
chunks are moved into the table's two column blocks (float64, int64), freeing each as it is
copied, so peak memory stays near the table's own size."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pandas as pd

from sim.ngsim.format import NGSIM_COLUMNS
from sim.runtime.schema import COLUMNS

_FLOAT_POS = np.array([j for j, c in enumerate(NGSIM_COLUMNS) if COLUMNS[c] == "float64"])
_INT_POS = np.array([j for j, c in enumerate(NGSIM_COLUMNS) if COLUMNS[c] == "int64"])


def _release_freed_memory() -> None:
    """Give freed heap memory back to the OS (glibc ``malloc_trim``; no-op elsewhere).

    The kept chunks are a few MB each: glibc's adaptive mmap threshold puts such arrays on the
    heap, whose freed pages otherwise stay resident while the table's blocks are allocated."""
    global _MALLOC_TRIM
    if _MALLOC_TRIM is None:
        try:
            import ctypes

            _MALLOC_TRIM = ctypes.CDLL("libc.so.6").malloc_trim
        except (OSError, AttributeError):
            _MALLOC_TRIM = False
    if callable(_MALLOC_TRIM):
        _MALLOC_TRIM(0)


_MALLOC_TRIM: Callable[[int], int] | bool | None = None  # None: not looked up yet


def assemble(parts: list[np.ndarray]) -> pd.DataFrame:
    """Move the kept chunks (float64[18, k] each; the list is emptied) into the table's two
    column blocks, freeing each chunk as it is copied: peak memory ~ the table plus a few chunks."""
    _release_freed_memory()  # heap left over from parsing and validating
    n = sum(p.shape[1] for p in parts)
    fblock = np.empty((len(_FLOAT_POS), n), dtype=np.float64)
    iblock = np.empty((len(_INT_POS), n), dtype=np.int64)
    at = 0
    parts.reverse()
    while parts:
        p = parts.pop()
        k = p.shape[1]
        for i, j in enumerate(_FLOAT_POS):
            fblock[i, at:at + k] = p[j]
        for i, j in enumerate(_INT_POS):
            iblock[i, at:at + k] = p[j]
        at += k
        del p
        if len(parts) % 8 == 0:
            _release_freed_memory()
    try:
        from pandas.api.internals import create_dataframe_from_blocks
    except ImportError:  # pandas < 2.3: the constructor copies once more
        cols = {NGSIM_COLUMNS[j]: fblock[i] for i, j in enumerate(_FLOAT_POS)}
        cols.update({NGSIM_COLUMNS[j]: iblock[i] for i, j in enumerate(_INT_POS)})
        return pd.DataFrame({c: cols[c] for c in NGSIM_COLUMNS})
    return create_dataframe_from_blocks(
        [(fblock, _FLOAT_POS), (iblock, _INT_POS)], index=pd.RangeIndex(n), columns=pd.Index(NGSIM_COLUMNS),
    )
