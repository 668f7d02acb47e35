"""Cancelling a run from outside its thread: a check that long work polls between steps.

A sweep that runs tasks where it cannot kill them (a Dask worker runs each task in a thread of
a process shared with other tasks) installs, around each task, a function that says whether the
task is still wanted (:func:`cancellable`). The work polls it: a SUMO run between its steps
(:class:`CancelHook`, at most every :data:`POLL_S` s), and :func:`merge_irl.run_folder.publish`
once more just before it publishes a folder, so that a cancelled run publishes nothing. Outside
such a block both are no-ops (a run in the calling process or in a process pool, which is killed
instead).
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

#: Seconds between two polls of the stop check by :class:`CancelHook` (the check may ask a
#: remote scheduler; a run stops at most this long after it was cancelled, plus one step).
POLL_S = 0.5

_LOCAL = threading.local()


class Cancelled(Exception):
    """The run was cancelled from outside (the sweep that started it was interrupted).

    ``retry = False``: a sweep does not run it again."""

    retry = False


@contextlib.contextmanager
def cancellable(stop_requested: Callable[[], bool], *, every_s: float = POLL_S) -> Iterator[None]:
    """While the block runs in this thread, :func:`check_cancelled` raises :class:`Cancelled`
    once ``stop_requested()`` returns True (polled at most every ``every_s`` s)."""
    before = getattr(_LOCAL, "scope", None)
    _LOCAL.scope = (stop_requested, float(every_s), [time.monotonic()])
    try:
        yield
    finally:
        _LOCAL.scope = before


def check_cancelled(*, now: bool = False) -> None:
    """Raise :class:`Cancelled` if this thread's run was cancelled (:func:`cancellable`);
    ``now``: ask even if the last poll was less than the block's interval ago.

    Raises:
        Cancelled: the stop check says so.
    """
    scope = getattr(_LOCAL, "scope", None)
    if scope is None:
        return
    stop_requested, every_s, last = scope
    t = time.monotonic()
    if not now and t - last[0] < every_s:
        return
    last[0] = t
    if stop_requested():
        raise Cancelled("the sweep that started this run was cancelled (interrupted); nothing was published")


class CancelHook:
    """A step hook (:class:`sim.runtime.hooks.StepHook`) that stops a simulation between two
    steps once its run is cancelled (:func:`check_cancelled`)."""

    def on_start(self, ctx: Any) -> None:
        check_cancelled(now=True)

    def on_step(self, ctx: Any, frame: Any) -> None:
        check_cancelled()

    def on_end(self, ctx: Any) -> None:
        check_cancelled(now=True)

    def on_abort(self, ctx: Any) -> None:
        """The run stopped early (an error, or this hook's :class:`Cancelled`): nothing to check."""
