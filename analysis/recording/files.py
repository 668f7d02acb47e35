"""A run's recording file (``.rrd``): its id and display name, and opening and closing it
under a temporary ``.partial`` name that is renamed into place only when the recording is
complete."""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

import numpy as np
import rerun as rr

from merge_irl.atomic import move_into_place, temporary_path

#: Entity holding a recording's properties (name, start time).
PROPERTIES = "/__properties"


def _tmp_path(path: Path) -> Path:
    return temporary_path(path, suffix=".partial")


def recording_identity(scenario: str, policy: str, seed: int, episode: int | None = None, *,
                       run: str = "") -> tuple[str, str]:
    """``(recording id, recording name)`` of one run's ``.rrd``: distinct for every scenario,
    policy, seed (and episode, when given) and ``run`` (:func:`run_token`: which run wrote the
    file), so the viewer keeps the files apart; it merges files that share an id.

    E.g. ``("merge-irl/synthetic/qavg/seed3/run-1a2b3c4d5e", "qavg on synthetic, seed 3 (run 1a2b3c4d5e)")``.
    """
    rid = f"merge-irl/{scenario}/{policy}/seed{int(seed)}"
    name = f"{policy} on {scenario}, seed {int(seed)}"
    if episode is not None:
        rid += f"/episode{int(episode)}"
        name += f", episode {int(episode)}"
    if run:
        rid += f"/run-{run}"
        name += f" (run {run})"
    return rid, name


def run_token(path: str | os.PathLike, *parts: str) -> str:
    """10 hex digits naming the run that writes the recording ``path``: the SHA-256 of its
    absolute path and ``parts`` (e.g. the scenario's TOML and :func:`policy_digest`).

    Deterministic: the same command with the same inputs and ``--out`` gives the same id (and
    replaces the file); two runs into different folders, or with different models or scenarios,
    give different ids even when file names, policy names and seeds agree.
    """
    h = hashlib.sha256(os.path.abspath(path).encode("utf-8"))
    for part in parts:
        h.update(b"\0" + part.encode("utf-8"))
    return h.hexdigest()[:10]


def policy_digest(policy) -> str:
    """The content of a driver, as a hex SHA-256: its ``source`` file's bytes when it was read
    from one, else its log-policy table (``log_pi``, a tabular model), else ``""`` (a baseline
    built in code: its name and the run's path tell it apart)."""
    source = str(getattr(policy, "source", "") or "")
    if source and os.path.isfile(source):
        from merge_irl.provenance import file_sha256

        return file_sha256(source)
    log_pi = getattr(policy, "log_pi", None)
    if log_pi is not None:
        return hashlib.sha256(np.ascontiguousarray(log_pi, dtype=np.float64).tobytes()).hexdigest()
    return ""


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
