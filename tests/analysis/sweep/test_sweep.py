"""Sweeps: identical results whatever the executor, resumable, crash- and error-tolerant."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest
from sweep_tasks import DrawConfig, FlakyConfig, draw, flaky

from analysis.sweep import ResultStore, Task, derive_seed, parse_executor, run_sweep

TESTS_DIR = Path(__file__).parents[2]


def _tasks(n=6, **kw):
    return [Task(f"draw-{i}", draw, DrawConfig(n=3 + i, **kw)) for i in range(n)]


def test_derive_seed_depends_on_sweep_seed_and_key_only():
    assert derive_seed(7, "a") == derive_seed(7, "a")
    assert len({derive_seed(7, "a"), derive_seed(7, "b"), derive_seed(8, "a")}) == 3
    assert 0 <= derive_seed(123, "x") < 2**63


def test_parse_executor_rejects_bad_values():
    assert parse_executor("process:3").workers == 3
    assert parse_executor("dask://10.0.0.1:8786").address == "tcp://10.0.0.1:8786"
    for bad in ("threads", "process:0", "process:x", "dask://nohost", "serial:2"):
        with pytest.raises(ValueError, match="--executor"):
            parse_executor(bad)


def test_serial_process_and_dask_local_agree(monkeypatch):
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(TESTS_DIR), os.environ.get("PYTHONPATH", "")]))
    serial = run_sweep(_tasks(), seed=5, executor="serial", progress=False)
    pool = run_sweep(reversed(_tasks()), seed=5, executor="process:2", progress=False)
    dask = run_sweep(_tasks(), seed=5, executor="dask-local:2", progress=False)
    assert serial.ok and pool.ok and dask.ok
    assert list(serial.results) == [f"draw-{i}" for i in range(6)]
    assert serial.results == dict(pool.results) == dask.results
    other = run_sweep(_tasks(), seed=6, executor="serial", progress=False)
    assert other.results != serial.results


def test_store_skips_finished_tasks(tmp_path):
    store = ResultStore(tmp_path / "store")
    first = run_sweep(_tasks(4), seed=1, executor="serial", store=store, progress=False)
    assert (first.n_cached, first.n_run) == (0, 4)
    second = run_sweep(_tasks(5), seed=1, executor="serial", store=store, progress=False)
    assert (second.n_cached, second.n_run) == (4, 1)
    assert {k: second.results[k] for k in first.results} == first.results


def test_truncated_result_file_is_not_read_as_complete(tmp_path):
    store = ResultStore(tmp_path)
    run_sweep(_tasks(2), seed=1, executor="serial", store=store, progress=False)
    files = sorted(tmp_path.glob("*.json"))
    files[0].write_text(files[0].read_text()[:20])
    again = run_sweep(_tasks(2), seed=1, executor="serial", store=store, progress=False)
    assert (again.n_cached, again.n_run) == (1, 1)


def test_errors_and_crashes_are_retried_and_reported(tmp_path):
    marker = tmp_path / "m"
    marker.mkdir()
    tasks = [
        Task("raises", flaky, FlakyConfig("raise")),
        Task("crashes", flaky, FlakyConfig("crash")),
        Task("recovers", flaky, FlakyConfig("raise-once", str(marker))),
        *_tasks(3),
    ]
    report = run_sweep(tasks, seed=0, executor="process:2", progress=False)
    assert not report.ok
    failed = {f.key: f for f in report.failures}
    assert set(failed) == {"raises", "crashes"}
    assert failed["raises"].attempts == 2 and "on purpose" in failed["raises"].error
    assert failed["crashes"].attempts == 2 and "died" in failed["crashes"].error
    assert report.results["recovers"] == {"attempt": 2}
    assert all(f"draw-{i}" in report.results for i in range(3))


def test_an_error_that_says_retry_false_is_not_run_again(capsys):
    """A PolicyError (retry = False: a callable's bad return fails the same way every time) fails
    after one attempt, with no 'running it again' line; other errors keep their retry."""
    tasks = [Task("bad-policy", flaky, FlakyConfig("policy-error")), Task("raises", flaky, FlakyConfig("raise"))]
    report = run_sweep(tasks, seed=0, executor="serial", progress=False, desc="t")
    failed = {f.key: f for f in report.failures}
    assert failed["bad-policy"].attempts == 1 and "returned action 7" in failed["bad-policy"].error
    assert failed["raises"].attempts == 2
    err = capsys.readouterr().err
    assert "bad-policy failed" not in err and "raises failed" in err, err


def test_unguarded_script_reports_the_main_guard(tmp_path):
    """A script that runs a process sweep at module level: each worker re-imports it and stops at
    run_sweep (instead of starting a sweep of its own); the failures name the missing guard."""
    imports = tmp_path / "imports"
    script = tmp_path / "unguarded.py"
    script.write_text(textwrap.dedent(f"""
        import sys
        sys.path[:0] = [{str(TESTS_DIR.parent)!r}, {str(TESTS_DIR)!r}]  # the checkout first: tests/analysis/ must not shadow analysis
        with open({str(imports)!r}, "a") as f:
            f.write("x")
        from analysis.sweep import Task, run_sweep
        from sweep_tasks import DrawConfig, draw
        report = run_sweep([Task("a", draw, DrawConfig(n=3))], seed=0, executor="process:1", progress=False)
        print(report.failures[0].error)
    """))
    out = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=240, cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    assert 'if __name__ == "__main__":' in out.stdout  # the failure says what to change
    assert "a sweep was started while a worker process imported the main script" in out.stderr  # the workers'
    # the script, the pool's worker (a pool-wide crash is not counted), then the task alone and its retry
    assert len(imports.read_text()) == 4


def test_killed_sweep_resumes_to_the_same_results(tmp_path):
    store_dir = tmp_path / "store"
    marker = tmp_path / "markers"
    marker.mkdir()
    script = textwrap.dedent(f"""
        import sys
        sys.path[:0] = [{str(TESTS_DIR.parent)!r}, {str(TESTS_DIR)!r}]  # the checkout first: tests/analysis/ must not shadow analysis
        from analysis.sweep import Task, run_sweep
        from sweep_tasks import DrawConfig, draw
        tasks = [Task(f"draw-{{i}}", draw, DrawConfig(n=4, sleep_s=0.3, marker_dir={str(marker)!r}))
                 for i in range(12)]
        run_sweep(tasks, seed=3, executor="serial", store={str(store_dir)!r}, progress=False)
    """)
    proc = subprocess.Popen([sys.executable, "-c", script], start_new_session=True)
    deadline = time.time() + 60
    while len(list(store_dir.glob("*.json"))) < 3 and time.time() < deadline:
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    n_before = len(list(store_dir.glob("*.json")))
    assert 3 <= n_before < 12
    tasks = [Task(f"draw-{i}", draw, DrawConfig(n=4, sleep_s=0.3, marker_dir=str(marker)))
             for i in range(12)]
    resumed = run_sweep(tasks, seed=3, executor="serial", store=store_dir, progress=False)
    assert resumed.n_cached == n_before and resumed.ok
    fresh = run_sweep(tasks, seed=3, executor="serial", progress=False)
    assert resumed.results == fresh.results


def test_duplicate_keys_are_rejected():
    with pytest.raises(ValueError, match="unique"):
        run_sweep([Task("a", draw, DrawConfig(1)), Task("a", draw, DrawConfig(2))], executor="serial",
                  progress=False)
