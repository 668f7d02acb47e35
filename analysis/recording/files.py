"""A run's recording file (``.rrd``): its id and display name, and opening and closing it
under a temporary ``.partial`` name that is renamed into place only when the recording is
complete."""

from __future__ import annotations

import os
from pathlib import Path

import rerun as rr

from merge_irl.atomic import move_into_place, temporary_path

#: Entity holding a recording's properties (name, start time).
PROPERTIES = "/__properties"


def _tmp_path(path: Path) -> Path:
    return temporary_path(path, suffix=".partial")


def recording_identity(scenario: str, policy: str, seed: int, episode: int | None = None) -> tuple[str, str]:
    """``(recording id, recording name)`` of one run's ``.rrd``: distinct for every scenario,
    policy, seed (and episode, when given), so the viewer keeps the files apart.

    E.g. ``("merge-irl/synthetic/qavg/seed3", "qavg on synthetic, seed 3")``.
    """
    rid = f"merge-irl/{scenario}/{policy}/seed{int(seed)}"
    name = f"{policy} on {scenario}, seed {int(seed)}"
    if episode is not None:
        rid += f"/episode{int(episode)}"
        name += f", episode {int(episode)}"
    return rid, name


def open_recording(path: str | os.PathLike, *, application_id: str = "merge-irl",
                   recording_id: str | None = None, name: str | None = None) -> tuple[rr.RecordingStream, Path]:
    """A recording stream saving to a temporary name next to ``path`` (see :func:`close_recording`);
    an existing file at ``path`` is removed first.

    ``recording_id``: what the viewer groups data by (two files with one id merge into one
    recording); ``name``: the recording's display name.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.unlink(missing_ok=True)  # a previous run's file must not pass for this run's
    rec = rr.RecordingStream(application_id, recording_id=recording_id)
    tmp = _tmp_path(path)
    rec.save(str(tmp))
    if name is not None:
        rec.send_recording_name(name)
    return rec, tmp


def close_recording(rec: rr.RecordingStream, tmp: Path, path: str | os.PathLike) -> Path:
    """Flush, close and atomically rename the file to ``path``."""
    rec.flush()
    rec.disconnect()
    return move_into_place(tmp, path)
