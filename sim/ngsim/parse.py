"""Parsing an NGSIM trajectory file for :func:`sim.ngsim.read.read_ngsim`: its layout (sniffed
from the first lines: comma-separated with or without a header, or whitespace-separated; text
encoding from the byte-order mark), line reading of bounded length, the streaming chunk parser
(pyarrow for ``.csv``, pandas for ``.txt``), and locating the first unparsable line."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.csv as pacsv

from sim.errors import TrajectoryFormatError
from sim.ngsim.format import NGSIM_COLUMNS, canonical_name


@dataclass(frozen=True)
class Layout:
    """How a file is laid out, as sniffed from its first lines (:func:`sniff`)."""

    kind: str  # "csv" | "txt"
    names: tuple[str, ...]  # all columns of the file, canonical spelling
    header_lines: int
    bytes_per_row: float
    encoding: str = "utf-8"  # "utf-8-sig" when a UTF-8 byte-order mark starts the file


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


#: Byte-order marks -> the encoding they announce (longest first).
_BOMS: tuple[tuple[bytes, str], ...] = (
    (b"\xef\xbb\xbf", "utf-8-sig"), (b"\xff\xfe", "utf-16"), (b"\xfe\xff", "utf-16"),
)


def _encoding(path: Path) -> str:
    """The file's text encoding from its byte-order mark (Excel's "CSV UTF-8" writes one);
    UTF-8 without a mark."""
    with open(path, "rb") as fh:
        start = fh.read(4)
    for bom, enc in _BOMS:
        if start.startswith(bom):
            return enc
    return "utf-8"


#: Longest line (characters) read while sniffing or locating a bad line: NGSIM rows are a few
#: hundred; a longer "line" (a damaged or sparse file, binary data) is refused without reading
#: it whole, so the memory of error reporting stays bounded.
MAX_LINE_CHARS = 1 << 16


def _bounded_lines(fh, path: Path) -> Iterator[tuple[int, str]]:
    """``(line number, line)`` of a text file, each line read at most :data:`MAX_LINE_CHARS` long.

    Raises:
        TrajectoryFormatError: a line longer than that (named by number).
    """
    lineno = 0
    while True:
        line = fh.readline(MAX_LINE_CHARS + 1)
        if not line:
            return
        lineno += 1
        if len(line) > MAX_LINE_CHARS:
            raise TrajectoryFormatError(
                f"{path}: line {lineno}: longer than {MAX_LINE_CHARS} characters without a line end; "
                "expected NGSIM rows (a few hundred characters each): a damaged or binary file?")
        yield lineno, line


def sniff(path: Path) -> Layout:
    """The :class:`Layout` of ``path`` (CSV or whitespace text, columns, header lines, encoding),
    from its first 50 non-empty lines.

    Raises:
        TrajectoryFormatError: the file is empty, or its first lines are no NGSIM layout (naming the line).
    """
    encoding = _encoding(path)
    with open(path, encoding=encoding, errors="replace", newline="") as fh:
        head = [line for _, (_, line) in zip(range(50), _bounded_lines(fh, path))]
    head = [h for h in head if h.strip()]
    if not head:
        raise TrajectoryFormatError(f"{path}: line 1: the file is empty; expected NGSIM rows")
    if encoding == "utf-16":
        raise TrajectoryFormatError(
            f"{path}: line 1: the file is UTF-16 text (Excel's \"Unicode text\"); expected UTF-8 "
            "CSV: save it as \"CSV UTF-8 (comma delimited)\""
        )
    first = head[0]
    bpr = max(1.0, sum(len(h) for h in head[1:] or head) / max(1, len(head[1:] or head)))
    if "," in first:
        raw = first.rstrip("\r\n").split(",")
        fields = [canonical_name(f) for f in raw]
        if not all(_is_number(f) for f in fields):
            missing = [c for c in NGSIM_COLUMNS if c not in fields]
            if missing:
                raise TrajectoryFormatError(
                    f"{path}: line 1 (header): missing column(s) {missing}; expected NGSIM's "
                    f"columns {list(NGSIM_COLUMNS)}; the header has {fields}"
                )
            return Layout("csv", tuple(fields), 1, bpr, encoding)
        if len(fields) < len(NGSIM_COLUMNS):
            raise TrajectoryFormatError(
                f"{path}: line 1: {len(fields)} fields and no header; expected a header line or "
                f"the {len(NGSIM_COLUMNS)} NGSIM columns"
            )
        extra = tuple(f"extra_{i}" for i in range(len(fields) - len(NGSIM_COLUMNS)))
        return Layout("csv", NGSIM_COLUMNS + extra, 0, bpr, encoding)
    n = len(first.split())
    if n != len(NGSIM_COLUMNS):
        raise TrajectoryFormatError(
            f"{path}: line 1: {n} whitespace-separated fields; expected the {len(NGSIM_COLUMNS)} "
            f"NGSIM columns {list(NGSIM_COLUMNS)}"
        )
    return Layout("txt", NGSIM_COLUMNS, 0, bpr, encoding)


def locate_bad_line(path: Path, layout: Layout, start_line: int, cause: Exception) -> TrajectoryFormatError:
    """Error path: find the first unparsable line at or after ``start_line`` (1-based)."""
    idx = {c: layout.names.index(c) for c in NGSIM_COLUMNS}
    with open(path, encoding=layout.encoding, errors="replace") as fh:
        for lineno, line in _bounded_lines(fh, path):
            if lineno < start_line or lineno <= layout.header_lines or not line.strip():
                continue
            fields = line.rstrip("\r\n").split(",") if layout.kind == "csv" else line.split()
            if len(fields) != len(layout.names):
                return TrajectoryFormatError(
                    f"{path}: line {lineno}: {len(fields)} fields; expected {len(layout.names)}"
                )
            for c, i in idx.items():
                try:
                    float(fields[i])
                except ValueError:
                    what = "missing value" if not fields[i].strip() else f"value {fields[i]!r} is not a number"
                    return TrajectoryFormatError(
                        f"{path}: line {lineno}, column {c}: {what}; expected a number"
                    )
    return TrajectoryFormatError(f"{path}: unreadable NGSIM data after line {start_line}: {cause}")


#: Block size of pyarrow's streaming reader. It runs without threads (``use_threads=False``): with
#: them it reads blocks ahead while the main thread is busy, and on a busy machine a 2 GB file
#: without line ends reached a 5 GB peak; serial reading keeps the speed (0.45x pandas' with and
#: without threads, ``python -m benchmarks.ngsim_bench --size-mb 100``) and bounds the blocks held.
MAX_BLOCK_BYTES = 1 << 20


def location_column(layout: Layout) -> str | None:
    """The file's ``Location`` column (any case), if it has one."""
    for n in layout.names:
        if n.lower() == "location":
            return n
    return None


