"""Progress of long work, one home for every command: a tqdm bar when stderr is a terminal, and
plain lines when it is not (a log file under nohup, CI or SLURM), so that a batch run is never
silent for minutes.

On a non-terminal, :class:`ProgressLines` writes one line when the work starts, one each time
another tenth of it is done or at least :data:`LINE_INTERVAL_S` has passed since the last line
(whichever comes first, and never more often than a line per update), and one at the end:
``merge-irl: episodes: 7/30 task (23%), 1m05s elapsed, about 3m40s left``. A run that reports its
own lines already (e.g. a line per DAgger round) needs none of these.
"""

from __future__ import annotations

import sys
import time
from typing import Any, TextIO

from tqdm import tqdm

#: At most this long (seconds) between two lines on a non-terminal while work progresses.
LINE_INTERVAL_S = 60.0


def _duration(seconds: float) -> str:
    s = int(round(seconds))
    if s < 60:
        return f"{s}s"
    if s < 3600:
        return f"{s // 60}m{s % 60:02d}s"
    return f"{s // 3600}h{s % 3600 // 60:02d}m"


class ProgressLines:
    """The part of tqdm's interface the project uses (``update``, ``close``, ``set_postfix``,
    a context manager, iteration), written as plain lines (module docstring).

    Args:
        total: units of work (None: unknown; then a line per :data:`LINE_INTERVAL_S` only).
        desc: what is being done (starts each line).
        unit: the unit of work (``task``, ``sim s``).
        initial: units already done (e.g. results taken from a store).
        file: where the lines go.
        interval_s: at most this long between two lines while updates come in.
        iterable: wrapped when the object is iterated (as ``tqdm(iterable)``).
    """

    def __init__(self, total: float | None = None, *, desc: str = "", unit: str = "it", initial: float = 0,
                 file: TextIO | None = None, interval_s: float = LINE_INTERVAL_S, iterable: Any = None):
        self.total = total
        self.desc = desc or "progress"
        self.unit = unit
        self.n = initial
        self.file = file if file is not None else sys.stderr
        self.interval_s = interval_s
        self.iterable = iterable
        self.postfix = ""
        self._t0 = self._last_t = time.monotonic()
        self._last_tenth = self._tenth()
        self._closed = False
        self._line("started" + (f", {_count(initial)} done before" if initial else ""))

    def _tenth(self) -> int:
        return int(10 * self.n / self.total) if self.total else 0

    def _line(self, note: str = "") -> None:
        elapsed = time.monotonic() - self._t0
        if self.total:
            text = f"{_count(self.n)}/{_count(self.total)} {self.unit} ({100 * self.n / self.total:.0f}%)"
        else:
            text = f"{_count(self.n)} {self.unit}"
        text += f", {_duration(elapsed)} elapsed"
        if self.total and 0 < self.n < self.total and not note:
            text += f", about {_duration(elapsed * (self.total - self.n) / self.n)} left"
        if self.postfix:
            text += f", {self.postfix}"
        if note:
            text += f" ({note})"
        print(f"merge-irl: {self.desc}: {text}", file=self.file, flush=True)
        self._last_t = time.monotonic()

    def update(self, n: float = 1) -> None:
        """``n`` more units done; a line when another tenth is done or the interval has passed."""
        self.n += n
        tenth = self._tenth()
        if tenth > self._last_tenth or time.monotonic() - self._last_t >= self.interval_s:
            self._last_tenth = tenth
            if not (self.total and self.n >= self.total):  # the last line is close()'s
                self._line()

    def set_postfix(self, ordered_dict: dict | None = None, refresh: bool = True, **kwargs: Any) -> None:
        """Extra ``key=value`` text at the end of the next lines (as tqdm's)."""
        items = {**(ordered_dict or {}), **kwargs}
        self.postfix = ", ".join(f"{k}={v}" for k, v in items.items())

    def close(self) -> None:
        """The last line (once)."""
        if not self._closed:
            self._closed = True
            self._line("done" if not self.total or self.n >= self.total else "stopped")

    def __enter__(self) -> ProgressLines:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __iter__(self):
        try:
            for x in self.iterable:
                yield x
                self.update(1)
        finally:
            self.close()


def _count(x: float) -> str:
    return f"{x:g}" if isinstance(x, float) and not x.is_integer() else f"{int(x)}"


def progress_bar(total: float | None = None, *, desc: str = "", unit: str = "it", enabled: bool = True,
                 initial: float = 0, leave: bool = True, lines: bool = True, file: TextIO | None = None,
                 iterable: Any = None) -> Any:
    """The progress display of long work: a tqdm bar on a terminal, :class:`ProgressLines` on
    anything else (a log file, a pipe), a disabled tqdm when not ``enabled``.

    Args:
        total, desc, unit, initial, iterable: as tqdm's.
        enabled: False shows nothing (``--no-progress``).
        leave: keep the bar on the terminal when done (tqdm's).
        lines: False: nothing on a non-terminal (for short inner loops whose outer work already
            reports, e.g. one IRL fit's iterations).
        file: the stream (default ``sys.stderr``, looked up at the call).

    Returns:
        An object with ``update``, ``close``, ``set_postfix``, usable as a context manager and,
        with ``iterable``, as an iterator.
    """
    stream = file if file is not None else sys.stderr
    tty = bool(getattr(stream, "isatty", lambda: False)())
    if enabled and not tty and lines:
        return ProgressLines(total, desc=desc, unit=unit, initial=initial, file=stream, iterable=iterable)
    return tqdm(iterable, total=total, desc=desc, unit=unit, initial=initial, leave=leave, file=stream,
                disable=not (enabled and tty))


def progress_write(line: str, file: TextIO | None = None) -> None:
    """``line`` on stderr (or ``file``) without breaking a bar drawn there (tqdm's ``write``)."""
    tqdm.write(line, file=file if file is not None else sys.stderr)
