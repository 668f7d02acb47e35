"""A user's ``--policy`` that misbehaves in ways no return value shows: a callable that blocks
forever stops the evaluation at its time limit (one line, exit 2, in the pool and under Dask), and
nothing of the run is left behind (worker processes, partial recordings)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
import uuid

import psutil
import pytest

from sim.drivers.callables.limits import DecisionTimeout, call_with_limit, check_limit
from sim.drivers.policy import PolicyError

#: A callable that never returns: sleeps (a network call), and one that spins and swallows
#: every Exception (an endless loop written defensively).
BLOCKING = '''
import time


def hang(obs):
    while True:
        time.sleep(0.5)


def spin(obs):
    while True:
        try:
            sum(range(1000))
        except Exception:
            pass
'''


def _cli(*args: str, marker: str, timeout: float = 240) -> subprocess.CompletedProcess:
    env = dict(os.environ, MERGE_IRL_TEST_MARK=marker)
    return subprocess.run([sys.executable, "-m", "analysis", "evaluate", *args], capture_output=True, text=True,
                          timeout=timeout, env=env)


def _processes_marked(marker: str) -> list[psutil.Process]:
    """Every process still alive that inherited the test's environment marker (the command's workers)."""
    found = []
    for p in psutil.process_iter():
        try:
            if p.environ().get("MERGE_IRL_TEST_MARK") == marker:
                found.append(p)
        except (psutil.Error, OSError):
            continue
    return found


def _gone(marker: str, within_s: float = 15.0) -> list[psutil.Process]:
    deadline = time.monotonic() + within_s
    while time.monotonic() < deadline:
        left = _processes_marked(marker)
        if not left:
            return []
        time.sleep(0.5)
    return _processes_marked(marker)


def test_a_blocking_callable_is_stopped_in_the_main_thread_and_in_another() -> None:
    def hang(obs):
        while True:
            try:
                time.sleep(0.2)
            except Exception:  # a callable's own guard does not swallow the time-out
                pass

    t0 = time.monotonic()
    with pytest.raises(DecisionTimeout, match=r"policy 'x': no action within 0.5 s .*--policy-timeout"):
        call_with_limit(hang, None, 0.5, where="policy 'x'")
    assert time.monotonic() - t0 < 3.0

    caught: list[BaseException] = []

    def in_thread() -> None:  # a Dask worker runs tasks in a thread: no SIGALRM there
        try:
            call_with_limit(hang, None, 0.5, where="policy 'y'")
        except BaseException as e:  # noqa: BLE001
            caught.append(e)

    t = threading.Thread(target=in_thread)
    t0 = time.monotonic()
    t.start()
    t.join(10)
    assert not t.is_alive() and time.monotonic() - t0 < 3.0
    assert len(caught) == 1 and isinstance(caught[0], DecisionTimeout) and "policy 'y'" in str(caught[0])
    assert DecisionTimeout.abort and not DecisionTimeout.retry
    # an answer in time is returned, an error of the callable passes unchanged, the alarm is off after
    assert call_with_limit(lambda o: o + 1, 1, 5.0, where="p") == 2
    with pytest.raises(ZeroDivisionError):
        call_with_limit(lambda o: 1 / o, 0, 5.0, where="p")
    assert signal.getitimer(signal.ITIMER_REAL) == (0.0, 0.0)
    for bad in (0, -1, float("inf"), float("nan"), "x"):
        with pytest.raises(PolicyError, match="--policy-timeout"):
            check_limit(bad)


@pytest.mark.sumo
@pytest.mark.parametrize("executor", ["process:2", "dask-local:1"])
def test_blocking_policy_stops_the_evaluation_in_one_line(tmp_path, executor) -> None:
    if executor.startswith("dask"):
        pytest.importorskip("distributed")
    rules = tmp_path / "rules.py"
    rules.write_text(BLOCKING)
    out = tmp_path / "ev"
    marker = uuid.uuid4().hex
    t0 = time.monotonic()
    r = _cli("--policy", f"{rules}:hang", "--policy", f"{rules}:spin", "--baselines", "sumo", "--episodes", "3",
             "--duration", "90", "--policy-timeout", "2", "--executor", executor, "--no-progress",
             "--out", str(out), marker=marker)
    wall = time.monotonic() - t0
    assert r.returncode == 2, r.stderr
    lines = [ln for ln in r.stderr.splitlines() if ln.startswith("merge-irl evaluate: error")]
    assert len(lines) == 1 and "Traceback" not in r.stderr, r.stderr
    assert "DecisionTimeout" in lines[0] and "--policy-timeout" in lines[0] and "no action within 2 s" in lines[0]
    assert "policy 'hang'" in lines[0] or "policy 'spin'" in lines[0]
    assert "(the evaluation stopped there)" in lines[0]
    assert wall < 150, f"{wall:.0f} s: the evaluation waited out more than one time-out"
    assert _gone(marker) == []
    assert not out.exists(), sorted(str(p) for p in out.rglob("*"))  # no .partial recording, no folder


@pytest.mark.sumo
def test_ctrl_c_ends_a_blocked_evaluation_with_130_and_nothing_left(tmp_path) -> None:
    rules = tmp_path / "rules.py"
    rules.write_text(BLOCKING)
    out = tmp_path / "ev"
    marker = uuid.uuid4().hex
    env = dict(os.environ, MERGE_IRL_TEST_MARK=marker)
    proc = subprocess.Popen([sys.executable, "-m", "analysis", "evaluate", "--policy", f"{rules}:hang", "--baselines",
                             "sumo", "--episodes", "2", "--duration", "90", "--executor", "process:2", "--no-progress",
                             "--out", str(out)], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        deadline = time.monotonic() + 120
        while not list(out.glob("rerun/.hang.rrd.*.tmp.partial")):  # the blocked episode is recording
            assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()
            time.sleep(0.5)
        time.sleep(1.0)
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, err
    assert err.strip().splitlines()[-1] == "merge-irl evaluate: interrupted" and "Traceback" not in err
    assert _gone(marker) == []
    assert not out.exists(), sorted(str(p) for p in out.rglob("*"))


@pytest.mark.parametrize("specs, words", [
    (["{r}:hang:sumo"], "its name 'sumo' is also the baseline 'sumo' of this evaluation"),
    (["{r}:hang:x", "{r}:spin:x"], "two policies are named 'x'"),
])
def test_a_name_that_would_be_ambiguous_is_refused(tmp_path, specs, words) -> None:
    rules = tmp_path / "rules.py"
    rules.write_text(BLOCKING)
    args = [a for spec in specs for a in ("--policy", spec.format(r=rules))]
    r = _cli(*args, "--baselines", "sumo", "--episodes", "1", "--duration", "90", "--out", str(tmp_path / "ev"),
             marker="none", timeout=120)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and words in r.stderr, r.stderr
    assert "give it a name of its own" in r.stderr or "give each a name of its own" in r.stderr
    assert not (tmp_path / "ev").exists()
