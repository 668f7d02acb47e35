"""What runs inside a worker: call the task, never let its exception escape."""

from __future__ import annotations

import json
import time
import traceback
from typing import Any
from collections.abc import Callable


def call_task(func: Callable[[Any, int], dict], config: Any, seed: int) -> dict[str, Any]:
    """Run ``func(config, seed)``; return ``{"ok", "result" | "error", "wall_time_s"}``.

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
        }
