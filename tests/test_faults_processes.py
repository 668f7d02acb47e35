"""Process faults, injected for real: a sweep parent killed or interrupted; its workers must
die with it, what finished must be stored."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import psutil
import pytest
from sim_testutil import default_sigint
from sweep_tasks import DrawConfig, draw

from analysis.sweep import ResultStore, Task, run_sweep

TESTS_DIR = Path(__file__).resolve().parent


def _sweep_script(store: Path, tasks_src: str, workers: int = 2) -> str:
    return textwrap.dedent(f"""
        import sys
        sys.path[:0] = [{str(TESTS_DIR.parent)!r}, {str(TESTS_DIR)!r}]  # the checkout first: tests/analysis/ must not shadow analysis
        from analysis.sweep import Task, run_sweep
        from sweep_tasks import DrawConfig, draw
        tasks = {tasks_src}
        run_sweep(tasks, seed=1, executor="process:{workers}", store={str(store)!r}, progress=False)
    """)


def _workers_of(pid: int, n: int, timeout: float = 60.0) -> list[psutil.Process]:
    """Wait until process ``pid`` has ``n`` pool workers (and whatever else: resource tracker)."""
    parent = psutil.Process(pid)
    deadline = time.time() + timeout
    while time.time() < deadline:
        kids = parent.children(recursive=True)
        workers = [k for k in kids if "spawn_main" in " ".join(_cmdline(k))]
        if len(workers) >= n:
            return kids
        time.sleep(0.05)
    raise AssertionError(f"no {n} pool workers under {pid} after {timeout} s")


def _cmdline(p: psutil.Process) -> list[str]:
    try:
        return p.cmdline()
    except psutil.Error:
        return []


def _gone_within(procs: list[psutil.Process], timeout: float) -> list[psutil.Process]:
    _, alive = psutil.wait_procs(procs, timeout=timeout)
    return alive


@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGTERM], ids=["SIGKILL", "SIGTERM"])
def test_pool_workers_die_with_the_sweep_parent(tmp_path, sig):
    tasks = "[Task(f'slow-{i}', draw, DrawConfig(n=2, sleep_s=120)) for i in range(4)]"
    proc = subprocess.Popen([sys.executable, "-c", _sweep_script(tmp_path / "store", tasks)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        kids = _workers_of(proc.pid, 2)
        time.sleep(0.5)  # the workers are inside their (two-minute) tasks
        proc.send_signal(sig)  # to the parent alone, not its process group
        proc.wait(timeout=30)
        alive = _gone_within(kids, 5.0)
        assert not alive, f"still running 5 s after the parent's {sig.name}: {[_cmdline(p) for p in alive]}"
        # nobody holds the parent's output any more: reading it to the end returns
        proc.communicate(timeout=5)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert not list((tmp_path / "store").glob("*.json"))


def test_interrupted_sweep_stores_what_finished_and_stops_at_once(tmp_path):
    store = tmp_path / "store"
    tasks = ("[Task(f'quick-{i}', draw, DrawConfig(n=2)) for i in range(3)]"
             " + [Task('slow', draw, DrawConfig(n=2, sleep_s=120))]")
    proc = subprocess.Popen([sys.executable, "-c", _sweep_script(store, tasks)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=default_sigint)
    try:
        deadline = time.time() + 60
        while len(list(store.glob("*.json"))) < 3 and time.time() < deadline:
            time.sleep(0.05)
        kids = _workers_of(proc.pid, 1)
        time.sleep(0.3)
        t0 = time.time()
        proc.send_signal(signal.SIGINT)  # Ctrl-C to the parent
        _, err = proc.communicate(timeout=30)
        stopped_after = time.time() - t0
    finally:
        if proc.poll() is None:
            proc.kill()
    assert "KeyboardInterrupt" in err
    assert stopped_after < 10, f"the parent waited {stopped_after:.0f} s for the run in flight"
    assert not _gone_within(kids, 5.0)
    # the three finished tasks are stored and a rerun takes them from the store
    full = [Task(f"quick-{i}", draw, DrawConfig(n=2)) for i in range(3)]
    rerun = run_sweep(full, seed=1, executor="serial", store=ResultStore(store), progress=False)
    assert rerun.n_cached == 3 and rerun.n_run == 0


def test_generate_sweep_sigterm_stops_workers_and_publishes_nothing_half_done(tmp_path):
    """The CLI: SIGTERM is handled like Ctrl-C (exit 130, one line), the SUMO workers die, no run
    folder exists under its final name, and the lock is free for a rerun."""
    out = tmp_path / "sweep"
    env = dict(os.environ, MERGE_IRL_CACHE=str(tmp_path / "cache"))
    proc = subprocess.Popen([sys.executable, "-m", "analysis", "generate", "--scenario", "i80", "--duration", "3000",
                             "--seeds", "1-4", "--executor", "process:2", "--no-progress", "--out", str(out)],
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        kids = _workers_of(proc.pid, 2)
        deadline = time.time() + 60  # both workers have started simulating (their staging folders exist)
        while len(list(out.glob(".i80-seed*.tmpdir"))) < 2 and time.time() < deadline:
            time.sleep(0.05)
        time.sleep(0.5)
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, err
    assert err.strip().splitlines()[-1] == "merge-irl generate: interrupted"
    assert not _gone_within(kids, 5.0)
    assert list(out.glob("i80-seed*")) == []  # no run folder published half-done


def test_pool_worker_killed_like_the_oom_killer_is_retried_and_said(tmp_path, capsys):
    """SIGKILL of a process-pool worker (what the out-of-memory killer sends) mid-task: the task
    runs again and succeeds, and a line on stderr names it, the signal and the rerun."""
    from sweep_tasks import SleepConfig, mark_then_sleep

    markers = tmp_path / "markers"
    markers.mkdir()
    killed: list[int] = []

    def kill_first_worker() -> None:
        deadline = time.time() + 60
        while time.time() < deadline:
            started = list(markers.glob("started-*"))
            if started:
                pid = int(started[0].name.split("-")[1])
                os.kill(pid, signal.SIGKILL)
                killed.append(pid)
                return
            time.sleep(0.02)

    import threading

    killer = threading.Thread(target=kill_first_worker, daemon=True)
    killer.start()
    report = run_sweep([Task("big", mark_then_sleep, SleepConfig(sleep_s=1.0, marker_dir=str(markers)))],
                       executor="process:1", progress=False, desc="oom")
    killer.join(5)
    err = capsys.readouterr().err
    assert killed, "the task never started"
    assert report.ok and report.results["big"]["pid"] != killed[0]
    said = [line for line in err.splitlines() if "big" in line]
    assert said and "killed by SIGKILL" in said[0] and "again" in said[0], err
    assert "Traceback" not in err


def test_failed_sweep_prints_no_traceback_after_its_lines(tmp_path):
    """``generate`` with a run that fails on every attempt (its run folder's path is a file): the
    FAILED line, the retry said, the tracebacks in a file, none on stderr."""
    out = tmp_path / "sweep"
    out.mkdir()
    (out / "synthetic-seed1").write_text("a file where the run's folder goes")
    env = dict(os.environ, MERGE_IRL_CACHE=str(tmp_path / "cache"))
    proc = subprocess.run([sys.executable, "-m", "analysis", "generate", "--seeds", "1", "--duration", "70",
                           "--executor", "serial", "--no-progress", "--out", str(out)],
                          env=env, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 1, proc.stderr
    assert "Traceback" not in proc.stderr and 'File "' not in proc.stderr, proc.stderr
    assert "FAILED synthetic-seed1 after 2 attempt(s)" in proc.stderr
    assert "running it again (attempt 2 of 2)" in proc.stderr
    log = out / "sweep.failures.log"
    assert f"tracebacks: {log}" in proc.stderr
    assert "Traceback" in log.read_text()


@pytest.mark.sumo
def test_workers_killed_on_a_blocked_policy_leave_no_temporary_folders(tmp_path):
    """``evaluate`` on ``process:2`` with a policy that never answers: the time-out aborts the
    sweep and the parent kills both workers mid-simulation; their SUMO run folders
    (``merge-irl-run-*``, in the workers' temporary directory) are removed with the pool's."""
    rules = tmp_path / "rules.py"
    rules.write_text("import time\n\n\ndef hang(obs):\n    while True:\n        time.sleep(0.5)\n")
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    env = dict(os.environ, TMPDIR=str(tmp), MERGE_IRL_CACHE=str(tmp_path / "cache"))
    proc = subprocess.run([sys.executable, "-m", "analysis", "evaluate", "--policy", f"{rules}:hang", "--baselines",
                           "sumo", "--episodes", "2", "--duration", "90", "--policy-timeout", "2", "--executor",
                           "process:2", "--no-progress", "--out", str(tmp_path / "ev")],
                          env=env, capture_output=True, text=True, timeout=240)
    assert proc.returncode == 2 and "no action within 2 s" in proc.stderr, proc.stderr
    left = sorted(p.name for p in tmp.iterdir())
    assert left == [], left
