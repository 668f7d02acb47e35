"""The sweep driver: derive seeds, skip finished tasks, run the rest, retry, report."""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import shutil
import signal
import tempfile
import time
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from typing import Any

from analysis.sweep.executors import ExecutorSpec, parse_executor
from analysis.sweep.seeds import derive_seed
from analysis.sweep.store import ResultStore, task_digest
from analysis.sweep.worker import call_task, die_with_parent
from merge_irl.progress import progress_bar, progress_write
from merge_irl.spawn_guard import GUARD_HINT, importing_main_in_worker


@dataclass(frozen=True)
class Task:
    """One unit of work.

    Attributes:
        key: unique, human-readable name within the sweep (also feeds the task's seed).
        func: a top-level (importable, picklable) function ``func(config, seed) -> dict``.
        config: the task's full configuration (a frozen dataclass or JSON-like value).
    """

    key: str
    func: Callable[[Any, int], dict]
    config: Any

    @property
    def func_name(self) -> str:
        return f"{self.func.__module__}:{self.func.__qualname__}"


@dataclass(frozen=True)
class TaskFailure:
    """A task that failed on every attempt: its key, the last error and the attempt count."""

    key: str
    error: str
    attempts: int
    traceback: str = ""


@dataclass(frozen=True)
class SweepReport:
    """Results of a sweep, in task order.

    Attributes:
        results: ``key -> result dict`` for every task that succeeded (now or earlier).
        seeds: ``key -> seed`` used for each task.
        failures: tasks that failed after their retry.
        n_cached: tasks skipped because a stored result existed.
        n_run: tasks run in this call (successful or not).
        wall_time_s: duration of this call.
        task_times_s: ``key -> wall time`` of each task run in this call.
        aborted: the sweep stopped at a failure whose error says ``abort = True`` (the tasks
            not yet finished are neither in ``results`` nor in ``failures``).
    """

    results: dict[str, dict]
    seeds: dict[str, int]
    failures: tuple[TaskFailure, ...]
    n_cached: int
    n_run: int
    wall_time_s: float
    task_times_s: dict[str, float] = field(default_factory=dict)
    aborted: bool = False

    @property
    def ok(self) -> bool:
        return not self.failures

    def summary(self) -> str:
        lines = [
            f"{len(self.results)} task(s) done ({self.n_cached} from the store, {self.n_run} run) "
            f"in {self.wall_time_s:.1f} s; {len(self.failures)} failed"
        ]
        for f in self.failures:
            lines.append(f"  FAILED {f.key} after {f.attempts} attempt(s): {f.error}")
        if self.aborted:
            lines.append("  the sweep stopped at that failure; the unfinished tasks did not run")
        return "\n".join(lines)


class _SweepAborted(Exception):
    """A task failed with an error whose class says ``abort = True``: the sweep stops (its workers
    stopped as on Ctrl-C) and reports that failure."""


@dataclass
class _Pending:
    task: Task
    seed: int
    digest: str
    attempts: int = 0
    last: dict = field(default_factory=dict)


def run_sweep(
    tasks: Iterable[Task],
    *,
    seed: int = 0,
    executor: str | ExecutorSpec = "process",
    store: ResultStore | str | os.PathLike | None = None,
    retries: int = 1,
    progress: bool = True,
    desc: str = "sweep",
) -> SweepReport:
    """Run ``tasks`` and return their results.

    Each task's seed is ``derive_seed(seed, task.key)``: identical whichever executor runs it
    and in whatever order. With a ``store``, a task whose result (keyed by its function, full
    config and seed) is stored is skipped, and each result is stored as soon as it arrives, so
    a sweep killed midway loses only the tasks in flight. A task that raises, or kills its
    worker process, is retried ``retries`` times and then reported in ``failures``; the other
    tasks go on, except after an error whose class says ``abort = True`` (e.g. a callable
    driver's time-out, :class:`sim.drivers.callables.limits.DecisionTimeout`): then the sweep stops
    at once, its workers ended, finished results kept, and that failure is reported
    (``SweepReport.aborted``).

    Raises:
        ValueError: two tasks share a key.
        RuntimeError: called while a worker process imports the main script (no ``__main__``
            guard); the worker stops there instead of starting a sweep of its own.
    """
    if importing_main_in_worker():
        raise RuntimeError(f"a sweep was started while a worker process imported the main script: {GUARD_HINT}")
    spec = parse_executor(executor) if isinstance(executor, str) else executor
    if store is not None and not isinstance(store, ResultStore):
        store = ResultStore(store)
    task_list = list(tasks)
    keys = _unique_keys(task_list)
    t0 = time.perf_counter()
    seeds, done, todo = _plan(task_list, seed, store)
    n_cached = len(done)
    if todo and spec.kind == "dask":  # an unusable scheduler is one line, before any progress line
        _check_dask_scheduler(spec)
    bar = progress_bar(len(task_list), initial=n_cached, desc=desc, unit="task", enabled=progress)
    finish = _Finisher(done, store, bar, retries, desc)

    aborted = False
    try:
        _execute(spec, todo, finish, desc)
    except _SweepAborted:
        aborted = True
    finally:
        bar.close()
    ordered = {k: done[k] for k in keys if k in done}
    order = {k: i for i, k in enumerate(keys)}
    return SweepReport(
        results=ordered,
        seeds=seeds,
        failures=tuple(sorted(finish.failures, key=lambda f: order[f.key])),
        n_cached=n_cached,
        n_run=len(todo),
        wall_time_s=time.perf_counter() - t0,
        task_times_s=finish.times,
        aborted=aborted,
    )


