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


def release_freed_memory() -> None:
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


_VEH = int(np.flatnonzero(_INT_POS == NGSIM_COLUMNS.index("Vehicle_ID"))[0])
_FRAME = int(np.flatnonzero(_INT_POS == NGSIM_COLUMNS.index("Frame_ID"))[0])


def in_order(vehicle: np.ndarray, frame: np.ndarray) -> bool:
    """Whether rows ``[N]`` are sorted by (vehicle, frame), strictly."""
    if len(vehicle) < 2:
        return True
    return bool(np.all((vehicle[1:] > vehicle[:-1]) | ((vehicle[1:] == vehicle[:-1]) & (frame[1:] > frame[:-1]))))


def permute_rows(block: np.ndarray, order: np.ndarray) -> None:
    """Reorder the columns of a ``[m, N]`` block by ``order [N]`` one row at a time, in place:
    a row's worth of memory more, not a second block."""
    for r in range(block.shape[0]):
        block[r] = block[r][order]


def _sort_in_place(fblock: np.ndarray, iblock: np.ndarray) -> None:
    """Sort the table's blocks by (Vehicle_ID, Frame_ID) in place (a file whose vehicles come in
    any order, each vehicle's rows together and in frame order), stable."""
    veh, frame = iblock[_VEH], iblock[_FRAME]
    if in_order(veh, frame):
        return
    order = np.lexsort((frame, veh))
    permute_rows(fblock, order)
    permute_rows(iblock, order)


def assemble(parts: list[np.ndarray]) -> pd.DataFrame:
    """Move the kept chunks (float64[18, k] each; the list is emptied) into the table's two
    column blocks, freeing each chunk as it is copied, and sort them by (Vehicle_ID, Frame_ID) in
    place: peak memory ~ the table plus a few chunks."""
    release_freed_memory()  # heap left over from parsing and validating
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
            release_freed_memory()
    _sort_in_place(fblock, iblock)
    return _frame(fblock, iblock)


def table_in_place(data: np.ndarray) -> pd.DataFrame:
    """The table over ``data`` (float64[18, N] in NGSIM's column order, sorted, integral values in
    the integer columns; consumed: its memory becomes the table's), with no second copy: the rows
    are reordered in place (float columns first), the integer rows converted to int64 in place
    (both 8 bytes) and the two blocks are views of ``data``. Peak memory: ``data`` plus a row."""
    _reorder_rows(data, np.concatenate([_FLOAT_POS, _INT_POS]))
    nf = len(_FLOAT_POS)
    for r in range(nf, data.shape[0]):
        data[r].view(np.int64)[:] = data[r].astype(np.int64)
    return _frame(data[:nf], data[nf:].view(np.int64))


def _reorder_rows(a: np.ndarray, perm: np.ndarray) -> None:
    """``a[i] = a[perm[i]]`` for every row at once, in place (cycle by cycle, one row held)."""
    done = np.zeros(len(perm), dtype=bool)
    tmp = np.empty(a.shape[1], dtype=a.dtype)
    for start in range(len(perm)):
        if done[start]:
            continue
        tmp[:] = a[start]
        i = start
        while True:
            done[i] = True
            j = int(perm[i])
            if j == start:
                a[i] = tmp
                break
            a[i] = a[j]
            i = j


def _frame(fblock: np.ndarray, iblock: np.ndarray) -> pd.DataFrame:
    """The table of the float64 ``[10, N]`` and int64 ``[8, N]`` column blocks (no copy where
    pandas allows)."""
    n = fblock.shape[1]
    try:
        from pandas.api.internals import create_dataframe_from_blocks
    except ImportError:  # pandas < 2.3: the constructor copies once more
        cols = {NGSIM_COLUMNS[j]: fblock[i] for i, j in enumerate(_FLOAT_POS)}
        cols.update({NGSIM_COLUMNS[j]: iblock[i] for i, j in enumerate(_INT_POS)})
        return pd.DataFrame({c: cols[c] for c in NGSIM_COLUMNS})
    return create_dataframe_from_blocks(
        [(fblock, _FLOAT_POS), (iblock, _INT_POS)], index=pd.RangeIndex(n), columns=pd.Index(NGSIM_COLUMNS),
    )
