"""``--executor dask://HOST:PORT`` / ``tls://HOST:PORT`` against real faults on loopback:
a real ``dask scheduler`` whose only worker (no nanny) is killed, one with no
worker, a plain TCP listener that never answers, a port answering HTTP 400, and a TLS scheduler
with self-signed certificates made here. Every wait is bounded (subprocess timeouts)."""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

import pytest
from sim_testutil import default_sigint
from sweep_tasks import DrawConfig, draw

pytest.importorskip("distributed")

from analysis.sweep import Task, parse_executor, run_sweep  # noqa: E402
from analysis.sweep.executors import DaskSettings, DaskUnavailable  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
TESTS_DIR = Path(__file__).resolve().parent


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _env(tmp_path: Path) -> dict[str, str]:
    """The children import this checkout (and the tests' task functions) and cache in tmp_path."""
    path = os.pathsep.join([str(ROOT), str(TESTS_DIR), os.environ.get("PYTHONPATH", "")])
    return dict(os.environ, PYTHONPATH=path, MERGE_IRL_CACHE=str(tmp_path / "cache"))


def _wait_for(predicate, timeout: float, what: str) -> None:
    deadline = time.time() + timeout
    while time.time() < deadline:
        if predicate():
            return
        time.sleep(0.05)
    raise AssertionError(f"{what}: not within {timeout} s")


def _stop(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        proc.kill()
    proc.wait(timeout=10)


@contextlib.contextmanager
def _dask(tmp_path: Path, *, workers: int, tls: list[str] | None = None) -> Iterator[tuple[str, list]]:
    """A real ``dask scheduler`` on loopback and ``workers`` workers without a nanny; yields the
    scheduler's address and the worker processes. ``tls``: the ``--tls-*`` options of both."""
    port = _free_port()
    protocol = "tls" if tls else "tcp"
    log = tmp_path / f"scheduler-{port}.log"
    env = _env(tmp_path)
    sec = tls or []
    procs = []
    with open(log, "w") as log_file:
        sched = subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
                                  "--port", str(port), "--protocol", protocol, "--no-dashboard", *sec],
                                 env=env, stdout=log_file, stderr=subprocess.STDOUT, cwd=tmp_path)
        procs.append(sched)
        try:
            _wait_for(lambda: "Scheduler at" in log.read_text() or sched.poll() is not None, 60, "scheduler up")
            assert sched.poll() is None, log.read_text()
            address = f"{protocol}://127.0.0.1:{port}"
            kids = []
            for _ in range(workers):
                kids.append(subprocess.Popen(
                    [sys.executable, "-m", "distributed.cli.dask_worker", address, "--no-nanny", "--nthreads", "1",
                     "--no-dashboard", *sec], env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                    cwd=tmp_path))
            procs.extend(kids)
            _wait_for(lambda: log.read_text().count("Register worker") >= workers, 60, "workers registered")
            yield address, kids
        finally:
            for p in reversed(procs):
                _stop(p)