def _unique_keys(task_list: Sequence[Task]) -> list[str]:
    """The tasks' keys, in order.

    Raises:
        ValueError: two tasks share a key.
    """
    keys = [t.key for t in task_list]
    if len(set(keys)) != len(keys):
        dupes = sorted({k for k in keys if keys.count(k) > 1})
        raise ValueError(f"task keys must be unique; repeated: {dupes}")
    return keys


def _plan(task_list: Sequence[Task], seed: int,
          store: ResultStore | None) -> tuple[dict[str, int], dict[str, dict], list[_Pending]]:
    """``(seeds, done, todo)``: each task's derived seed by key, the stored results by key and the
    tasks still to run (in order)."""
    seeds: dict[str, int] = {}
    done: dict[str, dict] = {}
    todo: list[_Pending] = []
    for t in task_list:
        s = derive_seed(seed, t.key)
        seeds[t.key] = s
        digest = task_digest(t.func_name, t.config, s)
        record = store.get(digest) if store is not None else None
        if record is not None:
            done[t.key] = record["result"]
        else:
            todo.append(_Pending(t, s, digest))
    return seeds, done, todo


class _Finisher:
    """Records each attempt's outcome for :func:`run_sweep` (called as ``finish(pending, record)``).

    Results go into ``done`` (by key) and the store, failures past ``retries`` into
    ``failures``, each attempt's wall time (s) into ``times``; ``bar`` advances once per task.
    """

    def __init__(self, done: dict[str, dict], store: ResultStore | None, bar, retries: int, desc: str) -> None:
        self.done, self.store, self.bar, self.retries, self.desc = done, store, bar, retries, desc
        self.failures: list[TaskFailure] = []
        self.times: dict[str, float] = {}

    def __call__(self, p: _Pending, record: dict) -> bool:
        """Record an attempt's outcome; return True if the task should be retried.

        Raises:
            _SweepAborted: the task failed for good with an error that aborts the sweep.
        """
        p.attempts += 1
        p.last = record
        self.times[p.task.key] = float(record.get("wall_time_s", 0.0))
        if record.get("ok"):
            self.done[p.task.key] = record["result"]
            if self.store is not None:
                self.store.put(p.digest, {"key": p.task.key, "func": p.task.func_name,
                                          "seed": p.seed, "result": record["result"]})
            self.bar.update(1)
            return False
        if p.attempts <= self.retries and record.get("retry", True):
            progress_write(f"{self.desc}: {p.task.key} failed ({record.get('error', 'unknown error')}); "
                           f"running it again (attempt {p.attempts + 1} of {self.retries + 1})")
            return True
        self.failures.append(TaskFailure(p.task.key, record.get("error", "unknown error"), p.attempts,
                                         record.get("traceback", "")))
        self.bar.update(1)
        if record.get("abort"):
            raise _SweepAborted(p.task.key)
        return False


