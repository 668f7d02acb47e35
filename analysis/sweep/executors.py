"""Executors: where a sweep's tasks run.

- ``serial``: in this process, one after the other (debugging, tiny sweeps).
- ``process`` / ``process:N``: a local process pool with N workers (default: every core),
  fresh ``spawn`` processes, so each task can own a libsumo simulation.
- ``dask-local`` / ``dask-local:N``: a Dask ``LocalCluster`` on the loopback interface.
- ``dask://HOST:PORT``: an existing Dask distributed scheduler (more than one machine).
"""

from __future__ import annotations

import os
from dataclasses import dataclass

EXECUTORS = ("serial", "process", "dask-local", "dask://HOST:PORT")


@dataclass(frozen=True)
class ExecutorSpec:
    """A parsed ``--executor`` value.

    Attributes:
        kind: ``"serial" | "process" | "dask-local" | "dask"``.
        workers: number of local workers (process pool or LocalCluster).
        address: scheduler address for ``kind == "dask"`` (``tcp://HOST:PORT``).
    """

    kind: str
    workers: int = 1
    address: str = ""


def default_workers() -> int:
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - non-Linux
        return max(1, os.cpu_count() or 1)


def parse_executor(text: str) -> ExecutorSpec:
    """Parse ``serial``, ``process[:N]``, ``dask-local[:N]`` or ``dask://HOST:PORT``.

    Raises:
        ValueError: ``text`` names no known executor, a ``dask://`` address without ``HOST:PORT``, a worker
            count for ``serial`` or a worker count that is not a positive integer.
    """
    text = text.strip()
    if text.startswith("dask://"):
        rest = text[len("dask://"):]
        host, sep, port = rest.rpartition(":")
        if not sep or not host or not port.isdigit():
            raise ValueError(f"--executor {text!r}: expected dask://HOST:PORT")
        return ExecutorSpec("dask", address=f"tcp://{host}:{port}")
    name, sep, count = text.partition(":")
    if name not in ("serial", "process", "dask-local"):
        raise ValueError(f"--executor {text!r}: expected one of {', '.join(EXECUTORS)}")
    if name == "serial":
        if sep:
            raise ValueError(f"--executor {text!r}: 'serial' takes no worker count")
        return ExecutorSpec("serial", workers=1)
    if sep:
        if not count.isdigit() or int(count) < 1:
            raise ValueError(f"--executor {text!r}: worker count must be a positive integer")
        workers = int(count)
    else:
        workers = default_workers()
    return ExecutorSpec(name, workers=workers)