class _Listener:
    """A loopback TCP server in a thread: ``silent`` accepts and never answers; ``http`` answers
    whatever it is sent with an HTTP 400 reply and closes, as a web server does."""

    def __init__(self, mode: str) -> None:
        self.mode = mode
        self.sock = socket.socket()
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen(8)
        self.port = self.sock.getsockname()[1]
        self.accepted = threading.Event()
        self._conns: list[socket.socket] = []
        threading.Thread(target=self._serve, daemon=True).start()

    def _serve(self) -> None:
        while True:
            try:
                conn, _ = self.sock.accept()
            except OSError:
                return
            self.accepted.set()
            if self.mode == "http":
                with contextlib.suppress(OSError):
                    conn.recv(4096)
                    conn.sendall(b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\nConnection: close\r\n\r\n")
                conn.close()
            else:
                self._conns.append(conn)

    def close(self) -> None:
        self.sock.close()
        for c in self._conns:
            c.close()


@pytest.fixture
def listener(request):
    lst = _Listener(request.param)
    yield lst
    lst.close()


def _generate(out: Path, executor: str, *extra: str) -> list[str]:
    return [sys.executable, "-m", "analysis", "generate", "--scenario", "synthetic", "--seeds", "1",
            "--duration", "3000", "--executor", executor, "--no-progress", "--out", str(out), *extra]


def _assert_cleaned(out: Path) -> None:
    """No lock beside ``--out`` and none, nor a staging folder, inside it."""
    assert not (out.parent / f".{out.name}.lock").exists()
    if out.exists():
        left = [p.name for p in out.iterdir() if p.name.endswith(".lock") or p.name.endswith(".tmpdir")]
        assert left == []


def _assert_nothing_created(out: Path) -> None:
    """A sweep that never reached a scheduler created nothing: no ``--out`` (no ``.sweep-store/``,
    ``sweep.csv`` nor ``sweep.timings.json``) and no lock beside it."""
    assert not out.exists(), sorted(p.name for p in out.iterdir())
    assert not (out.parent / f".{out.name}.lock").exists()


def _one_line_exit_2(proc: subprocess.CompletedProcess | subprocess.Popen, err: str) -> str:
    lines = err.strip().splitlines()
    assert proc.returncode == 2 and len(lines) == 1, err
    assert lines[0].startswith("merge-irl generate: error: Dask scheduler "), err
    return lines[0]


# -- item 1: nothing that is a Dask scheduler on the port -----------------------------------------------

@pytest.mark.parametrize("listener", ["silent", "http"], indirect=True)
def test_a_port_that_is_not_a_dask_scheduler_fails_in_one_line(tmp_path, listener):
    out = tmp_path / "sweep"
    address = f"127.0.0.1:{listener.port}"
    t0 = time.time()
    proc = subprocess.run(_generate(out, f"dask://{address}", "--dask-connect-timeout", "2"),
                          env=_env(tmp_path), capture_output=True, text=True, timeout=120)
    line = _one_line_exit_2(proc, proc.stderr)
    assert f"tcp://{address}" in line
    assert ("no answer within 2 s" in line) if listener.mode == "silent" else ("Dask's protocol" in line)
    assert time.time() - t0 < 60
    _assert_nothing_created(out)


@pytest.mark.parametrize("listener", ["silent"], indirect=True)
def test_with_progress_lines_an_unusable_scheduler_is_still_one_line(tmp_path, listener):
    """Progress on (the default) and stderr not a terminal, as in CI: before, a '(started)' and a
    '(stopped)' progress line came before the error; now the scheduler is asked before the bar."""
    out = tmp_path / "sweep"
    argv = [a for a in _generate(out, f"dask://127.0.0.1:{listener.port}", "--dask-connect-timeout", "2")
            if a != "--no-progress"]
    proc = subprocess.run(argv, env=_env(tmp_path), capture_output=True, text=True, timeout=120)
    assert "no answer within 2 s" in _one_line_exit_2(proc, proc.stderr)
    _assert_nothing_created(out)


@pytest.mark.parametrize("listener", ["silent"], indirect=True)
def test_connect_timeout_inside_a_running_event_loop(listener):
    """As from a notebook, whose thread runs an event loop: the same one error, not asyncio's."""
    import asyncio

    from analysis.sweep.dask_executor import check_scheduler, security_for

    address = f"tcp://127.0.0.1:{listener.port}"
    settings = DaskSettings(connect_timeout_s=1.0)

    async def in_a_loop() -> None:
        check_scheduler(address, settings, security_for(address, settings))

    with pytest.raises(DaskUnavailable, match=r"no answer within 1 s"):
        asyncio.run(in_a_loop())


def test_nothing_listening_fails_in_one_line(tmp_path):
    out = tmp_path / "sweep"
    port = _free_port()
    proc = subprocess.run(_generate(out, f"dask://127.0.0.1:{port}", "--dask-connect-timeout", "2"),
                          env=_env(tmp_path), capture_output=True, text=True, timeout=120)
    assert f"tcp://127.0.0.1:{port}" in _one_line_exit_2(proc, proc.stderr)
    _assert_nothing_created(out)


def test_a_failed_connect_keeps_what_was_in_out_and_adds_nothing(tmp_path):
    """An --out that holds a file already: it is kept, and nothing of the sweep is added."""
    out = tmp_path / "sweep"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    proc = subprocess.run(_generate(out, f"dask://127.0.0.1:{_free_port()}", "--dask-connect-timeout", "2"),
                          env=_env(tmp_path), capture_output=True, text=True, timeout=120)
    _one_line_exit_2(proc, proc.stderr)
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt"]
    assert (out / "notes.txt").read_text() == "mine"


@pytest.mark.parametrize("listener", ["silent"], indirect=True)
def test_ctrl_c_while_connecting_exits_130_and_cleans(tmp_path, listener):
    out = tmp_path / "sweep"
    proc = subprocess.Popen(_generate(out, f"dask://127.0.0.1:{listener.port}", "--dask-connect-timeout", "300"),
                            env=_env(tmp_path), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=default_sigint)
    def connected() -> None:
        assert listener.accepted.wait(60), "the sweep never connected"
    _assert_ctrl_c_exits_130_and_cleans(proc, out, connected, settle_s=0.3)


def _assert_ctrl_c_exits_130_and_cleans(proc: subprocess.Popen, out, ready, settle_s: float) -> None:
    """Once ``ready()`` returns and ``settle_s`` passed, SIGINT: exit 130 within 20 s, one line, ``out`` clean."""
    try:
        ready()
        time.sleep(settle_s)
        t0 = time.time()
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=30)
        stopped_after = time.time() - t0
    finally:
        _stop(proc)
    assert proc.returncode == 130, err
    assert err.strip().splitlines() == ["merge-irl generate: interrupted"], err
    assert stopped_after < 20
    _assert_cleaned(out)


