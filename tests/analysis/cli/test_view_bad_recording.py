"""``merge-irl view RUN_DIR``: one unreadable recording in a run folder does not block the others
(they open, it is named on stderr); a single unreadable file, or a folder of none readable, is one
line and exit 2; the advice without a viewer says what is missing (the viewer or a display)."""

from __future__ import annotations

import os
import subprocess
import sys

import rerun as rr


def _rrd(path) -> None:
    rec = rr.RecordingStream("merge-irl-test")
    rec.save(str(path))
    rec.log("points", rr.Points2D([[0.0, 0.0], [1.0, 1.0]]))
    rec.flush()
    rec.disconnect()


def _view(*args, env=None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "analysis", "view", *args], capture_output=True, text=True,
                          timeout=120, env=env)


def test_one_bad_recording_leaves_the_others_viewable(tmp_path) -> None:
    run = tmp_path / "run"
    (run / "rerun").mkdir(parents=True)
    _rrd(run / "rerun" / "qavg.rrd")
    _rrd(run / "rerun" / "sumo.rrd")
    (run / "rerun" / "broken.rrd").write_bytes(b"not a recording\n" * 10)
    r = _view("--print-only", str(run))
    assert r.returncode == 0, r.stderr
    assert "qavg.rrd" in r.stdout and "sumo.rrd" in r.stdout and "broken.rrd" not in r.stdout
    bad = [ln for ln in r.stderr.splitlines() if "broken.rrd" in ln]
    assert len(bad) == 1 and bad[0].startswith("merge-irl view: warning: left out ") and "not a readable" in bad[0]
    # the file itself, or a folder with nothing readable: refused in one line
    r = _view("--print-only", str(run / "rerun" / "broken.rrd"))
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "not a readable rerun recording" in r.stderr
    (run / "rerun" / "qavg.rrd").unlink()
    (run / "rerun" / "sumo.rrd").unlink()
    (run / "rerun" / "also-broken.rrd").write_bytes(b"")
    r = _view("--print-only", str(run))
    assert r.returncode == 2 and "none of its 2 .rrd recordings is readable" in r.stderr


def test_without_a_display_the_advice_says_so_when_rerun_is_installed(tmp_path) -> None:
    _rrd(tmp_path / "a.rrd")
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    r = _view(str(tmp_path / "a.rrd"), env=env)  # rerun-sdk is installed here (a dependency)
    assert r.returncode == 0, r.stderr
    assert "pip install" not in r.stdout and "is installed" in r.stdout and "no display" in r.stdout
    env["PATH"] = ""  # no viewer on PATH ...
    r = subprocess.run([sys.executable, "-c", "import analysis.recording.view as v, sys; "
                        "v.viewer_executable = lambda: None; print(v.no_viewer_advice())"],
                       capture_output=True, text=True, env=env, timeout=60)
    assert "pip install rerun-sdk" in r.stdout  # ... and none beside Python: install it