def iter_chunks(path: Path, layout: Layout, chunksize: int) -> Iterator[tuple[np.ndarray, np.ndarray | None]]:
    """Yield (float64[18, n], object[n] or None) pairs: one row per schema column, and the
    ``Location`` value of every row when the file has that column; in file order, n =
    ``chunksize`` except for the last. The arrays may be reused for the next chunk: copy what
    you keep."""
    cols = list(NGSIM_COLUMNS)
    loc = location_column(layout)
    if layout.kind == "csv":
        block = int(min(MAX_BLOCK_BYTES, max(1 << 12, chunksize * layout.bytes_per_row)))
        types = {c: pa.float64() for c in cols}
        if loc is not None:
            types[loc] = pa.string()
        reader = pacsv.open_csv(
            path,
            read_options=pacsv.ReadOptions(
                skip_rows=layout.header_lines, column_names=list(layout.names), block_size=block,
                encoding=layout.encoding, use_threads=False,
            ),
            parse_options=pacsv.ParseOptions(delimiter=","),
            convert_options=pacsv.ConvertOptions(
                include_columns=cols + ([loc] if loc is not None else []), column_types=types,
            ),
        )
        # batches (~5k rows) are copied straight into a reused chunk buffer, column by column
        buf = np.empty((len(cols), chunksize), dtype=np.float64)
        lbuf = np.empty(chunksize, dtype=object) if loc is not None else None
        n_buf = 0
        for batch in reader:
            at, m = 0, batch.num_rows
            arrays = [batch.column(j).to_numpy(zero_copy_only=False) for j in range(len(cols))]
            larr = batch.column(loc).to_numpy(zero_copy_only=False) if loc is not None else None
            while at < m:
                take = min(m - at, chunksize - n_buf)
                for j in range(len(cols)):
                    buf[j, n_buf:n_buf + take] = arrays[j][at:at + take]
                if lbuf is not None and larr is not None:
                    lbuf[n_buf:n_buf + take] = larr[at:at + take]
                n_buf += take
                at += take
                if n_buf == chunksize:
                    yield buf, lbuf
                    n_buf = 0
        if n_buf:
            yield buf[:, :n_buf], (lbuf[:n_buf] if lbuf is not None else None)
    else:
        it = pd.read_csv(
            path, sep=r"\s+", header=None, names=cols, dtype=np.float64,
            chunksize=chunksize, engine="c", encoding=layout.encoding,
        )
        for df in it:
            yield np.ascontiguousarray(df.to_numpy(dtype=np.float64).T), None
