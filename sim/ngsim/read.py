"""Streaming reader of the public NGSIM vehicle-trajectory files into the trajectory table.

``read_ngsim(path)`` reads ``trajectories-*.csv`` (comma-separated, header line) with pyarrow's
streaming CSV reader, and the older header-less whitespace-separated ``.txt`` files with
pandas' chunked C parser. Either way only the 18 schema columns are parsed (extra columns are
dropped), all as float64 and then checked and cast to the schema dtypes, one chunk at a time:
memory is bounded by the chunk size plus the rows kept by the filters (``lanes``, ``frames``,
``vehicles``), whatever the file size.

Every defect is either an error or reported (:class:`NgsimReport`), never silent:

Errors (:class:`~sim.errors.TrajectoryFormatError`, naming file, line and column; nothing is
returned): missing columns (header); non-numeric or missing values; non-integral ids / frames /
lanes / classes; negative ``v_Length`` / ``v_Width``; frames out of order for a vehicle; a frame
repeated with different values; metric-looking units (mean vehicle length < 8 ft or width <
3.5 ft).

Reported and handled: exact duplicate rows (dropped), vehicles with gaps in their frames (kept;
counted), acceleration noise (rows at NGSIM's +-11.2 ft/s^2 cap, RMS jerk; optional smoothing,
see :mod:`sim.ngsim.smooth`).

Parsing the file (layout, chunks, bad lines): :mod:`sim.ngsim.parse`; building the table from
the kept rows: :mod:`sim.ngsim.assemble`.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa

from merge_irl.tables import PARQUET_SUFFIXES, read_table
from sim.errors import TrajectoryFormatError, out_of_memory
from sim.ngsim.assemble import assemble, permute_rows, release_freed_memory, table_in_place
from sim.ngsim.format import NGSIM_COLUMNS
from sim.ngsim.parse import iter_chunks, locate_bad_line, location_column, sniff
from sim.ngsim.recordings import RecordingTally, choose_location, choose_recording, normalise_location
from sim.ngsim.smooth import SmoothingConfig, jerk_rms, smooth_table
from sim.ngsim.validate import ChunkValidator, check_kinematic_units
from sim.runtime.schema import COLUMNS

_COL = {c: i for i, c in enumerate(NGSIM_COLUMNS)}
DEFAULT_CHUNKSIZE = 100_000  #: rows per chunk


@dataclass(frozen=True)
class NgsimReport:
    """What the reader found and did. Counts refer to the whole file unless marked *kept*."""

    path: str
    layout: str  #: "csv" (header, comma-separated) or "txt" (no header, whitespace)
    rows_read: int
    rows_kept: int  #: rows in the returned table (after dropping duplicates and filters)
    chunks: int
    duplicate_rows_dropped: int
    vehicles: int  #: distinct vehicles in the file
    vehicles_with_gaps: tuple[int, ...]  #: ids of vehicles whose frames skip (data kept)
    gap_events: int
    missing_frames: int
    max_gap_frames: int
    acc_saturated_rows: int  #: rows with ``|v_Acc|`` at NGSIM's 11.2 ft/s^2 cap
    jerk_rms_ft_s3: float  #: RMS jerk of the kept rows as read (acceleration noise)
    smoothing: str  #: "none" or the filter's description
    jerk_rms_smoothed_ft_s3: float | None
    extra_columns_dropped: tuple[str, ...]
    location: str | None = None  #: the site kept (``Location`` column), None: not selected
    recording: str = ""  #: the recording kept when the file holds several, described

    def summary(self) -> str:
        """A few human-readable lines."""
        lines = [
            f"{self.path} ({self.layout}): {self.rows_read} rows read in {self.chunks} chunks, "
            f"{self.rows_kept} kept, {self.vehicles} vehicles",
            f"  duplicate rows dropped: {self.duplicate_rows_dropped}",
            f"  vehicles with frame gaps: {len(self.vehicles_with_gaps)} ({self.gap_events} gaps, "
            f"{self.missing_frames} missing frames, longest {self.max_gap_frames})",
            f"  acceleration noise: {self.acc_saturated_rows} rows at the +-11.2 ft/s^2 cap, "
            f"RMS jerk {self.jerk_rms_ft_s3:.1f} ft/s^3",
            f"  smoothing: {self.smoothing}"
            + (f" (RMS jerk after {self.jerk_rms_smoothed_ft_s3:.1f} ft/s^3)"
               if self.jerk_rms_smoothed_ft_s3 is not None else ""),
        ]
        if self.location is not None or self.recording:
            lines.append(f"  recording kept: site {self.location or '-'} {self.recording}".rstrip())
        if self.extra_columns_dropped:
            lines.append(f"  extra columns dropped: {', '.join(self.extra_columns_dropped)}")
        return "\n".join(lines)


@dataclass(frozen=True)
class NgsimLoad:
    """A loaded file: the trajectory table (schema dtypes, sorted by vehicle and frame)."""

    table: pd.DataFrame
    report: NgsimReport


class _NeedsSorting(Exception):
    """The streaming (file-order) pass met rows it cannot check in file order."""


def read_ngsim(
    path: str | os.PathLike,
    *,
    location: str | None = None,
    recording: int | None = None,
    lanes: Iterable[int] | None = None,
    frames: tuple[int, int] | None = None,
    vehicles: Iterable[int] | None = None,
    chunksize: int = DEFAULT_CHUNKSIZE,
    smooth: bool | SmoothingConfig = False,
    progress: bool = False,
) -> NgsimLoad:
    """Load an NGSIM trajectory file (``.csv`` with header or whitespace ``.txt``).

    A file may hold several recordings (sites in a ``Location`` column, periods or days told
    apart by ``Global_Time``; see :mod:`sim.ngsim.recordings`): one is returned, the one
    ``location`` / ``recording`` select, and a file holding several is refused without them.
    Rows may come in any order (the newer public layout is unsorted): a file sorted by vehicle
    and frame is validated while streaming; otherwise the rows of the selected recording are
    held in memory, sorted and then validated.

    Args:
        path: the file.
        location: keep the rows whose ``Location`` is this site (case-insensitive, e.g.
            ``"i-80"``); required when the column holds several sites.
        recording: keep recording N (1-based, in Global_Time order); required when the
            (selected site of the) file holds several.
        lanes: keep only rows with these ``Lane_ID`` (e.g. ``(6, 7)``); None keeps all.
        frames: keep only ``first <= Frame_ID <= last``; None keeps all.
        vehicles: keep only these ``Vehicle_ID``; None keeps all.
        chunksize: rows parsed per chunk (memory bound; validation is streaming).
        smooth: True (default filter) or a :class:`~sim.ngsim.smooth.SmoothingConfig`: recompute ``Local_Y``,
            ``v_Vel`` and ``v_Acc`` from smoothed positions (see :mod:`sim.ngsim.smooth`).
        progress: show the progress on stderr (a bar on a terminal, lines elsewhere).

    Returns:
        :class:`NgsimLoad`: ``.table`` in the schema dtypes, sorted by (Vehicle_ID, Frame_ID),
        and ``.report``. Validation covers every row of the selected recording, not only the
        kept ones.

    Raises:
        TrajectoryFormatError: naming file, line and column (see the module docstring);
            several sites or recordings and no choice (naming the column and what was found).
        FileNotFoundError: ``path`` does not exist.
        InputTooLargeError: memory ran out (one line: the file, the allocation refused, what to do).
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"NGSIM file not found: {path}")
    if chunksize < 1:
        raise ValueError(f"chunksize must be >= 1, got {chunksize}")
    layout = sniff(path)
    if location is not None and location_column(layout) is None:
        raise TrajectoryFormatError(
            f"{path}: line 1 (header): no Location column, so location={location!r} cannot be "
            "applied; expected the newer public layout's Location column"
        )
    args = (path, layout, location, recording, lanes, frames, vehicles, chunksize, progress)
    try:
        return _load(args, smooth)
    except MemoryError as e:
        raise out_of_memory(e, str(path), memory_advice(path)) from None