def _execute(spec: ExecutorSpec, todo: Sequence[_Pending], finish: _Finisher, desc: str) -> None:
    """Run ``todo`` on ``spec``'s executor; progress lines on stderr, each prefixed by ``desc``
    (said with or without the progress bar, which does not overwrite them)."""
    if spec.kind == "serial":
        _run_serial(todo, finish)
    elif spec.kind == "process":
        _run_process_pool(todo, finish, spec.workers, say=lambda line: progress_write(f"{desc}: {line}"))
    else:
        _run_dask(todo, finish, spec)


def _run_serial(todo: Sequence[_Pending], finish) -> None:
    for p in todo:
        while finish(p, call_task(p.task.func, p.task.config, p.seed)):
            pass


def _crash_record(e: BaseException) -> dict:
    return {"ok": False, "error": f"worker process died ({type(e).__name__}: {e}; if it ran from a script: "
                                  f"{GUARD_HINT})", "wall_time_s": 0.0}


#: Thread-pool sizes of the numerical libraries, fixed to 1 in process-pool workers (as Dask's
#: nanny does for its workers): N processes each using every core for BLAS would oversubscribe
#: the machine; parallelism comes from the processes. A value the user set is kept.
_THREAD_ENV = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


@contextlib.contextmanager
def _single_threaded_workers():
    """Spawned workers inherit the environment: set the thread counts while the pool lives."""
    added = [k for k in _THREAD_ENV if k not in os.environ]
    for k in added:
        os.environ[k] = "1"
    try:
        yield
    finally:
        for k in added:
            os.environ.pop(k, None)


@contextlib.contextmanager
def _worker_tmpdir():
    """Spawned workers' temporary folders (a SUMO run's ``merge-irl-run-*``) go under one hidden
    folder of this pool (``TMPDIR`` while it lives), removed once its workers have ended: a worker
    killed mid-run (Ctrl-C, a failure that aborts the sweep, a crash) cannot remove its own. This
    process keeps its own temporary directory (looked up, and cached by :mod:`tempfile`, first)."""
    tempfile.gettempdir()
    root = tempfile.mkdtemp(prefix="merge-irl-sweep-")
    before = os.environ.get("TMPDIR")
    os.environ["TMPDIR"] = root
    try:
        yield root
    finally:
        if before is None:
            os.environ.pop("TMPDIR", None)
        else:
            os.environ["TMPDIR"] = before
        shutil.rmtree(root, ignore_errors=True)


def _pool(workers: int, ctx) -> ProcessPoolExecutor:
    """A process pool whose workers die with this process (:func:`die_with_parent`)."""
    return ProcessPoolExecutor(workers, mp_context=ctx, initializer=die_with_parent, initargs=(os.getpid(),))


def _store_finished(in_flight: dict[Future, _Pending], finish) -> None:
    """On interrupt: record the tasks in flight that have finished all the same."""
    for fut, p in list(in_flight.items()):
        if fut.done() and not fut.cancelled() and fut.exception() is None:
            record = fut.result()
            if record.get("ok"):
                finish(p, record)
        in_flight.pop(fut)


def _stop_workers(pool: ProcessPoolExecutor) -> None:
    """End the pool now: queued tasks cancelled, the workers' runs in flight killed (their
    output folders stay unpublished, see :mod:`merge_irl.run_folder`)."""
    procs = list((getattr(pool, "_processes", None) or {}).values())
    pool.shutdown(wait=False, cancel_futures=True)
    for proc in procs:
        if proc.is_alive():
            proc.kill()
    for proc in procs:
        proc.join(5)


def _run_isolated(p: _Pending, finish) -> None:
    """Run one task alone in a fresh process until it succeeds or runs out of retries."""
    ctx = multiprocessing.get_context("spawn")
    while True:
        with _worker_tmpdir(), _single_threaded_workers(), _pool(1, ctx) as pool:
            try:
                record = pool.submit(call_task, p.task.func, p.task.config, p.seed).result()
            except BrokenProcessPool as e:
                record = _crash_record(e)
            except BaseException:
                _stop_workers(pool)
                raise
        if not finish(p, record):
            return


