"""Progress on terminals and elsewhere: batch runs whose stderr is a log file
(nohup, CI, SLURM) get progress lines; terminals get bars; ``--no-progress`` gets nothing."""

from __future__ import annotations

import io
import subprocess
import sys

import pytest
from tqdm import tqdm

import merge_irl.progress as progress_mod
from merge_irl.progress import ProgressLines, progress_bar


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_lines_at_each_tenth_at_least_once_a_minute_and_at_the_end(monkeypatch):
    now = [0.0]
    monkeypatch.setattr(progress_mod.time, "monotonic", lambda: now[0])
    out = io.StringIO()
    bar = progress_bar(100, desc="episodes", unit="task", file=out)
    assert isinstance(bar, ProgressLines)
    for _ in range(5):  # 5 % in 5 s: no tenth done, no minute passed, no line
        now[0] += 1.0
        bar.update(1)
    now[0] += 61.0
    bar.update(1)  # a minute without a line: one now
    for _ in range(94):
        bar.update(1)
    bar.close()
    bar.close()  # once
    lines = out.getvalue().splitlines()
    assert lines[0] == "merge-irl: episodes: 0/100 task (0%), 0s elapsed (started)"
    assert lines[1] == "merge-irl: episodes: 6/100 task (6%), 1m06s elapsed, about 17m14s left"
    assert [ln.split(": ")[2].split(" ")[0] for ln in lines[2:]] == [f"{k}/100" for k in range(10, 100, 10)] + ["100/100"]
    assert lines[-1].endswith("(done)") and len(lines) == 12


def test_terminals_get_a_bar_and_no_progress_gets_nothing():
    term = _Terminal()
    bar = progress_bar(3, desc="x", file=term)
    assert isinstance(bar, tqdm) and not bar.disable
    bar.close()
    quiet = io.StringIO()
    for b in (progress_bar(3, desc="x", file=quiet, enabled=False), progress_bar(3, desc="x", file=quiet, lines=False)):
        assert isinstance(b, tqdm) and b.disable
        b.update(3)
        b.close()
    assert quiet.getvalue() == ""
    # iterating, as tqdm(iterable)
    out = io.StringIO()
    assert list(progress_bar(2, desc="trials", iterable=iter("ab"), file=out)) == ["a", "b"]
    assert out.getvalue().splitlines()[-1].startswith("merge-irl: trials: 2/2 it (100%)")


def test_a_sweep_reports_to_a_stream_that_is_not_a_terminal(capsys):
    """run_sweep (evaluate's episodes, reproduce's trials, generate's runs): lines where a bar used
    to be drawn in place (stderr not a terminal)."""
    from sweep_tasks import DrawConfig, draw

    from analysis.sweep import Task, run_sweep

    report = run_sweep([Task(f"t{i}", draw, DrawConfig(2)) for i in range(3)], seed=0, executor="serial",
                       desc="table 3")
    assert report.ok
    err = capsys.readouterr().err
    assert "merge-irl: table 3: 0/3 task (0%)" in err and "merge-irl: table 3: 3/3 task (100%)" in err
    assert "\r" not in err


@pytest.mark.sumo
def test_a_batch_command_with_stderr_to_a_file_prints_progress_lines(tmp_path):
    log = tmp_path / "stderr.log"
    with log.open("w") as err:
        r = subprocess.run([sys.executable, "-m", "analysis", "generate", "--scenario", "synthetic", "--seeds", "1-2",
                            "--duration", "65", "--executor", "serial", "--out", str(tmp_path / "g")],
                           stdout=subprocess.PIPE, stderr=err, text=True, timeout=300)
    text = log.read_text()
    assert r.returncode == 0, text
    assert "merge-irl: generate synthetic: 0/2 task (0%)" in text
    assert "merge-irl: generate synthetic: 1/2 task (50%)" in text
    assert "merge-irl: generate synthetic: 2/2 task (100%)" in text and "(done)" in text
    assert "\r" not in text  # lines, not a bar redrawn in place