# -- item 1: a real scheduler whose workers are gone --------------------------------------------------

def test_ctrl_c_while_waiting_for_workers_exits_130_and_cleans(tmp_path):
    out = tmp_path / "sweep"
    with _dask(tmp_path, workers=0) as (address, _):
        log = tmp_path / f"scheduler-{address.rsplit(':', 1)[1]}.log"
        proc = subprocess.Popen(_generate(out, address.replace("tcp://", "dask://")), env=_env(tmp_path),
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=default_sigint)
        # settle 1 s: the task is submitted and waits for a worker
        _assert_ctrl_c_exits_130_and_cleans(
            proc, out, lambda: _wait_for(lambda: "Receive client connection" in log.read_text(), 60, "client connected"),
            settle_s=1.0)


@pytest.mark.sumo
def test_only_worker_killed_without_nanny_stops_after_the_stall_timeout(tmp_path):
    """The worker (no nanny) dies mid-run, SIGKILL: the sweep stops after --dask-stall-timeout with
    one line naming the address; its staging folder and locks are removed."""
    out = tmp_path / "sweep"
    with _dask(tmp_path, workers=1) as (address, (worker,)):
        proc = subprocess.Popen(_generate(out, address.replace("tcp://", "dask://"), "--dask-stall-timeout", "3"),
                                env=_env(tmp_path), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            _wait_for(lambda: out.exists() and any(p.name.endswith(".tmpdir") for p in out.iterdir()), 90,
                      "the worker started the run")
            worker.kill()
            t0 = time.time()
            _, err = proc.communicate(timeout=60)
            stopped_after = time.time() - t0
        finally:
            _stop(proc)
    line = _one_line_exit_2(proc, err)
    assert address in line and "--dask-stall-timeout" in line
    assert stopped_after < 50  # the stall timeout (3 s) and a bounded shutdown, on a loaded machine
    _assert_cleaned(out)


def test_a_task_running_longer_than_the_stall_timeout_is_not_stopped(tmp_path):
    """A task that runs on a live worker is progress, however long it takes."""
    with _dask(tmp_path, workers=1) as (address, _):
        spec = replace(parse_executor(address.replace("tcp://", "dask://")),
                       dask=DaskSettings(connect_timeout_s=20, stall_timeout_s=1.5))
        report = run_sweep([Task("long", draw, DrawConfig(n=2, sleep_s=5.0))], seed=2, executor=spec, progress=False)
    assert report.ok and list(report.results) == ["long"]


# -- item 16: TLS -----------------------------------------------------------------------------------------

def _self_signed(tmp_path: Path) -> tuple[Path, Path]:
    """A self-signed certificate and key for 127.0.0.1 (CA, scheduler, worker and client alike)."""
    openssl = shutil.which("openssl")
    if openssl is None:
        pytest.skip("no openssl command to make a certificate with")
    cert, key = tmp_path / "cert.pem", tmp_path / "key.pem"
    subprocess.run([openssl, "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days", "1", "-subj", "/CN=127.0.0.1",
                    "-addext", "subjectAltName=IP:127.0.0.1", "-keyout", str(key), "-out", str(cert)],
                   check=True, capture_output=True, timeout=60)
    return cert, key


def test_tls_scheduler_with_self_signed_certificates(tmp_path):
    cert, key = _self_signed(tmp_path)
    tasks = [Task(f"t{i}", draw, DrawConfig(n=3)) for i in range(3)]
    serial = run_sweep(tasks, seed=4, executor="serial", progress=False)
    tls = ["--tls-ca-file", str(cert), "--tls-cert", str(cert), "--tls-key", str(key)]
    with _dask(tmp_path, workers=1, tls=tls) as (address, _):
        assert address.startswith("tls://")
        spec = parse_executor(address)
        assert spec.address == address
        quick = DaskSettings(connect_timeout_s=10, stall_timeout_s=60)
        # certificates given as files (the --dask-tls-* options)
        given = run_sweep(tasks, seed=4, progress=False, executor=replace(
            spec, dask=replace(quick, tls_ca_file=str(cert), tls_cert=str(cert), tls_key=str(key))))
        assert given.ok and given.results == serial.results
        # certificates from Dask's configuration (its files or DASK_DISTRIBUTED__COMM__TLS__* variables)
        import dask.config

        with dask.config.set({"distributed.comm.tls.ca-file": str(cert), "distributed.comm.tls.client.cert": str(cert),
                              "distributed.comm.tls.client.key": str(key)}):
            configured = run_sweep(tasks, seed=4, progress=False, executor=replace(spec, dask=quick))
        assert configured.ok and configured.results == serial.results
        # without certificates, and in plain TCP: one line each, naming the address
        with pytest.raises(DaskUnavailable, match=r"TLS needs --dask-tls-ca-file and --dask-tls-cert"):
            run_sweep(tasks, progress=False, executor=replace(spec, dask=quick))
        plain = parse_executor(address.replace("tls://", "dask://"))
        with pytest.raises(DaskUnavailable, match=address.replace("tls://", "tcp://")):
            run_sweep(tasks, progress=False, executor=replace(plain, dask=replace(quick, connect_timeout_s=3)))
        # a certificate from another authority: which side refused which file
        (tmp_path / "other").mkdir()
        other, other_key = _self_signed(tmp_path / "other")
        with pytest.raises(DaskUnavailable, match=r"TLS: this client refused the scheduler's certificate "
                           r"\(self-signed certificate\): it does not verify against the CA file "
                           + str(other) + r" \(--dask-tls-ca-file\)"):
            run_sweep(tasks, progress=False, executor=replace(spec, dask=replace(
                quick, connect_timeout_s=10, tls_ca_file=str(other), tls_cert=str(other), tls_key=str(other_key))))
        # the right CA, a client certificate the scheduler does not trust: the scheduler refused it
        with pytest.raises(DaskUnavailable, match=r"TLS: the scheduler ended the handshake .*: it refused this "
                           r"client's certificate " + str(other) + r" \(--dask-tls-cert\)"):
            run_sweep(tasks, progress=False, executor=replace(spec, dask=replace(
                quick, connect_timeout_s=10, tls_ca_file=str(cert), tls_cert=str(other), tls_key=str(other_key))))


def test_tls_from_the_command_line(tmp_path):
    """``generate --executor tls://... --dask-tls-*``: a bad certificate path is one line, exit 2;
    tls:// parses."""
    out = tmp_path / "sweep"
    proc = subprocess.run(_generate(out, "tls://127.0.0.1:1", "--dask-tls-ca-file", str(tmp_path / "missing.pem")),
                          env=_env(tmp_path), capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.strip().splitlines() == [
        f"merge-irl generate: error: --dask-tls-ca-file {tmp_path / 'missing.pem'}: no such file"]
    assert parse_executor("tls://h:8786").address == "tls://h:8786"
    for bad in ("tls://nohost", "tls://h:0", "dask://h:99999"):
        with pytest.raises(ValueError):
            parse_executor(bad)


@pytest.mark.parametrize("executor", ["dask://127.0.0.1:1", "process:1", None])
def test_tls_files_without_a_tls_address_are_refused_at_once(tmp_path, executor):
    """--dask-tls-* with dask:// waited 121 s despite a 10 s connect timeout."""
    cert, key = _self_signed(tmp_path)
    out = tmp_path / "sweep"
    cmd = _generate(out, executor or "serial", "--dask-tls-cert", str(cert), "--dask-tls-key", str(key))
    if executor is None:
        cmd = [c for c in cmd if c not in ("--executor", "serial")]
    t0 = time.monotonic()
    proc = subprocess.run(cmd, env=_env(tmp_path), capture_output=True, text=True, timeout=120)
    assert time.monotonic() - t0 < 30
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2 and len(lines) == 1, proc.stderr
    assert "--dask-tls-cert, --dask-tls-key given" in lines[0] and "only over TLS" in lines[0]
    if executor and executor.startswith("dask://"):
        assert "use --executor tls://127.0.0.1:1" in lines[0]
    assert not out.exists()


def test_a_killed_scheduler_is_named_and_what_finished_is_kept(tmp_path):
    """The scheduler killed mid-sweep was reported as a dead worker with the
    ``if __name__ == "__main__"`` advice; now: the scheduler went away, finished results stored."""
    store = tmp_path / "store"
    tasks = [Task("fast", draw, DrawConfig(n=2)), Task("slow", draw, DrawConfig(n=2, sleep_s=30.0))]
    with _dask(tmp_path, workers=1) as (address, _):
        sched = None
        import psutil

        for p in psutil.process_iter(["cmdline"]):
            if "distributed.cli.dask_scheduler" in " ".join(p.info["cmdline"] or []) and \
                    address.rsplit(":", 1)[1] in p.info["cmdline"]:
                sched = p
        assert sched is not None
        spec = replace(parse_executor(address.replace("tcp://", "dask://")),
                       dask=DaskSettings(connect_timeout_s=10, stall_timeout_s=120))
        box: dict = {}

        def run() -> None:
            try:
                box["report"] = run_sweep(tasks, seed=1, executor=spec, store=store, progress=False)
            except BaseException as e:  # noqa: BLE001
                box["error"] = e

        t = threading.Thread(target=run, daemon=True)
        t.start()
        _wait_for(lambda: store.exists() and any(store.rglob("*.json")), 60, "the fast task stored")
        sched.kill()
        t0 = time.time()
        t.join(90)
        assert not t.is_alive(), "the sweep did not notice the scheduler was gone"
        assert time.time() - t0 < 60
    err = box.get("error")
    assert isinstance(err, DaskUnavailable), box
    msg = str(err)
    assert "went away" in msg and address in msg and "__main__" not in msg and "\n" not in msg
    assert "1 of 2" in msg or "finished" in msg
    # what finished is kept: the same sweep on a serial executor reruns only the slow task
    again = run_sweep(tasks[:1], seed=1, executor="serial", store=store, progress=False)
    assert again.n_cached == 1 and again.n_run == 0


@pytest.mark.sumo
def test_a_finished_sweep_needs_no_scheduler(tmp_path):
    """Every run stored and in place: the same command on a dask:// address where nothing listens
    asks no scheduler and succeeds from the store."""
    out = tmp_path / "sweep"
    first = _generate(out, "serial")
    first[first.index("--duration") + 1] = "70"
    done = subprocess.run(first, env=_env(tmp_path), capture_output=True, text=True, timeout=180)
    assert done.returncode == 0, done.stderr
    again = [a if a != "serial" else f"dask://127.0.0.1:{_free_port()}" for a in first]
    proc = subprocess.run(again, env=_env(tmp_path), capture_output=True, text=True, timeout=180)
    assert proc.returncode == 0, proc.stderr
    assert "1 from the store, 0 run" in proc.stderr


# -- TLS and protocol mismatches, each named for what it is --------------------------------------------

def _tls_line(tmp_path: Path, out: Path, executor: str, *tls: str, env: dict | None = None) -> str:
    proc = subprocess.run(_generate(out, executor, "--dask-connect-timeout", "10", *tls),
                          env=env or _env(tmp_path), capture_output=True, text=True, timeout=120)
    line = _one_line_exit_2(proc, proc.stderr)
    _assert_nothing_created(out)
    return line


def test_protocol_mismatches_are_named(tmp_path):
    """A TLS client against a plain TCP scheduler, and a plain client against a TLS scheduler."""
    cert, key = _self_signed(tmp_path)
    tls = ["--dask-tls-ca-file", str(cert), "--dask-tls-cert", str(cert), "--dask-tls-key", str(key)]
    with _dask(tmp_path, workers=0) as (address, _):
        hostport = address[len("tcp://"):]
        line = _tls_line(tmp_path, tmp_path / "a", f"tls://{hostport}", *tls)
        assert f"Dask scheduler at tls://{hostport} does not speak TLS" in line
        assert f"dask://{hostport}" in line and "certificate" not in line
    sec = ["--tls-ca-file", str(cert), "--tls-cert", str(cert), "--tls-key", str(key)]
    with _dask(tmp_path, workers=0, tls=sec) as (address, _):
        hostport = address[len("tls://"):]
        line = _tls_line(tmp_path, tmp_path / "b", f"dask://{hostport}")
        assert f"Dask scheduler at tcp://{hostport} speaks TLS" in line and f"tls://{hostport}" in line


def test_tls_files_are_checked_before_connecting(tmp_path):
    """Nothing listens at the address: each file problem is named before any connection."""
    cert, key = _self_signed(tmp_path)
    (tmp_path / "other").mkdir()
    other, other_key = _self_signed(tmp_path / "other")
    address = f"tls://127.0.0.1:{_free_port()}"
    # a key/certificate mismatch
    line = _tls_line(tmp_path, tmp_path / "a", address, "--dask-tls-ca-file", str(cert), "--dask-tls-cert",
                     str(cert), "--dask-tls-key", str(other_key))
    assert (f"the key {other_key} (--dask-tls-key / distributed.comm.tls.client.key) does not match the certificate "
            f"{cert} (--dask-tls-cert / distributed.comm.tls.client.cert)") in line
    # a CA file that is not a certificate, a key file that is not a key
    notes = tmp_path / "notes.txt"
    notes.write_text("not a certificate\n")
    line = _tls_line(tmp_path, tmp_path / "b", address, "--dask-tls-ca-file", str(notes), "--dask-tls-cert",
                     str(cert), "--dask-tls-key", str(key))
    assert f"{notes} (--dask-tls-ca-file / distributed.comm.tls.ca-file): not a PEM certificate" in line
    line = _tls_line(tmp_path, tmp_path / "c", address, "--dask-tls-ca-file", str(cert), "--dask-tls-cert",
                     str(cert), "--dask-tls-key", str(notes))
    assert f"the key {notes} (--dask-tls-key / distributed.comm.tls.client.key) is not a PEM private key" in line
    # missing files: given on the command line, and from Dask's configuration
    proc = subprocess.run(_generate(tmp_path / "d", address, "--dask-tls-ca-file", str(cert), "--dask-tls-cert",
                                    str(cert), "--dask-tls-key", str(tmp_path / "gone.key")),
                          env=_env(tmp_path), capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and proc.stderr.strip().splitlines() == [
        f"merge-irl generate: error: --dask-tls-key {tmp_path / 'gone.key'}: no such file"], proc.stderr
    env = dict(_env(tmp_path), DASK_DISTRIBUTED__COMM__TLS__CA_FILE=str(cert),
               DASK_DISTRIBUTED__COMM__TLS__CLIENT__CERT=str(cert),
               DASK_DISTRIBUTED__COMM__TLS__CLIENT__KEY=str(tmp_path / "gone.key"))
    line = _tls_line(tmp_path, tmp_path / "e", address, env=env)
    assert f"{tmp_path / 'gone.key'} (--dask-tls-key / distributed.comm.tls.client.key): no such file" in line


# -- Ctrl-C on a Dask sweep: the runs in flight stop on the workers ------------------------------------

def _own_group_default_sigint() -> None:
    """The child leads a process group of its own (as a background job does), with Ctrl-C's default."""
    os.setpgrp()
    default_sigint()


def _runs_and_records(out: Path) -> tuple[set[str], set[str]]:
    """The run folders in ``out`` and the runs ``sweep.csv`` records."""
    recorded = set()
    if (out / "sweep.csv").exists():
        import pandas as pd

        recorded = set(pd.read_csv(out / "sweep.csv")["run"])
    return {p.name for p in out.iterdir() if p.is_dir() and not p.name.startswith(".")}, recorded


def _two_runs_in_flight(tmp_path: Path, out: Path, address: str) -> subprocess.Popen:
    """``generate`` of two 1200-s runs on ``address``, in a process group of its own; returns once
    both runs are simulating on the workers (their staging folders exist)."""
    argv = _generate(out, address.replace("tcp://", "dask://"))
    argv[argv.index("--seeds") + 1] = "1,2"
    argv[argv.index("--duration") + 1] = "1200"
    proc = subprocess.Popen(argv, env=_env(tmp_path), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=_own_group_default_sigint)
    try:
        _wait_for(lambda: out.exists() and len([p for p in out.iterdir() if p.name.endswith(".tmpdir")]) == 2,
                  120, "both runs started on the workers")
    except BaseException:
        _stop(proc)
        raise
    time.sleep(1.0)
    return proc


def _wait_until_workers_idle(address: str, timeout: float = 180) -> None:
    """Until no worker of ``address`` executes a task (a run that was not stopped goes on to its
    end, and publishes, before this returns)."""
    from distributed import Client

    def executing(dask_worker) -> int:
        return dask_worker.state.executing_count

    with Client(address, timeout=30) as client:
        _wait_for(lambda: not any(client.run(executing).values()), timeout, "the workers idle")


@pytest.mark.sumo
def test_a_killed_client_s_runs_stop_on_the_workers(tmp_path):
    """The client SIGKILLed with two runs in flight: the scheduler releases its tasks and the runs
    stop on the workers; once the workers are idle nothing is published, no run's lock or staging
    folder is left."""
    out = tmp_path / "sweep"
    with _dask(tmp_path, workers=2) as (address, workers):
        proc = _two_runs_in_flight(tmp_path, out, address)
        proc.kill()
        proc.communicate(timeout=30)
        _wait_until_workers_idle(address)
        assert all(w.poll() is None for w in workers)
    runs, _ = _runs_and_records(out)
    assert runs == set()
    assert [p.name for p in out.iterdir() if p.name.endswith((".lock", ".tmpdir"))] == []


@pytest.mark.sumo
def test_ctrl_c_stops_the_runs_in_flight_on_the_workers(tmp_path):
    """Two runs in flight on two workers, SIGINT to the client's process group: exit 130 in one
    line; the runs stop on the workers (before, they went on and published their folders into
    --out after the client exited, unrecorded, their locks left meanwhile). Once the
    workers are idle, --out holds only what sweep.csv records and no lock anywhere."""
    out = tmp_path / "sweep"
    with _dask(tmp_path, workers=2) as (address, workers):
        proc = _two_runs_in_flight(tmp_path, out, address)
        try:
            t0 = time.time()
            os.killpg(proc.pid, signal.SIGINT)
            _, err = proc.communicate(timeout=60)
            stopped_after = time.time() - t0
        finally:
            _stop(proc)
        assert proc.returncode == 130, err
        assert err.strip().splitlines() == ["merge-irl generate: interrupted"], err
        assert stopped_after < 30
        _wait_until_workers_idle(address)  # a run not stopped would have published by then
        assert all(w.poll() is None for w in workers)
    runs, recorded = _runs_and_records(out)
    assert runs == recorded, (runs, recorded)
    assert [p for p in tmp_path.rglob("*.lock")] == []
    assert [p.name for p in out.iterdir() if p.name.endswith(".tmpdir")] == []


@pytest.mark.sumo
def test_ctrl_c_stops_evaluation_episodes_on_the_workers(tmp_path):
    """``evaluate`` on Dask, two episodes on two workers (the first one recording), SIGINT: the
    episodes stop on the workers (idle within 20 s of the client's exit); no recording (final or
    partial) is in --out."""
    out = tmp_path / "ev"
    with _dask(tmp_path, workers=2) as (address, workers):
        proc = subprocess.Popen([sys.executable, "-m", "analysis", "evaluate", "--baselines", "sumo", "--episodes", "2",
                                 "--duration", "2400", "--executor", address.replace("tcp://", "dask://"),
                                 "--no-progress", "--out", str(out)], env=_env(tmp_path), stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True, preexec_fn=_own_group_default_sigint)
        try:
            _wait_for(lambda: len(list(out.glob("rerun/.*.partial"))) == 1, 120, "the first episode recording")
            time.sleep(1.0)
            os.killpg(proc.pid, signal.SIGINT)
            _, err = proc.communicate(timeout=60)
        finally:
            _stop(proc)
        assert proc.returncode == 130, err
        assert err.strip().splitlines()[-1] == "merge-irl evaluate: interrupted", err
        # the episodes stopped (an episode of 2400 simulated s runs on for a minute when not stopped)
        _wait_until_workers_idle(address, timeout=20)
        assert all(w.poll() is None for w in workers)
    left = sorted(str(p.relative_to(out)) for p in out.rglob("*")) if out.exists() else []
    assert [p for p in left if p.endswith((".rrd", ".partial"))] == [], left