def memory_advice(path: Path) -> str:
    """What to do when reading ``path`` ran out of memory: the reader needs about twice the file's
    size (the kept rows as a table, once while they are assembled)."""
    mb = path.stat().st_size / 1e6
    return (f"reading this {mb:.0f} MB file needs about {2 * mb:.0f} MB free; free memory or raise the limit "
            "(ulimit -v), or keep fewer rows (--location, --recording)")


def _load(args: tuple, smooth: bool | SmoothingConfig) -> NgsimLoad:
    """:func:`read_ngsim` after its argument checks (``args``: what :func:`_read_pass` takes)."""
    path, layout, location, recording = args[:4]
    if recording is None:
        try:
            table, validator, rows_read, chunks, rec = _read_pass(*args, ordered=True)
        except _NeedsSorting:
            table, validator, rows_read, chunks, rec = _read_pass(*args, ordered=False)
    else:
        table, validator, rows_read, chunks, rec = _read_pass(*args, ordered=False)
    jerk = jerk_rms(table)
    smoothing, jerk_after = "none", None
    if smooth:
        cfg = smooth if isinstance(smooth, SmoothingConfig) else SmoothingConfig()
        table = smooth_table(table, cfg)
        smoothing, jerk_after = cfg.describe(), jerk_rms(table)
    t = validator.totals
    report = NgsimReport(
        path=str(path), layout=layout.kind, rows_read=rows_read, rows_kept=len(table),
        chunks=chunks, duplicate_rows_dropped=t.duplicate_rows,
        vehicles=validator.n_vehicles, vehicles_with_gaps=validator.vehicles_with_gaps,
        gap_events=t.gap_events, missing_frames=t.missing_frames, max_gap_frames=t.max_gap_frames,
        acc_saturated_rows=t.acc_saturated_rows, jerk_rms_ft_s3=jerk, smoothing=smoothing,
        jerk_rms_smoothed_ft_s3=jerk_after,
        extra_columns_dropped=tuple(n for n in layout.names if n not in COLUMNS),
        location=None if location is None else normalise_location(location),
        recording="" if rec is None else rec.describe(),
    )
    return NgsimLoad(table=table, report=report)


