"""What runs inside a worker: call the task, never let its exception escape; die with the parent."""

from __future__ import annotations

import ctypes
import json
import os
import signal
import threading
import time
import traceback
from collections.abc import Callable
from typing import Any

#: Linux ``prctl`` option: the signal a process receives when its parent dies.
PR_SET_PDEATHSIG = 1
#: How often (s) a worker checks that its parent is alive (fallback of the death signal).
PARENT_POLL_S = 0.5


def die_with_parent(parent_pid: int) -> None:
    """Pool-worker initializer: end this worker when the process ``parent_pid`` ends.

    Two mechanisms: Linux's parent-death signal (``prctl(PR_SET_PDEATHSIG, SIGKILL)``, sent by
    the kernel the moment the parent dies, even by SIGKILL), and a daemon thread that polls
    the parent's pid every :data:`PARENT_POLL_S` s (other systems, or a parent that died before
    the signal was armed). SIGINT is ignored: a Ctrl-C goes to the whole process group, and the
    parent decides what happens to the runs in flight (it stops the workers itself).
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
    except (OSError, AttributeError):  # pragma: no cover - not Linux: polling only
        pass
    if os.getppid() != parent_pid:  # the parent died before the signal was armed
        os._exit(1)
    threading.Thread(target=_watch_parent, args=(parent_pid,), name="watch-parent", daemon=True).start()


def _watch_parent(parent_pid: int) -> None:
    while os.getppid() == parent_pid:
        time.sleep(PARENT_POLL_S)
    os._exit(1)


def call_task(func: Callable[[Any, int], dict], config: Any, seed: int) -> dict[str, Any]:
    """Run ``func(config, seed)``; return ``{"ok", "result" | "error", "wall_time_s"}`` (and on an
    error ``"retry"``: False when the exception's class says ``retry = False``; ``"abort"``: True
    when it says ``abort = True``, the sweep then stops).

    The result must be a JSON-serialisable dict (it is stored as JSON); anything else is
    reported as the task's error.

    Raises:
        TypeError: the task returned something other than a dict.
    """
    t0 = time.perf_counter()
    try:
        result = func(config, seed)
        if not isinstance(result, dict):
            raise TypeError(f"task returned {type(result).__name__}, expected a dict")
        json.dumps(result)
        return {"ok": True, "result": result, "wall_time_s": time.perf_counter() - t0}
    except Exception as e:  # noqa: BLE001 - the sweep reports every task error
        return {
            "ok": False,
            "error": f"{type(e).__name__}: {e}",
            "traceback": traceback.format_exc(limit=20),
            "wall_time_s": time.perf_counter() - t0,
            # an error class that says the same inputs fail the same way (``retry = False``,
            # e.g. sim.drivers.policy.PolicyError) is not run again
            "retry": bool(getattr(e, "retry", True)),
            # an error class that says every other task would fail the same way after as long a
            # wait (``abort = True``, e.g. a callable driver's time-out) stops the whole sweep
            "abort": bool(getattr(e, "abort", False)),
        }
