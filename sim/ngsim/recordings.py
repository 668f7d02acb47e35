"""Recordings inside one NGSIM file: sites (the ``Location`` column) and periods (``Global_Time``).

A vehicle and a moment are keyed by ``Vehicle_ID`` and ``Frame_ID`` only *within one
recording*: NGSIM restarts both for every site and period, so a file joining the three I-80
periods, several days or several sites (the newer public layout's ``Location`` column) must be
split or narrowed before vehicles are followed through frames.

Within a recording ``Global_Time`` (ms) runs with ``Frame_ID`` (0.1 s frames):
``Global_Time - 100 * Frame_ID`` is the same for every row. A change of this offset by more
than :data:`OFFSET_TOLERANCE_MS` (a jump in ``Global_Time`` between consecutive frames) starts
a new recording. Recordings are numbered 1, 2, ... in order of their first ``Global_Time``.
"""

from __future__ import annotations

import datetime as _dt
from dataclasses import dataclass

import numpy as np

from sim.errors import TrajectoryFormatError

#: Largest change (ms) of Global_Time - 100 * Frame_ID still taken as the same recording.
OFFSET_TOLERANCE_MS = 1000.0
#: Global_Time values above this (ms) are read as Unix epoch times in messages (year 2001+).
_EPOCH_MS = 1e12


@dataclass(frozen=True)
class Recording:
    """One recording found in a file (offsets in ms, frames inclusive)."""

    number: int  #: 1-based, in order of first Global_Time
    offset_lo_ms: float
    offset_hi_ms: float
    first_frame: int
    last_frame: int
    first_time_ms: float
    rows: int

    def describe(self) -> str:
        start = f"Global_Time {self.first_time_ms:.0f} ms"  # not a date: before 2001 (1e12 ms), or past year 9999
        if self.first_time_ms >= _EPOCH_MS:
            try:
                start = _dt.datetime.fromtimestamp(self.first_time_ms / 1000.0, _dt.UTC).strftime("%Y-%m-%d %H:%M:%S UTC")
            except (ValueError, OverflowError, OSError):
                pass
        return (f"#{self.number}: frames {self.first_frame}-{self.last_frame} from {start}, "
                f"{self.rows} rows")


class RecordingTally:
    """Accumulates ``Global_Time - 100 * Frame_ID`` offsets chunk by chunk (memory ~ distinct
    offsets, at most one per frame)."""

    def __init__(self) -> None:
        self._stats: dict[float, list[float]] = {}  # offset -> [min frame, max frame, rows]

    def add(self, frame: np.ndarray, global_time: np.ndarray) -> np.ndarray:
        """Tally one chunk (float64[N] each); return the offsets float64[N]."""
        off = global_time - 100.0 * frame
        if off.size == 0:
            return off
        lo, hi = off.min(), off.max()
        if lo == hi:  # the usual case: one recording, exact 100 ms frames
            u, fmin, fmax, cnt = np.array([lo]), np.array([frame.min()]), np.array([frame.max()]), np.array([off.size])
        else:
            u, inv = np.unique(off, return_inverse=True)
            fmin = np.full(u.size, np.inf)
            fmax = np.full(u.size, -np.inf)
            np.minimum.at(fmin, inv, frame)
            np.maximum.at(fmax, inv, frame)
            cnt = np.bincount(inv, minlength=u.size)
        for o, lo, hi, c in zip(u.tolist(), fmin.tolist(), fmax.tolist(), cnt.tolist()):
            s = self._stats.get(o)
            if s is None:
                self._stats[o] = [lo, hi, c]
            else:
                s[0], s[1], s[2] = min(s[0], lo), max(s[1], hi), s[2] + c
        return off

    def recordings(self) -> tuple[Recording, ...]:
        """The recordings found, numbered in time order."""
        if not self._stats:
            return ()
        offs = np.array(sorted(self._stats))
        brk = np.flatnonzero(np.diff(offs) > OFFSET_TOLERANCE_MS) + 1
        groups = np.split(offs, brk)
        recs = []
        for g in groups:
            st = [self._stats[o] for o in g.tolist()]
            lo = min(s[0] for s in st)
            recs.append((float(g[0]), float(g[-1]), int(lo), int(max(s[1] for s in st)),
                         float(g[0]) + 100.0 * lo, int(sum(s[2] for s in st))))
        recs.sort(key=lambda r: r[4])
        return tuple(Recording(i, *r) for i, r in enumerate(recs, start=1))


def choose_recording(path: str, recs: tuple[Recording, ...], recording: int | None) -> Recording | None:
    """The recording to keep: None when the file holds one (keep everything).

    Raises:
        TrajectoryFormatError: several recordings and ``recording`` is None, or ``recording``
            is not one of them; the message lists what was found.
    """
    if recording is None and len(recs) <= 1:
        return None
    found = "; ".join(r.describe() for r in recs)
    if recording is None:
        raise TrajectoryFormatError(
            f"{path}: column Global_Time: {len(recs)} recordings found (Global_Time jumps against "
            f"Frame_ID): {found}; vehicles are keyed within one recording, so choose one "
            "(recording=N, command line --recording N)"
        )
    for r in recs:
        if r.number == recording:
            return r
    raise TrajectoryFormatError(
        f"{path}: recording {recording} not found; column Global_Time gives {len(recs)} "
        f"recording(s): {found}"
    )


def normalise_location(value: str) -> str:
    """Site names compared case- and space-insensitively (``I-80`` == `` i-80``)."""
    return str(value).strip().lower()


def choose_location(path: str, column: str, counts: dict[str, int], location: str | None) -> None:
    """Check the ``Location`` values found (``counts``: normalised value -> rows).

    Raises:
        TrajectoryFormatError: several sites and ``location`` is None, or ``location`` absent.
    """
    found = ", ".join(f"{k!r} ({v} rows)" for k, v in sorted(counts.items()))
    if location is None:
        if len(counts) > 1:
            raise TrajectoryFormatError(
                f"{path}: column {column}: {len(counts)} sites found: {found}; vehicle ids "
                "restart at every site, so choose one (location=..., command line --location SITE)"
            )
        return
    if counts.get(normalise_location(location), 0) == 0:
        raise TrajectoryFormatError(
            f"{path}: column {column}: no rows of site {location!r}; sites found: {found or 'none'}"
        )
