"""Write a run to a rerun ``.rrd`` file, headless (no viewer, no display needed).

:class:`RerunLogger` is a :class:`sim.runtime.hooks.StepHook`. Entities (hierarchical, units ft, ft/s):

* ``world/road`` (static): each lane drawn as a band of its real width (``LineStrips2D`` with
  radius half the lane width, in ft), so that the road reads as a road at any zoom;
* ``world/lanes`` (static): one ``LineStrips2D`` strip per lane centre line (I-80 numbering,
  labelled by its role: "lane 6 (right main lane)", "lane 7 (ramp / auxiliary lane)"), from
  the run's lane shapes;
* ``world/landmarks`` (static, ``Points2D`` with labels): "on-ramp" where lane 7 begins,
  "merge zone: auxiliary lane begins" (:func:`sim.runtime.lanes.aux_lane_start_ft`) and "auxiliary lane
  ends" where lane 7 ends; ``world`` (static) carries an ``AnnotationContext``
  naming the vehicle roles and a ``Transform3D`` mirroring y, so that the top-down 2D views
  (whose y axis points down) show the road as SUMO draws it (ramp on the right of travel).
* ``world/vehicles``: every vehicle of every frame as ONE batched ``Boxes2D`` entity, in the
  vehicles' real size: centres (the box centre, half a length behind the front bumper along
  +x), half sizes (length/2, width/2), ``class_ids`` = role (:data:`ROLE_IDS`: 0 other,
  1 A controlled, 2 B merging, 3 C lead, 4 A observed, i.e. a lag car the policy does not
  drive, as with the ``sumo`` baseline) with matching ``colors``, ``labels`` on A, B and C
  only ("A 12"; others ""), and an extra component ``vehicle_id`` (the table's Vehicle_ID), so
  each box can be matched to the trajectory table (front bumper = centre + (length/2, 0)).
* ``follow`` (``Transform3D`` per frame): the centre of the current merge (car A of the lowest
  Vehicle_ID under control; held between merges) in the mirrored frame; the blueprint's
  "merge" view has it as origin, so that view follows the merge.
* ``policy/A_<id>/probs`` (``Scalars``, 5 series named by action), ``policy/A_<id>/action``
  (``Scalars``: action index 0..4), ``policy/action_probs`` (``BarChart``: the 5 probabilities
  of the latest decision of any controlled car, in ``ACTION_NAMES`` order; rerun 0.41's bar
  charts have no bar names), ``policy/action_bars`` (``Boxes2D``, the same probabilities as
  five named bars: one box per action of height its probability, labelled with it, and static
  ``policy/action_bars/names`` labelling each bar with its action's name),
  ``policy/A_<id>/features/<name>`` (``Scalars``: the paper's reward features of the chosen
  action, from the continuous observation) at each decision of controlled car ``<id>``.
* ``metrics/A_<id>/speed``, ``.../d_AC``, ``.../d_AB``, ``.../ttc`` (``Scalars``) per frame
  while ``<id>`` is controlled (``ttc`` only when A closes in on its leader).
* ``train/<method>/loglik`` and ``train/<method>/theta/<k>`` (``Scalars`` on the
  ``iteration`` timeline): IRL training traces, via :func:`log_training`.

Timelines: ``sim_time`` (duration, s) and ``step`` (sequence: Frame_ID).

Every recording written by :class:`RerunLogger` carries a blueprint (:func:`~analysis.recording.blueprint.merge_blueprint`),
sent with the data, so the viewer opens on the merge view, car A's time series, the action
probabilities and (when logged) the training traces instead of its automatic layout. Frames are buffered
and sent in columns (``send_columns``) every ``flush_every`` frames, which keeps logging well
under 10 microseconds per vehicle-frame. The file is written under a temporary name
(``<name>.partial``) and renamed only when the run succeeds (``on_end``); a run that fails or
is interrupted (``on_abort``) leaves the ``.partial`` file, never a complete-looking ``.rrd``.
The static scene (road, lanes, landmarks, roles): :mod:`analysis.recording.scene`; the columns
sent in bulk: :mod:`analysis.recording.columns`. Naming, opening and closing the file: :mod:`analysis.recording.files`. Reading a recording back:
:mod:`analysis.recording.read`.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pyarrow as pa
import rerun as rr

from analysis.recording.blueprint import merge_blueprint
from analysis.recording.columns import action_bar_columns, bar_chart_column
from analysis.recording.files import close_recording, open_recording, policy_digest, recording_identity, run_token
from analysis.recording.scene import ROLE_IDS, ROLE_LABELS, ROLE_RGBA_U32, log_scene
from irl.domains.merge.actions import ACTION_NAMES
from irl.domains.merge.features import FEATURE_NAMES, paper_features
from sim.drivers.observe import lead_of
from sim.runtime.hooks import FrameState, RunContext
from sim.runtime.sites import I80

__all__ = ["RerunLogger", "log_training"]

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
        controller: the run's :class:`sim.closed_loop.controller.Controller` (must run *before* this hook);
            gives roles, decisions and controlled cars. Without it, vehicles on the
            site's ramp lane (I-80: 7) are shown as B.
        recording: an open stream (from :func:`~analysis.recording.files.open_recording`) to add to instead of opening
            one; then the caller closes it.
        flush_every: frames buffered before they are sent.
        log_vehicles: log ``world/vehicles`` (False: only policy/metrics scalars).
        episode: the episode's index, if the file holds one episode of several; it goes into
            the recording id and name (:func:`~analysis.recording.files.recording_identity`) with the scenario, the
            controller's policy (``sumo`` without a controller), the seed and the run
            (:func:`~analysis.recording.files.run_token` of ``path``, the scenario and the policy's content).
        training_methods: methods whose traces (:func:`log_training`) the recording holds,
            for the blueprint's training tab.
    """

    def __init__(self, path: str | os.PathLike, *, controller=None, recording: tuple[rr.RecordingStream, Path] | None = None,
                 flush_every: int = 600, log_vehicles: bool = True, application_id: str = "merge-irl",
                 episode: int | None = None, training_methods: Sequence[str] = ()):
        self.path = Path(path)
        self.training_methods = tuple(training_methods)
        self._section: tuple[float, float, float, float] | None = None
        self._focus = np.zeros(2)
        self._ramp_lane = I80.ramp_lanes[0]  # the run's site profile's, set by on_start
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
        self._lanes: list[np.ndarray] = []  # without a controller: roles come from the lanes
        self._ids: list[np.ndarray] = []
        self._marks: list[tuple[int, int]] = []  # (row in the buffer, role id): the controller's A, B, C
        self._n_buffered = 0  # vehicle rows buffered
        self._foci: list[np.ndarray] = []

    @property
    def _stream(self) -> rr.RecordingStream:
        if self._rec is None:
            raise RuntimeError("RerunLogger: the recording opens in on_start; nothing can be logged before")
        return self._rec

    # -- hook protocol -------------------------------------------------------------------
    def on_start(self, ctx: RunContext) -> None:
        if self._rec is None:
            driver = self.controller.policy if self.controller is not None else None
            policy = driver.name if driver is not None else "sumo"
            run = run_token(self.path, ctx.spec.to_toml(), policy_digest(driver))  # unique per run, deterministic
            rid, name = recording_identity(ctx.spec.name, policy, ctx.seed, self.episode, run=run)
            self._rec, self._tmp = open_recording(self.path, application_id=self._app, recording_id=rid, name=name)
        self._ramp_lane = int(ctx.site.ramp_lanes[0])
        bounds = log_scene(self._stream, ctx)
        if bounds is not None:
            self._section, self._focus = bounds

    def on_step(self, ctx: RunContext, frame: FrameState) -> None:
        n = len(frame.sumo_ids)
        if self.log_vehicles:
            # the frame's arrays are read-only and never reused: keep references, not copies;
            # roles and labels are built for the whole buffer in _flush
            self._gx.append(frame.global_x)
            self._gy.append(frame.global_y)
            self._len.append(frame.length)
            self._wid.append(frame.width)
            self._ids.append(frame.vehicle_id)
            if self.controller is None:
                self._lanes.append(frame.lane_id)
            else:
                self._mark_roles(frame)
            self._foci.append(self._focus)
            self._n_buffered += n
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
        a_ids, first = self._controls()
        # TTC is logged only while A closes in on its leader: name only the series that exist
        ttc_ids = [a for a in a_ids if any(r[5] == r[5] for r in self._metric_rows.get(a, ()))]
        self._flush_scalars()
        self._stream.send_blueprint(merge_blueprint(a_ids, training_methods=self.training_methods,
                                                    section_bounds=self._section, first_control=first,
                                                    ttc_ids=ttc_ids))
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
    def _mark_roles(self, frame: FrameState) -> None:
        """Buffers the controller's roles of the frame (A, B, C rows; the others are "other") and
        moves the focus to the current merge: the centre (mirrored frame, ft) of its car A, the
        controlled A of the lowest Vehicle_ID; the focus stays where it was between merges."""
        a_role = ROLE_IDS["A"] if getattr(self.controller.policy, "controls", True) else ROLE_IDS["A observed"]
        base = self._n_buffered
        a_rows = []
        for row, role in self.controller.role_rows.items():
            if role == "A":
                a_rows.append(row)
                self._marks.append((base + row, a_role))
            else:
                self._marks.append((base + row, ROLE_IDS[role]))
        if a_rows:
            vid = frame.vehicle_id
            i = min(a_rows, key=lambda r: int(vid[r]))
            self._focus = np.array([float(frame.global_x[i]) - 0.5 * float(frame.length[i]), -float(frame.global_y[i])])

    def _buffered_roles(self, ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Role ids ``uint16[n]`` of the buffered vehicle rows and their labels (``[n]`` object
        array: "A 12" etc. on A, B and C, "" on the others)."""
        roles = np.zeros(ids.size, dtype=np.uint16)
        if self.controller is None:
            roles[np.concatenate(self._lanes) == self._ramp_lane] = ROLE_IDS["B"]
        elif self._marks:
            rows, role_ids = zip(*self._marks)
            roles[list(rows)] = role_ids
        labels = np.full(roles.size, "", dtype=object)
        marked = np.flatnonzero(roles)
        for i, r, v in zip(marked.tolist(), roles[marked].tolist(), ids[marked].tolist()):
            labels[i] = f"{ROLE_LABELS[r]} {v}"
        return roles, labels

    def _controls(self) -> tuple[list[int], tuple[int, int] | None]:
        """Controlled cars' ids (in order of take-over) and the first take-over's frame range."""
        if self.controller is None or not self.controller.controls:
            return [], None
        cs = sorted(self.controller.controls, key=lambda c: (c.start_frame, c.a_id))
        c = cs[0]
        end = c.end_frame if c.end_frame >= 0 else c.start_frame + 300
        return list(dict.fromkeys(int(x.a_id) for x in cs)), (int(c.start_frame), int(end))

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
        roles, labels = self._buffered_roles(ids)
        length = np.concatenate(self._len)
        n = length.size
        centers = np.empty((n, 2), dtype=np.float32)
        centers[:, 0] = np.concatenate(self._gx) - 0.5 * length
        centers[:, 1] = np.concatenate(self._gy)
        half = np.empty((n, 2), dtype=np.float32)
        half[:, 0] = 0.5 * length
        half[:, 1] = 0.5 * np.concatenate(self._wid)
        cols = [
            *rr.Boxes2D.columns(centers=centers, half_sizes=half, class_ids=roles, colors=ROLE_RGBA_U32[roles],
                                labels=pa.array(labels, type=pa.string())).partition(lens),
            # the viewer hides the labels of entities with many instances; the others' labels are ""
            *rr.Boxes2D.columns(show_labels=[True] * lens.size),
            # an arrow array, not numpy: rerun turns a numpy column into one Python list per value
            *rr.AnyValues.columns(vehicle_id=pa.array(ids)).partition(lens),
        ]
        indexes = [rr.TimeColumn("step", sequence=np.asarray(self._steps)),
                   rr.TimeColumn("sim_time", duration=np.asarray(self._times))]
        self._stream.send_columns("world/vehicles", indexes=indexes, columns=cols)
        foci = np.zeros((len(self._foci), 3))
        foci[:, :2] = self._foci
        self._stream.send_columns("follow", indexes=indexes, columns=rr.Transform3D.columns(translation=foci))
        self._reset_buffers()

    def _flush_scalars(self) -> None:
        """Sends the buffered per-car series as columns, one ``send_columns`` per entity."""
        for a_id, rows in self._metric_rows.items():
            m = np.asarray(rows, dtype=np.float64)  # [n, 6]: step, t, speed, d_AC, d_AB, ttc
            for k, name in enumerate(("speed", "d_AC", "d_AB", "ttc"), start=2):
                keep = ~np.isnan(m[:, k]) if name == "ttc" else slice(None)
                self._send_series(f"metrics/A_{a_id}/{name}", m[keep, 0], m[keep, 1], m[keep, k])
        bars: list[np.ndarray] = []
        for a_id, rows in self._decision_rows.items():
            d = np.asarray(rows, dtype=np.float64)  # [n, 2 + 5 + 1 + 3]
            base = f"policy/A_{a_id}"
            self._stream.log(f"{base}/probs", rr.SeriesLines(names=[n.lower() for n in ACTION_NAMES]), static=True)
            self._send_series(f"{base}/probs", d[:, 0], d[:, 1], d[:, 2:7])
            self._send_series(f"{base}/action", d[:, 0], d[:, 1], d[:, 7])
            bars.append(d[:, :7])
            for k, name in enumerate(FEATURE_NAMES, start=8):
                self._send_series(f"{base}/features/{name}", d[:, 0], d[:, 1], d[:, k])
        if bars:
            b = np.concatenate(bars)
            b = b[np.argsort(b[:, 0], kind="stable")]  # [n, 7]: step, t, p0..p4, by step
            self._stream.send_columns(
                "policy/action_probs",
                indexes=[rr.TimeColumn("step", sequence=b[:, 0].astype(np.int64)), rr.TimeColumn("sim_time", duration=b[:, 1])],
                columns=[bar_chart_column(b[:, 2:7])])
            self._stream.send_columns(
                "policy/action_bars",
                indexes=[rr.TimeColumn("step", sequence=b[:, 0].astype(np.int64)), rr.TimeColumn("sim_time", duration=b[:, 1])],
                columns=action_bar_columns(b[:, 2:7]))
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
