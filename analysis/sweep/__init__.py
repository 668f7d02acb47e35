"""Run many independent tasks (IRL trials, scenario runs, evaluation episodes) reproducibly.

One entry point, :func:`run_sweep`, used by ``reproduce``, ``generate``, ``evaluate`` and
``demo``. A task is a top-level function ``func(config, seed) -> dict`` (JSON-serialisable
result) plus a frozen config; its seed is derived from the sweep seed and the task's key, so
results do not depend on the executor or the order. Finished results are stored under a key
derived from the task's full config, so re-running a sweep skips what is done.
"""

from analysis.sweep.executors import EXECUTORS, parse_executor, resolve_executor
from analysis.sweep.seeds import derive_seed
from analysis.sweep.store import ResultStore, task_digest
from analysis.sweep.sweep import SweepReport, Task, TaskFailure, run_sweep

__all__ = [
    "EXECUTORS",
    "ResultStore",
    "SweepReport",
    "Task",
    "TaskFailure",
    "derive_seed",
    "parse_executor",
    "resolve_executor",
    "run_sweep",
    "task_digest",
]
