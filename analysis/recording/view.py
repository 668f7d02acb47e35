"""Find rerun recordings and open them in the viewer (the API behind ``merge-irl view``)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

from analysis.errors import AnalysisError


def find_recordings(target: str | os.PathLike) -> list[Path]:
    """``target`` itself if it is an ``.rrd`` file, else every ``.rrd`` under the folder, sorted.

    Raises ``AnalysisError`` naming ``target`` if there is nothing to open.

    Raises:
        AnalysisError: a path does not exist, is not a ``.rrd`` file, or is a folder without recordings.
    """
    p = Path(target)
    if p.is_file():
        if p.suffix != ".rrd":
            raise AnalysisError(f"{p}: not a rerun recording (expected a .rrd file or a run folder)")
        return [p]
    if p.is_dir():
        files = sorted(p.rglob("*.rrd"))
        if not files:
            raise AnalysisError(f"{p}: no .rrd recordings in this folder (run with rerun logging on)")
        return files
    raise AnalysisError(f"{p}: no such file or folder")


def check_recordings(files: list[Path]) -> None:
    """Raise unless every file reads as a rerun recording (:func:`analysis.recording.read.check_rrd`),
    so that ``merge-irl view`` refuses a corrupt or foreign file before it starts a viewer.

    Raises:
        AnalysisError: one line naming the first unreadable file and why.
    """
    from analysis.recording.read import check_rrd

    for f in files:
        try:
            check_rrd(f)
        except (ValueError, FileNotFoundError) as e:
            raise AnalysisError(str(e)) from None


def readable_recordings(files: list[Path]) -> tuple[list[Path], list[str]]:
    """``(readable files, one line per unreadable file naming it and why)``: a run folder with one
    corrupt or foreign ``.rrd`` still opens the others (:func:`analysis.recording.read.check_rrd`)."""
    from analysis.recording.read import check_rrd

    good, bad = [], []
    for f in files:
        try:
            check_rrd(f)
        except (ValueError, FileNotFoundError) as e:
            bad.append(str(e))
        else:
            good.append(f)
    return good, bad


def has_display() -> bool:
    """Whether a GUI can open here (always assumed on macOS/Windows)."""
    if sys.platform.startswith("linux"):
        return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))
    return True


def viewer_executable() -> str | None:
    """The rerun viewer's executable (on PATH, or beside this Python: rerun-sdk's), or None."""
    exe = shutil.which("rerun")
    if exe is None:
        cand = Path(sys.executable).parent / "rerun"
        exe = str(cand) if cand.exists() else None
    return exe


def viewer_command(files: list[Path]) -> list[str] | None:
    """The command that opens ``files`` in the rerun viewer, or None when none can run here."""
    exe = viewer_executable()
    if exe is None or not has_display():
        return None
    return [exe, *map(str, files)]


def no_viewer_advice() -> str:
    """Why no viewer starts here, and what to do: the viewer is missing (install rerun-sdk), or it
    is installed and there is no display (copy the files to a machine with one)."""
    exe = viewer_executable()
    if exe is not None:
        return (f"(the rerun viewer is installed ({exe}) but there is no display here (DISPLAY / WAYLAND_DISPLAY "
                "unset): run the command above on a machine with a display, e.g. after copying the files)")
    return ("(no rerun viewer found here: install it with `pip install rerun-sdk` on a machine with a display, "
            "then run the command above)")


def open_viewer(cmd: list[str]) -> subprocess.Popen:
    """Start the viewer detached (it outlives this command)."""
    return subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
