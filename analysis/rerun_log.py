"""Write a run to a rerun ``.rrd`` file, headless (no viewer, no display needed).

:class:`RerunLogger` is a :class:`sim.hooks.StepHook`. Entities (hierarchical, units ft, ft/s):

* ``world/lanes`` (static): one ``LineStrips3D`` strip per lane centre line (I-80 numbering,
  labelled), from the run's lane shapes; ``world`` (static) carries an ``AnnotationContext``
  naming the vehicle roles.
* ``world/vehicles``: every vehicle of every frame as ONE batched ``Boxes3D`` entity: centres
  (the box centre, half a length behind the front bumper along +x), half sizes, ``class_ids``
  = role (0 other, 1 A controlled, 2 B merging, 3 C lead) with matching ``colors``, and an
  extra component ``vehicle_id`` (the table's Vehicle_ID), so each box can be matched to the
  trajectory table (front bumper = centre + (length/2, 0, 0)).
* ``policy/A_<id>/probs`` (``Scalars``, 5 series named by action), ``policy/A_<id>/action``
  (``Scalars``: action index 0..4),
  ``policy/A_<id>/features/<name>`` (``Scalars``: the paper's reward features of the chosen
  action, from the continuous observation) at each decision of controlled car ``<id>``.
* ``metrics/A_<id>/speed``, ``.../d_AC``, ``.../d_AB``, ``.../ttc`` (``Scalars``) per frame
  while ``<id>`` is controlled (``ttc`` only when A closes in on its leader).
* ``train/<method>/loglik`` and ``train/<method>/theta/<k>`` (``Scalars`` on the
  ``iteration`` timeline): IRL training traces, via :func:`log_training`.

Timelines: ``sim_time`` (duration, s) and ``step`` (sequence: Frame_ID). Frames are buffered
and sent in columns (``send_columns``) every ``flush_every`` frames, which keeps logging well
under 10 microseconds per vehicle-frame. The file is written under a temporary name
(``<name>.partial``) and renamed only when the run succeeds (``on_end``); a run that fails or
is interrupted (``on_abort``) leaves the ``.partial`` file, never a complete-looking ``.rrd``.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pyarrow as pa
import rerun as rr

from irl.atomic import move_into_place, temporary_path
from irl.domains.merge import ACTION_NAMES, FEATURE_NAMES, paper_features
from sim.hooks import FrameState, RunContext
from sim.observe import lead_of
from sim.schema import RAMP_LANE

ROLE_IDS = {"other": 0, "A": 1, "B": 2, "C": 3}
#: RGBA colours of the roles, indexed by role id.
ROLE_COLORS = np.array(
    [[150, 150, 150, 255], [230, 40, 40, 255], [40, 110, 230, 255], [40, 180, 70, 255]], dtype=np.uint8
)
ROLE_RGBA_U32 = (ROLE_COLORS.astype(np.uint32) @ np.array([1 << 24, 1 << 16, 1 << 8, 1], dtype=np.uint32)).astype(np.uint32)
VEHICLE_HEIGHT_FT = 5.0
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


def log_training(rec: rr.RecordingStream, method: str, loglik_trace: np.ndarray, theta_trace: np.ndarray,
                 feature_names: Sequence[str] = ()) -> None:
    """IRL training traces: ``train/<method>/loglik`` and ``train/<method>/theta/<k>``.

    Args:
        loglik_trace: ``[n_iter]``; theta_trace: ``[n_iter, K]``; on the ``iteration`` timeline.
    """
    ll = np.asarray(loglik_trace, dtype=np.float64).reshape(-1)
    th = np.asarray(theta_trace, dtype=np.float64).reshape(ll.size, -1) if ll.size else np.zeros((0, 0))
    if ll.size == 0:
        return
    it = [rr.TimeColumn("iteration", sequence=np.arange(ll.size))]
    rec.send_columns(f"train/{method}/loglik", indexes=it, columns=rr.Scalars.columns(scalars=ll))
    for k in range(th.shape[1]):
        name = feature_names[k] if k < len(feature_names) else str(k)
        rec.send_columns(f"train/{method}/theta/{name}", indexes=it, columns=rr.Scalars.columns(scalars=th[:, k]))


class RerunLogger:
    """Step hook writing the run to ``path`` (``.rrd``); see the module docstring.

    Args:
        path: output file.
        controller: the run's :class:`sim.controller.Controller` (must run *before* this hook);
            gives roles, decisions and controlled cars. Without it, lane-7 vehicles are shown as B.
        recording: an open stream (from :func:`open_recording`) to add to instead of opening
            one; then the caller closes it.
        flush_every: frames buffered before they are sent.
        log_vehicles: log ``world/vehicles`` (False: only policy/metrics scalars).
        episode: the episode's index, if the file holds one episode of several; it goes into
            the recording id and name (:func:`recording_identity`) with the scenario, the
            controller's policy (``sumo`` without a controller) and the seed.
    """

    def __init__(self, path: str | os.PathLike, *, controller=None, recording: tuple[rr.RecordingStream, Path] | None = None,
                 flush_every: int = 600, log_vehicles: bool = True, application_id: str = "merge-irl",
                 episode: int | None = None):
        self.path = Path(path)
        self.episode = episode
        self.controller = controller
        self.flush_every = int(flush_every)
        self.log_vehicles = log_vehicles
        self._own = recording is None
        self._app = application_id
        self._rec: rr.RecordingStream | None
        self._tmp: Path | None
        self._rec, self._tmp = recording if recording is not None else (None, None)
        self._reset_buffers()
        # per controlled car: rows (step, t, speed, d_AC, d_AB, ttc) and decision rows
        # (step, t, p0..p4, action, features...), sent as columns when the run ends
        self._metric_rows: dict[int, list[tuple]] = {}
        self._decision_rows: dict[int, list[tuple]] = {}
        self.n_vehicle_frames = 0

    def _reset_buffers(self) -> None:
        self._steps: list[int] = []
        self._times: list[float] = []
        self._lens: list[int] = []
        self._gx: list[np.ndarray] = []
        self._gy: list[np.ndarray] = []
        self._len: list[np.ndarray] = []
        self._wid: list[np.ndarray] = []
        self._roles: list[np.ndarray] = []
        self._ids: list[np.ndarray] = []

    @property
    def _stream(self) -> rr.RecordingStream:
        if self._rec is None:
            raise RuntimeError("RerunLogger: the recording opens in on_start; nothing can be logged before")
        return self._rec

    # -- hook protocol -------------------------------------------------------------------
    def on_start(self, ctx: RunContext) -> None:
        if self._rec is None:
            policy = self.controller.policy.name if self.controller is not None else "sumo"
            rid, name = recording_identity(ctx.spec.name, policy, ctx.seed, self.episode)
            self._rec, self._tmp = open_recording(self.path, application_id=self._app, recording_id=rid, name=name)
        rec = self._rec
        names = sorted(ctx.lane_shapes, key=lambda s: int(s) if s.isdigit() else 99)
        strips = [np.column_stack([np.asarray(ctx.lane_shapes[n], float), np.zeros(len(ctx.lane_shapes[n]))]) for n in names]
        rec.log("world/lanes", rr.LineStrips3D(strips, labels=[f"lane {n}" for n in names],
                                               colors=[[90, 90, 90, 255]] * len(strips)), static=True)
        rec.log("world", rr.AnnotationContext(
            [(i, name, tuple(int(c) for c in ROLE_COLORS[i][:3])) for name, i in ROLE_IDS.items()]), static=True)

    def on_step(self, ctx: RunContext, frame: FrameState) -> None:
        n = len(frame.sumo_ids)
        roles = self._roles_of(frame)
        if self.log_vehicles:
            # the frame's arrays are read-only and never reused: keep references, not copies
            self._gx.append(frame.global_x)
            self._gy.append(frame.global_y)
            self._len.append(frame.length)
            self._wid.append(frame.width)
            self._roles.append(roles)
            self._ids.append(frame.vehicle_id)
            self._lens.append(n)
            self._steps.append(int(frame.frame))
            self._times.append(float(frame.time_s))
            self.n_vehicle_frames += n
        if self.controller is not None:
            self._log_controlled(frame)
        if len(self._steps) >= self.flush_every:
            self._flush()

    def on_end(self, ctx: RunContext) -> None:
        self._flush()
        self._flush_scalars()
        if self._own and self._rec is not None and self._tmp is not None:
            close_recording(self._rec, self._tmp, self.path)
            self._rec = None

    def on_abort(self, ctx: RunContext) -> None:
        """The run failed or was interrupted: close the stream and leave it under its temporary
        ``.partial`` name, never under the final one."""
        if self._own and self._rec is not None:
            self._rec.flush()
            self._rec.disconnect()
            self._rec = None

    # -- internals ----------------------------------------------------------------------
    def _roles_of(self, frame: FrameState) -> np.ndarray:
        roles = np.zeros(len(frame.sumo_ids), dtype=np.uint16)
        if self.controller is None:
            roles[frame.lane_id == RAMP_LANE] = ROLE_IDS["B"]
            return roles
        for row, role in self.controller.role_rows.items():
            roles[row] = ROLE_IDS[role]
        return roles

    def _log_controlled(self, frame: FrameState) -> None:
        """Buffers one row per controlled car and frame (and one per decision); see _flush_scalars."""
        ctl = self.controller
        if not ctl.last:
            return
        step, t = int(frame.frame), float(frame.time_s)
        rows = ctl.rows
        for a_id, (obs, probs, action) in ctl.last.items():
            ia = rows.get(a_id)
            if ia is None:
                continue
            speed, y = float(frame.speed[ia]), float(frame.local_y[ia])
            ttc = np.nan  # only while A closes in on its leader
            il = lead_of(frame, y, lane=int(frame.lane_id[ia]), exclude=(ia,))
            if il is not None:
                closing = speed - float(frame.speed[il])
                if closing > 1e-6:
                    ttc = max(float(frame.local_y[il]) - y - float(frame.length[il]), 0.0) / closing
            self._metric_rows.setdefault(a_id, []).append((step, t, speed, obs.d_AC, obs.d_AB, ttc))
            if a_id in ctl.decided:
                self._decision_rows.setdefault(a_id, []).append(
                    (step, t, *probs.tolist(), float(action), *paper_features(obs.d_AC, obs.b_is_truck, action)))

    def _flush(self) -> None:
        if not self._steps:
            return
        lens = np.asarray(self._lens)
        ids = np.concatenate(self._ids)
        roles = np.concatenate(self._roles)
        length = np.concatenate(self._len)
        n = length.size
        centers = np.empty((n, 3), dtype=np.float32)
        centers[:, 0] = np.concatenate(self._gx) - 0.5 * length
        centers[:, 1] = np.concatenate(self._gy)
        centers[:, 2] = 0.5 * VEHICLE_HEIGHT_FT
        half = np.empty((n, 3), dtype=np.float32)
        half[:, 0] = 0.5 * length
        half[:, 1] = 0.5 * np.concatenate(self._wid)
        half[:, 2] = 0.5 * VEHICLE_HEIGHT_FT
        cols = [
            *rr.Boxes3D.columns(centers=centers, half_sizes=half,
                                class_ids=roles, colors=ROLE_RGBA_U32[roles]).partition(lens),
            # an arrow array, not numpy: rerun turns a numpy column into one Python list per value
            *rr.AnyValues.columns(vehicle_id=pa.array(ids)).partition(lens),
        ]
        self._stream.send_columns(
            "world/vehicles",
            indexes=[rr.TimeColumn("step", sequence=np.asarray(self._steps)),
                     rr.TimeColumn("sim_time", duration=np.asarray(self._times))],
            columns=cols,
        )
        self._reset_buffers()

    def _flush_scalars(self) -> None:
        """Sends the buffered per-car series as columns, one ``send_columns`` per entity."""
        for a_id, rows in self._metric_rows.items():
            m = np.asarray(rows, dtype=np.float64)  # [n, 6]: step, t, speed, d_AC, d_AB, ttc
            for k, name in enumerate(("speed", "d_AC", "d_AB", "ttc"), start=2):
                keep = ~np.isnan(m[:, k]) if name == "ttc" else slice(None)
                self._send_series(f"metrics/A_{a_id}/{name}", m[keep, 0], m[keep, 1], m[keep, k])
        for a_id, rows in self._decision_rows.items():
            d = np.asarray(rows, dtype=np.float64)  # [n, 2 + 5 + 1 + 3]
            base = f"policy/A_{a_id}"
            self._stream.log(f"{base}/probs", rr.SeriesLines(names=[n.lower() for n in ACTION_NAMES]), static=True)
            self._send_series(f"{base}/probs", d[:, 0], d[:, 1], d[:, 2:7])
            self._send_series(f"{base}/action", d[:, 0], d[:, 1], d[:, 7])
            for k, name in enumerate(FEATURE_NAMES, start=8):
                self._send_series(f"{base}/features/{name}", d[:, 0], d[:, 1], d[:, k])
        self._metric_rows, self._decision_rows = {}, {}

    def _send_series(self, entity: str, steps: np.ndarray, times: np.ndarray, values: np.ndarray) -> None:
        """``values [n]`` (one series) or ``[n, S]`` (S series per row) on the step and sim_time timelines."""
        if steps.size == 0:
            return
        cols = rr.Scalars.columns(scalars=values.reshape(-1))
        if values.ndim == 2:
            cols = cols.partition(np.full(values.shape[0], values.shape[1]))
        self._stream.send_columns(
            entity,
            indexes=[rr.TimeColumn("step", sequence=steps.astype(np.int64)),
                     rr.TimeColumn("sim_time", duration=times)],
            columns=cols,
        )


def read_entities(path: str | os.PathLike) -> dict[str, list]:
    """Entity path -> list of pyarrow record batches of an ``.rrd`` (for tests and checks)."""
    from rerun.chunk import RrdReader

    out: dict[str, list] = {}
    for chunk in RrdReader(str(path)).store().stream():
        out.setdefault(chunk.entity_path, []).append(chunk.to_record_batch())
    return out


def recording_info(path: str | os.PathLike) -> dict[str, str | None]:
    """``{"application_id", "recording_id", "name"}`` of the (first) recording in an ``.rrd``
    (``name`` None if none was set).

    Raises:
        FileNotFoundError: no such file.
        ValueError: the file holds no recording.
    """
    from rerun.chunk import RrdReader

    if not Path(path).is_file():
        raise FileNotFoundError(f"{path}: no such recording")
    reader = RrdReader(str(path))
    entries = reader.recordings()
    if not entries:
        raise ValueError(f"{path}: no recording in this .rrd file")
    name = None
    for chunk in reader.stream(store=entries[0]):
        if chunk.entity_path == PROPERTIES:
            batch = chunk.to_record_batch()
            if "RecordingInfo:name" in batch.schema.names:
                name = str(batch.column("RecordingInfo:name")[0][0])
    return {"application_id": entries[0].application_id, "recording_id": entries[0].recording_id, "name": name}


def read_rrd_table(path: str | os.PathLike, entity: str | None = None, *, properties: bool = False):
    """An ``.rrd`` file as a pandas table, one row per logged row, in file order.

    Columns: ``entity`` (e.g. ``/metrics/A_12/speed``), ``static``, one column per timeline
    present (``step``, ``iteration``: integers; ``sim_time``: float seconds; NaN/None where an
    entity lacks it) and one per component (rerun's names, e.g. ``Scalars:scalars``,
    ``Boxes3D:centers``, ``vehicle_id``). A component column whose every value is a
    one-element list holds that element; others hold arrays (e.g. the 5 action probabilities
    of ``policy/A_<id>/probs``, or one array per frame of ``world/vehicles``).

    Example::

        df = read_rrd_table("runs/eval/rerun/qavg.rrd", "/metrics/")
        speed = df[df.entity.str.endswith("/speed")][["entity", "sim_time", "Scalars:scalars"]]

    Args:
        entity: keep only entities whose path starts with this (None: all).
        properties: also return the recording's properties (``/__properties``: name, start time).

    Raises:
        FileNotFoundError: no such file.
        ValueError: the file holds no recording.
    """
    import pandas as pd
    from rerun.chunk import RrdReader

    if not Path(path).is_file():
        raise FileNotFoundError(f"{path}: no such recording")
    reader = RrdReader(str(path))
    if not reader.recordings():
        raise ValueError(f"{path}: no recording in this .rrd file")
    parts = []
    for chunk in reader.stream():
        ent = chunk.entity_path
        if (entity is not None and not ent.startswith(entity)) or (ent == PROPERTIES and not properties):
            continue
        batch = chunk.to_record_batch()
        keep = [f.name for f in batch.schema if (f.metadata or {}).get(b"rerun:kind") != b"control"]
        df = batch.select(keep).to_pandas()
        for col in df.columns:
            if pd.api.types.is_timedelta64_dtype(df[col]):
                df[col] = df[col].dt.total_seconds()
        df.insert(0, "static", bool(chunk.is_static))
        df.insert(0, "entity", ent)
        parts.append(df)
    if not parts:
        return pd.DataFrame({"entity": pd.Series(dtype=object), "static": pd.Series(dtype=bool)})
    table = pd.concat(parts, ignore_index=True)
    for col in table.columns[2:]:
        values = table[col].dropna()
        if len(values) and all(hasattr(v, "__len__") and not isinstance(v, str) and len(v) == 1 for v in values):
            table[col] = [v[0] if hasattr(v, "__len__") and not isinstance(v, str) else v for v in table[col]]
    return table