def _read_pass(path, layout, location, recording, lanes, frames, vehicles, chunksize, progress, *, ordered):
    """One pass over the file; see :func:`read_ngsim`. Returns (table, validator, rows read,
    chunks, the recording chosen or None). ``ordered``: validate in file order (raises
    :class:`_NeedsSorting` at the first order problem); else hold, sort, then validate."""
    lane_set = None if lanes is None else np.unique(np.asarray(list(lanes), dtype=np.float64))
    veh_set = None if vehicles is None else np.unique(np.asarray(list(vehicles), dtype=np.float64))
    target = None if location is None else normalise_location(location)
    validator = ChunkValidator(str(path))
    tally = RecordingTally()
    loc_counts: dict[str, int] = {}
    parts: list[np.ndarray] = []  # kept rows of every chunk, float64[18, k]
    line_parts: list[np.ndarray] = []  # unordered: their file lines
    off_parts: list[np.ndarray] = []  # unordered: their Global_Time offsets
    chunks = rows_read = 0
    bar = None
    if progress:
        from merge_irl.progress import progress_bar

        bar = progress_bar(path.stat().st_size, unit="B", desc=path.name)

    def filters(data: np.ndarray, keep: np.ndarray) -> np.ndarray:
        if lane_set is not None:
            keep &= np.isin(data[_COL["Lane_ID"]], lane_set)
        if frames is not None:
            f = data[_COL["Frame_ID"]]
            keep &= (f >= frames[0]) & (f <= frames[1])
        if veh_set is not None:
            keep &= np.isin(data[_COL["Vehicle_ID"]], veh_set)
        return keep

    try:
        gen = iter_chunks(path, layout, chunksize)
        while True:
            try:
                data, locs = next(gen)
            except StopIteration:
                break
            except (pa.ArrowInvalid, ValueError, pd.errors.ParserError) as e:
                raise locate_bad_line(path, layout, rows_read + layout.header_lines + 1, e) from None
            n = data.shape[1]
            lines = np.arange(n, dtype=np.int64) + rows_read + layout.header_lines + 1
            if locs is not None:
                codes, uniq = pd.factorize(locs, use_na_sentinel=False)  # hashing in C: few sites
                names = [normalise_location("" if v is None or v != v else v) for v in uniq]
                for k, m in zip(names, np.bincount(codes, minlength=len(names)).tolist()):
                    loc_counts[k] = loc_counts.get(k, 0) + m
                if target is not None:
                    sel = np.isin(codes, [i for i, k in enumerate(names) if k == target])
                    data, lines = data[:, sel], lines[sel]
            if ordered:
                try:
                    keep = validator.check(data, lines)
                except TrajectoryFormatError as e:
                    raise _NeedsSorting(str(e)) from e
                tally.add(data[_COL["Frame_ID"]], data[_COL["Global_Time"]])
                parts.append(data[:, filters(data, keep)])  # a copy: ``data`` is reused
            else:
                validator.check(data, lines, order=False)
                off = tally.add(data[_COL["Frame_ID"]], data[_COL["Global_Time"]])
                parts.append(data.copy())
                line_parts.append(lines)
                off_parts.append(off)
            del data
            chunks += 1
            rows_read += n
            if bar is not None:
                bar.update(int(n * layout.bytes_per_row))
    finally:
        if bar is not None:
            bar.close()
    loc_col = location_column(layout)
    if loc_col is not None:
        choose_location(str(path), loc_col, loc_counts, location)
    rec = choose_recording(str(path), tally.recordings(), recording)
    if not ordered:
        data = _concatenate(parts)
        lines = np.concatenate(line_parts) if line_parts else np.empty(0, np.int64)
        if rec is not None:
            off = np.concatenate(off_parts)
            sel = (off >= rec.offset_lo_ms) & (off <= rec.offset_hi_ms)
            data, lines = data[:, sel], lines[sel]
        order = np.lexsort((lines, data[_COL["Frame_ID"]], data[_COL["Vehicle_ID"]]))
        permute_rows(data, order)  # in place: one row's memory more, not a second copy
        lines = lines[order]
        del order
        validator = ChunkValidator(str(path))  # again, in order now: chunk by chunk, bounding its temporaries
        keep = filters(data, np.concatenate(
            [validator.check(data[:, a:a + chunksize], lines[a:a + chunksize])
             for a in range(0, data.shape[1], chunksize)] or [np.empty(0, dtype=bool)]))
        data = _kept(data, keep)
    validator.check_units()
    table = _sorted(assemble(parts) if ordered else table_in_place(data))
    vehicle, frame, lane, x, y, speed = (table[c].to_numpy() for c in (
        "Vehicle_ID", "Frame_ID", "Lane_ID", "Local_X", "Local_Y", "v_Vel"))
    check_kinematic_units(vehicle, frame, lane, x, y, speed, str(path))
    return table, validator, rows_read, chunks, rec