def _death_cause(procs: Sequence[multiprocessing.process.BaseProcess]) -> str:
    """How a broken pool's worker ended: ``killed by SIGKILL``, ``exit status 13`` or ``""``
    (the pool stops the other workers with SIGTERM; a signal other than that is the cause).

    ``procs``: the pool's worker processes, taken while it ran (a broken pool forgets them); each
    is waited for briefly, since the pool may report the breakage before the dead worker is reaped.
    """
    for p in procs:
        if p.exitcode is None:
            p.join(timeout=2.0)
    codes = [p.exitcode for p in procs if p.exitcode not in (None, 0)]
    for code in sorted(codes, key=lambda c: c == -signal.SIGTERM):
        if code < 0:
            name = signal.Signals(-code).name
            hint = " (the out-of-memory killer sends it)" if code == -signal.SIGKILL else ""
            return f"killed by {name}{hint}"
        return f"exit status {code}"
    return ""


def _run_process_pool(todo: Sequence[_Pending], finish, workers: int,
                      say: Callable[[str], None] = lambda line: None) -> None:
    """At most ``workers`` tasks in flight; a worker crash only affects those in flight.

    When a worker dies the pool is broken and we cannot tell which in-flight task killed it,
    so each in-flight task is re-run alone in its own process (the culprit crashes again and
    uses up its retry; the others just finish), then a fresh pool continues with the rest.
    ``say`` is told of each such crash (one line naming the tasks run again).
    """
    ctx = multiprocessing.get_context("spawn")
    queue = list(todo)
    while queue:
        in_flight: dict[Future, _Pending] = {}
        crashed: list[_Pending] = []
        procs: dict[int, multiprocessing.process.BaseProcess] = {}  # the pool's workers, for _death_cause
        with _worker_tmpdir(), _single_threaded_workers(), _pool(workers, ctx) as pool:
            try:
                while queue or in_flight:
                    while queue and len(in_flight) < workers:
                        try:
                            fut = pool.submit(call_task, queue[0].task.func, queue[0].task.config, queue[0].seed)
                        except BrokenProcessPool:  # a worker died since the last wait: its future says so
                            break
                        in_flight[fut] = queue.pop(0)
                        procs.update(getattr(pool, "_processes", None) or {})
                    if not in_flight:  # broken with nothing in flight: a fresh pool for the rest
                        break
                    finished, _ = wait(in_flight, return_when=FIRST_COMPLETED)
                    for fut in finished:
                        p = in_flight.pop(fut)
                        try:
                            record = fut.result()
                        except BrokenProcessPool:
                            crashed.append(p)
                            continue
                        if finish(p, record):
                            queue.append(p)
                    if crashed:
                        crashed.extend(in_flight.values())
                        in_flight.clear()
                        cause = _death_cause(list(procs.values()))
                        say(f"a worker process died{' (' + cause + ')' if cause else ''} with "
                            f"{', '.join(p.task.key for p in crashed)} in flight; running "
                            f"{'it' if len(crashed) == 1 else 'each'} again in a process of its own")
                        break
            except BaseException:  # Ctrl-C, SIGTERM (see analysis.cli.main), or an error storing a result
                _store_finished(in_flight, finish)
                _stop_workers(pool)
                raise
        for p in crashed:  # the pool-wide crash is not counted: it cannot be attributed
            _run_isolated(p, finish)


def check_executor(executor: str | ExecutorSpec) -> None:
    """Before creating any output: for ``dask://`` / ``tls://``, ask the scheduler who it is
    (what :func:`run_sweep` does before running anything); other executors need no check.

    Raises:
        ValueError: ``executor`` does not parse.
        DaskUnavailable: the scheduler does not answer, is not one, or the TLS files are missing,
            unreadable or do not match (:mod:`analysis.sweep.dask_executor`).
    """
    spec = parse_executor(executor) if isinstance(executor, str) else executor
    if spec.kind == "dask":
        _check_dask_scheduler(spec)


def _check_dask_scheduler(spec: ExecutorSpec) -> None:
    """Ask the scheduler of ``dask://``/``tls://`` who it is (``DaskUnavailable`` otherwise)."""
    from analysis.sweep.dask_executor import check_scheduler, security_for, settings_from_config

    try:
        import distributed  # noqa: F401 - loads Dask's distributed configuration (timeouts, TLS)
    except ImportError:  # pragma: no cover - without Dask, run_dask says how to install it
        return
    settings = spec.dask or settings_from_config()
    check_scheduler(spec.address, settings, security_for(spec.address, settings))


def _run_dask(todo: Sequence[_Pending], finish, spec: ExecutorSpec) -> None:
    from analysis.sweep.dask_executor import run_dask

    run_dask(todo, finish, spec, call_task, _crash_record)
