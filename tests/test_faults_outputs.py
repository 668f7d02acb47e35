"""Output faults, injected for real: concurrent writers, kills mid-run, leftovers, read-only and
full file systems, paths that are files."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from merge_irl.atomic import temporary_path
from merge_irl.run_folder import (
    OutputLockedError,
    check_replaceable,
    locked,
    publish,
    remove_temporaries,
    staging_folder,
)


def _cli(*args: str, env: dict | None = None, timeout: float = 300) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "analysis", *args], capture_output=True, text=True,
                          timeout=timeout, env=env)


def _one_line_exit_2(proc: subprocess.CompletedProcess, command: str) -> str:
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"merge-irl {command}: error: "), proc.stderr
    return lines[0]


def _mount_tmpfs(where: Path, options: str) -> None:
    where.mkdir()
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(where)], capture_output=True, text=True)
    if r.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here ({r.stderr.strip()}); needs root in a mount namespace")


@pytest.fixture
def full_fs(tmp_path):
    """A 64 KiB file system: any real output fills it."""
    mnt = tmp_path / "full"
    _mount_tmpfs(mnt, "size=64k")
    yield mnt
    subprocess.run(["umount", "-l", str(mnt)], check=False)


@pytest.fixture
def readonly_fs(tmp_path):
    mnt = tmp_path / "ro"
    _mount_tmpfs(mnt, "ro,size=64k")
    yield mnt
    subprocess.run(["umount", "-l", str(mnt)], check=False)


@pytest.fixture
def sim_env(tmp_path):
    return dict(os.environ, MERGE_IRL_CACHE=str(tmp_path / "cache"))


# -- the run-folder primitives ------------------------------------------------------------

def test_lock_is_exclusive_across_processes_and_freed_by_death(tmp_path):
    out = tmp_path / "out"
    holder = subprocess.Popen([sys.executable, "-c", (
        "import sys, time; from merge_irl.run_folder import locked\n"
        f"with locked({str(out)!r}):\n    print('held', flush=True); time.sleep(60)")],
        stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        with pytest.raises(OutputLockedError, match="another run is writing into this folder"):
            with locked(out):
                pass
        holder.send_signal(signal.SIGKILL)
        holder.wait(timeout=10)
    finally:
        if holder.poll() is None:
            holder.kill()
    with locked(out):  # the kernel released the dead holder's lock
        pass


def test_publish_replaces_a_previous_set_whole(tmp_path):
    final = tmp_path / "run"
    final.mkdir()
    (final / "a.txt").write_text("old a")
    (final / "b.txt").write_text("old b")
    stage = staging_folder(final)
    (stage / "a.txt").write_text("new a")
    publish(stage, final)
    assert sorted(p.name for p in final.iterdir()) == ["a.txt"] and (final / "a.txt").read_text() == "new a"
    assert [p.name for p in tmp_path.iterdir()] == ["run"]  # no staging or old folder left


def test_check_replaceable_refuses_foreign_files_and_files(tmp_path):
    (tmp_path / "run").mkdir()
    (tmp_path / "run" / "notes.txt").write_text("mine")
    with pytest.raises(FileExistsError, match=r"notes\.txt"):
        check_replaceable(tmp_path / "run", ("trajectories.parquet",))
    (tmp_path / "f").write_text("x")
    with pytest.raises(NotADirectoryError, match="not a folder"):
        check_replaceable(tmp_path / "f", ())


def test_remove_temporaries_finds_what_atomic_writes_leave(tmp_path):
    left = temporary_path(tmp_path / "trajectories.parquet")  # what a killed write_atomic leaves
    stage = staging_folder(tmp_path / "run")
    keep = [tmp_path / ".hidden-config", tmp_path / "model.json", tmp_path / ".x.tmp"]
    for k in keep:
        k.write_text("keep")
    removed = remove_temporaries(tmp_path)
    assert sorted(removed) == sorted([left, stage])
    assert all(k.exists() for k in keep) and not left.exists() and not stage.exists()


# -- generate: published as a set, locked, leftovers removed -----------------------------------

def test_second_generate_into_the_same_out_fails_at_once(tmp_path, sim_env):
    out = tmp_path / "run"
    first = subprocess.Popen([sys.executable, "-m", "analysis", "generate", "--scenario", "i80", "--duration", "3000",
                              "--no-progress", "--out", str(out)], env=sim_env,
                             stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.time() + 60
        while not list(tmp_path.glob(".run.*.tmpdir")) and time.time() < deadline:
            time.sleep(0.05)
        t0 = time.time()
        second = _cli("generate", "--scenario", "synthetic", "--duration", "90", "--no-progress", "--out", str(out),
                      env=sim_env)
        assert time.time() - t0 < 30
        line = _one_line_exit_2(second, "generate")
        assert "another run is writing into this folder" in line and str(out) in line
        # the sweep form is refused the same way (its lock is the folder's)
        sweep = _cli("generate", "--scenario", "synthetic", "--seeds", "1-2", "--duration", "90", "--no-progress",
                     "--out", str(out), env=sim_env)
        assert "another run is writing" in _one_line_exit_2(sweep, "generate")
        assert first.poll() is None  # the first run goes on
        first.send_signal(signal.SIGKILL)
        first.wait(timeout=10)
    finally:
        if first.poll() is None:
            first.kill()
    # killed mid-run: nothing published; a rerun removes the leftovers and publishes its set
    assert not out.exists() or not any(out.iterdir())
    (out).mkdir(exist_ok=True)
    stale_tmp = temporary_path(out / "merges.parquet")  # as a write killed inside the folder leaves
    rerun = _cli("generate", "--scenario", "synthetic", "--duration", "90", "--no-progress", "--out", str(out),
                 env=sim_env)
    assert rerun.returncode == 0, rerun.stderr
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(".run.")) == []  # lock removed on release
    assert not stale_tmp.exists()
    assert sorted(p.name for p in out.iterdir()) == sorted(
        ["trajectories.parquet", "encounters.parquet", "merges.parquet", "scenario.toml", "run.toml"])


def test_generate_refuses_an_out_folder_with_other_files(tmp_path, sim_env):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("keep me")
    line = _one_line_exit_2(_cli("generate", "--scenario", "synthetic", "--duration", "90", "--no-progress",
                                 "--out", str(out), env=sim_env), "generate")
    assert "notes.txt" in line and "not this run's outputs" in line
    assert (out / "notes.txt").read_text() == "keep me"


def test_generate_on_a_full_disk_fails_in_one_line_and_publishes_nothing(full_fs, sim_env):
    out = full_fs / "run"
    line = _one_line_exit_2(_cli("generate", "--scenario", "synthetic", "--duration", "90", "--no-progress",
                                 "--out", str(out), env=sim_env), "generate")
    assert "No space left on device" in line
    assert f": {full_fs}/" in line and line.endswith(".parquet")  # names the file it could not write
    assert not out.exists() or not any(out.iterdir())
    assert [p.name for p in full_fs.iterdir() if p.name != "run"] == []  # the lock file too


def test_generate_sweep_on_a_full_disk_names_the_path_and_prints_no_traceback(full_fs, sim_env):
    """The FAILED line names the file the full disk refused; no traceback."""
    out = full_fs / "sweep"
    proc = _cli("generate", "--scenario", "synthetic", "--seeds", "1", "--duration", "90", "--executor", "serial",
                "--no-progress", "--out", str(out), env=sim_env)
    assert proc.returncode in (1, 2), proc.stderr
    assert "Traceback" not in proc.stderr and 'File "' not in proc.stderr, proc.stderr
    failed = [line for line in proc.stderr.splitlines() if "No space left on device" in line]
    assert failed and all(f"{out}/" in line for line in failed), proc.stderr
    assert not [p for p in out.iterdir() if p.name.endswith(".tmpdir") or p.name.endswith(".lock")]
    assert [p.name for p in full_fs.iterdir()] == ["sweep"]


def test_generate_into_a_read_only_file_system_fails_before_simulating(readonly_fs, sim_env):
    t0 = time.time()
    line = _one_line_exit_2(_cli("generate", "--scenario", "i80", "--duration", "3000", "--no-progress",
                                 "--out", str(readonly_fs / "run"), env=sim_env), "generate")
    assert "Read-only file system" in line
    assert time.time() - t0 < 30  # 3000 s of i80 would take minutes


# -- learn / evaluate: outputs checked before the work -----------------------------------------

def test_learn_checks_out_before_reading_or_fitting(readonly_fs, tmp_path):
    # the demos do not exist: an error about them would mean --out was checked too late
    line = _one_line_exit_2(_cli("learn", "--method", "qavg", "--domain", "gridworld", "--demos",
                                 str(tmp_path / "no-such-demos"), "--out", str(readonly_fs / "model.json")), "learn")
    assert "Read-only file system" in line and "no-such-demos" not in line


def test_learn_out_under_a_file_is_one_line(tmp_path):
    (tmp_path / "afile").write_text("x")
    line = _one_line_exit_2(_cli("learn", "--method", "qavg", "--domain", "gridworld", "--demos",
                                 str(tmp_path / "no-such-demos"), "--out", str(tmp_path / "afile" / "model.json")),
                            "learn")
    assert "afile" in line


def test_learn_out_that_is_a_folder_is_one_line(tmp_path):
    line = _one_line_exit_2(_cli("learn", "--method", "qavg", "--domain", "gridworld", "--demos",
                                 str(tmp_path / "no-such-demos"), "--out", str(tmp_path)), "learn")
    assert "Is a directory" in line


# -- leftovers: the network cache, a moved sweep ---------------------------------------------

@pytest.mark.parametrize("damage", ["truncated", "emptied", "checksum-lost", "net-lost"])
def test_damaged_network_cache_entry_is_rebuilt(tmp_path, monkeypatch, damage):
    import scenarios.network as network
    from scenarios.loader import load_scenario

    monkeypatch.setenv("MERGE_IRL_CACHE", str(tmp_path))
    road = load_scenario("synthetic").road
    net = network.build_network(road)
    good = net.read_bytes()
    if damage == "truncated":
        net.write_bytes(good[: len(good) // 2])
    elif damage == "emptied":
        net.write_bytes(b"")
    elif damage == "checksum-lost":
        (net.parent / network.CHECKSUM_FILE).unlink()
    else:
        net.unlink()
    calls = []
    real = network.netconvert_binary
    monkeypatch.setattr(network, "netconvert_binary", lambda: calls.append(1) or real())
    again = network.build_network(road)
    body = good[good.index(b"<net "):]  # netconvert's header comment holds the build time
    assert again == net and again.read_bytes().endswith(body) and calls == [1]
    assert [p.name for p in (tmp_path / "networks").iterdir()] == [net.parent.name]  # nothing left aside
    network.build_network(road)
    assert calls == [1]  # intact now: reused


def test_moved_sweep_folder_resumes_without_recomputing(tmp_path, sim_env):
    args = ["generate", "--scenario", "synthetic", "--seeds", "1-2", "--duration", "90", "--executor", "serial",
            "--no-progress"]
    first = _cli(*args, "--out", str(tmp_path / "a" / "sweep"), env=sim_env)
    assert first.returncode == 0, first.stderr
    (tmp_path / "b").mkdir()
    os.rename(tmp_path / "a" / "sweep", tmp_path / "b" / "sweep")
    moved = _cli(*args, "--out", str(tmp_path / "b" / "sweep"), env=sim_env)
    assert moved.returncode == 0, moved.stderr
    assert "(2 from the store, 0 run)" in moved.stderr
    import pandas as pd

    table = pd.read_csv(tmp_path / "b" / "sweep" / "sweep.csv")
    assert all(str(tmp_path / "b" / "sweep") in d for d in table["out_dir"])  # where the runs are now


def test_second_evaluate_into_the_same_out_fails_at_once(tmp_path, sim_env):
    out = tmp_path / "eval"
    holder = subprocess.Popen([sys.executable, "-c", (
        "import time; from merge_irl.run_folder import locked\n"
        f"with locked({str(out)!r}):\n    print('held', flush=True); time.sleep(60)")],
        stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        line = _one_line_exit_2(_cli("evaluate", "--baselines", "sumo", "--scenario", "synthetic", "--episodes", "1",
                                     "--no-progress", "--out", str(out), env=sim_env), "evaluate")
        assert "another run is writing into this folder" in line
    finally:
        holder.kill()
        holder.wait()
    assert not out.exists()


# -- learn: one --out, one writer --------------------------------------------------------------

def test_second_learn_into_the_same_out_fails_at_once(tmp_path):
    sys.path.insert(0, str(Path(__file__).parent))
    from irl_testdata import gridworld_demos

    from irl.io import save_npz

    demos = save_npz(gridworld_demos("0.0"), tmp_path / "demos.npz")
    out = tmp_path / "models" / "model.json"
    args = ("learn", "--method", "qavg", "--domain", "npz", "--demos", str(demos), "--l2", "0.1", "--no-progress",
            "--out", str(out))
    holder = subprocess.Popen([sys.executable, "-c", (  # a first learn holding the lock of --out
        "import time; from merge_irl.run_folder import locked\n"
        f"with locked({str(out)!r}):\n    print('held', flush=True); time.sleep(60)")],
        stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        second = _cli(*args)
        line = _one_line_exit_2(second, "learn")
        assert "another run is writing this file" in line and str(out) in line
        assert "wrote" not in second.stdout and not out.exists()  # nothing written over the first run's result
    finally:
        holder.kill()
        holder.wait()
    done = _cli(*args)  # the lock went with its holder
    assert done.returncode == 0 and f"wrote {out}" in done.stdout, done.stderr
    assert out.is_file()