def _kept(data: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """The columns ``keep`` (bool[N]) of ``data`` (float64[18, N]): ``data`` itself when all are
    kept; moved left in place when most are (no second copy at the peak; the table then holds
    ``data``'s memory); else a copy (at most half its size more, and the rest freed)."""
    k = int(np.count_nonzero(keep))
    if k == data.shape[1]:
        return data
    if 2 * k < data.shape[1]:
        return data[:, keep]
    for r in range(data.shape[0]):
        data[r, :k] = data[r][keep]
    return data[:, :k]


def _concatenate(parts: list[np.ndarray]) -> np.ndarray:
    """The chunks (float64[18, k] each; the list is emptied) side by side, each freed once copied."""
    n = sum(p.shape[1] for p in parts)
    data = np.empty((len(NGSIM_COLUMNS), n), dtype=np.float64)
    at = 0
    parts.reverse()
    while parts:
        p = parts.pop()
        data[:, at:at + p.shape[1]] = p
        at += p.shape[1]
        del p
        release_freed_memory()  # each chunk's pages back to the system before the next is copied
    return data


def _sorted(table: pd.DataFrame) -> pd.DataFrame:
    v = table["Vehicle_ID"].to_numpy()
    f = table["Frame_ID"].to_numpy()
    if len(v) < 2 or bool(np.all((v[1:] > v[:-1]) | ((v[1:] == v[:-1]) & (f[1:] > f[:-1])))):
        return table
    order = np.lexsort((f, v))
    return table.take(order).reset_index(drop=True)


def read_trajectories(path: str | os.PathLike, **kwargs) -> pd.DataFrame:
    """A trajectory table from Parquet (simulated runs: a file, or a Parquet dataset folder of part
    files, :func:`merge_irl.tables.read_table`) or an NGSIM ``.csv`` / ``.txt`` file.

    ``kwargs`` go to :func:`read_ngsim` for NGSIM files (ignored for Parquet).

    Raises:
        FileNotFoundError: a Parquet path that does not exist.
        TrajectoryFormatError: an unknown suffix, a folder holding no Parquet part files, or a file
            that is not a valid trajectory table (the message names the file, and for NGSIM files
            the line and column).
    """
    from sim.runtime.schema import conform

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix in PARQUET_SUFFIXES or path.is_dir():
        if not path.exists():
            raise FileNotFoundError(f"trajectory file not found: {path}")
        try:
            return conform(read_table(path, error=TrajectoryFormatError))
        except TrajectoryFormatError:
            raise
        except (KeyError, ValueError, TypeError) as e:
            raise TrajectoryFormatError(f"{path}: {' '.join(str(e).split())}") from e
    if suffix in (".csv", ".txt"):
        return read_ngsim(path, **kwargs).table
    raise TrajectoryFormatError(
        f"{path}: unknown trajectory file type {suffix!r}; expected .parquet, .csv or .txt, or a Parquet dataset folder"
    )
