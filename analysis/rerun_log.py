"""Write a run to a rerun ``.rrd`` file, headless (no viewer, no display needed).

:class:`RerunLogger` is a :class:`sim.hooks.StepHook`. Entities (hierarchical, units ft, ft/s):

* ``world/lanes`` (static): one ``LineStrips2D`` strip per lane centre line (I-80 numbering,
  labelled), from the run's lane shapes; ``world`` (static) carries an ``AnnotationContext``
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
  of the latest decision of any controlled car, in ``ACTION_NAMES`` order),
  ``policy/A_<id>/features/<name>`` (``Scalars``: the paper's reward features of the chosen
  action, from the continuous observation) at each decision of controlled car ``<id>``.
* ``metrics/A_<id>/speed``, ``.../d_AC``, ``.../d_AB``, ``.../ttc`` (``Scalars``) per frame
  while ``<id>`` is controlled (``ttc`` only when A closes in on its leader).
* ``train/<method>/loglik`` and ``train/<method>/theta/<k>`` (``Scalars`` on the
  ``iteration`` timeline): IRL training traces, via :func:`log_training`.

Timelines: ``sim_time`` (duration, s) and ``step`` (sequence: Frame_ID).

Every recording written by :class:`RerunLogger` carries a blueprint (:func:`merge_blueprint`),
sent with the data, so the viewer opens on the merge view, car A's time series, the action
probabilities and (when logged) the training traces instead of its automatic layout. Frames are buffered
and sent in columns (``send_columns``) every ``flush_every`` frames, which keeps logging well
under 10 microseconds per vehicle-frame. The file is written under a temporary name
(``<name>.partial``) and renamed only when the run succeeds (``on_end``); a run that fails or
is interrupted (``on_abort``) leaves the ``.partial`` file, never a complete-looking ``.rrd``.
Reading a recording back: :mod:`analysis.rrd_read`.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pyarrow as pa
import rerun as rr

from irl.atomic import move_into_place, temporary_path
from irl.domains.merge_actions import ACTION_NAMES
from irl.domains.merge_features import FEATURE_NAMES, paper_features
from sim.hooks import FrameState, RunContext
from sim.observe import lead_of
from sim.schema import RAMP_LANE

ROLE_IDS = {"other": 0, "A": 1, "B": 2, "C": 3, "A observed": 4}
#: Short label drawn on a box, by role id ("" = no label).
ROLE_LABELS = ("", "A", "B", "C", "A")
#: RGBA colours of the roles, indexed by role id.
ROLE_COLORS = np.array(
    [[150, 150, 150, 255], [230, 40, 40, 255], [40, 110, 230, 255], [40, 180, 70, 255], [240, 150, 30, 255]],
    dtype=np.uint8,
)
ROLE_RGBA_U32 = (ROLE_COLORS.astype(np.uint32) @ np.array([1 << 24, 1 << 16, 1 << 8, 1], dtype=np.uint32)).astype(np.uint32)
#: The ``world`` transform: y mirrored (2D views draw y downwards).
MIRROR_Y = np.diag([1.0, -1.0, 1.0])
#: Half extent (ft) of the merge view around the followed car.
FOLLOW_HALF_FT = (330.0, 75.0)
#: TTC axis of the time series (s): larger values are off the chart.
TTC_RANGE_S = (0.0, 10.0)
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


def merge_blueprint(a_ids: Sequence[int], *, training_methods: Sequence[str] = (),
                    section_bounds: tuple[float, float, float, float] | None = None,
                    first_control: tuple[int, int] | None = None, play: float | None = None,
                    active_tab: int = 0, ttc_ids: Sequence[int] | None = None):
    """The viewer layout of a run's recording (``rerun.blueprint.Blueprint``).

    Tab "run": the merge view (2D, origin ``/follow``: follows the current merge), the whole
    section (2D, origin ``/``), and the group "car A": time series of speed, d_AB, d_AC, TTC
    (y axis clipped to :data:`TTC_RANGE_S`) and the action taken of every controlled car, and
    the bar chart of the current action probabilities. Tab "training" (only when
    ``training_methods`` is not empty): log-likelihood and weights against the iteration.
    The time panel shows the ``step`` timeline, paused, with the first take-over selected.
    ``ttc_ids``: the cars with a TTC series (None: all of ``a_ids``).

    Args:
        a_ids: Vehicle_IDs of the controlled cars (their ``metrics/A_<id>`` entities).
        training_methods: the ``<method>`` of the ``train/<method>`` entities.
        section_bounds: ``(x_min, x_max, y_min, y_max)`` ft of the lanes in the mirrored
            frame, the section view's bounds; None: the viewer's own.
        first_control: ``(start_frame, end_frame)`` of the first take-over (Frame_IDs).
        play: play at this speed (x real time) and loop over the selection once the cursor
            reaches it, instead of pausing (for screenshots: the blueprint has no setting for
            the time cursor, which starts at the first frame).
        active_tab: the tab shown first (0 run, 1 training); with the training tab the time
            panel shows the ``iteration`` timeline.
    """
    import rerun.blueprint as rrb
    from rerun.blueprint.components import AbsoluteTimeRange

    def series(name: str, paths: list[str], **kw):
        return rrb.TimeSeriesView(name=name, origin="/", contents=paths or ["-/**"],
                                  plot_legend=rrb.PlotLegend(visible=False), **kw)

    ids = [int(a) for a in a_ids]
    fx, fy = FOLLOW_HALF_FT
    merge = rrb.Spatial2DView(
        name="merge (follows car A)", origin="/follow", contents=["/world/**"],
        visual_bounds=rrb.VisualBounds2D(x_range=(-fx, fx), y_range=(-fy, fy)), background=[30, 30, 30])
    bounds = None
    if section_bounds is not None:
        x0, x1, y0, y1 = section_bounds
        bounds = rrb.VisualBounds2D(x_range=(x0, x1), y_range=(y0, y1))
    section = rrb.Spatial2DView(name="section", origin="/", contents=["/world/**"], background=[30, 30, 30],
                                visual_bounds=bounds)
    car_a = rrb.Vertical(
        series("speed of A (ft/s)", [f"/metrics/A_{a}/speed" for a in ids]),
        series("d_AB (ft)", [f"/metrics/A_{a}/d_AB" for a in ids]),
        series("d_AC (ft)", [f"/metrics/A_{a}/d_AC" for a in ids]),
        series("TTC A to its leader (s)", [f"/metrics/A_{a}/ttc" for a in (ids if ttc_ids is None else ttc_ids)],
               axis_y=rrb.ScalarAxis(range=TTC_RANGE_S, zoom_lock=True)),
        series("action of A (0 " + ACTION_NAMES[0].lower() + " .. 4 " + ACTION_NAMES[-1].lower() + ")",
               [f"/policy/A_{a}/action" for a in ids], axis_y=rrb.ScalarAxis(range=(-0.2, 4.2), zoom_lock=True)),
        rrb.BarChartView(name="action probabilities now (" + ", ".join(n.lower() for n in ACTION_NAMES) + ")",
                         origin="/policy/action_probs"),
        name="car A",
    )
    tabs: list[rrb.Container] = [rrb.Horizontal(rrb.Vertical(merge, section, row_shares=[3, 2]), car_a, column_shares=[3, 2], name="run")]
    if training_methods:
        tabs.append(rrb.Vertical(
            series("log-likelihood", [f"/train/{m}/loglik" for m in training_methods]),
            rrb.TimeSeriesView(name="weights theta", origin="/train", contents=[f"/train/{m}/theta/**" for m in training_methods]),
            name="training"))
    sel = None if first_control is None else AbsoluteTimeRange(min=int(first_control[0]), max=int(first_control[1]))
    return rrb.Blueprint(
        rrb.Tabs(*tabs, active_tab=min(int(active_tab), len(tabs) - 1)),
        rrb.TimePanel(timeline="iteration" if active_tab == 1 and training_methods else "step", state="collapsed",
                      time_selection=sel, play_state="playing" if play and sel is not None else "paused",
                      playback_speed=float(play) if play else None,
                      loop_mode="selection" if play and sel is not None else None),
        rrb.BlueprintPanel(state="collapsed"), rrb.SelectionPanel(state="collapsed"),
        auto_views=False,
    )


class _ArrowBatch:
    """A ready arrow array as a rerun component batch (what ``rr.ComponentColumn`` takes)."""

    def __init__(self, array: pa.Array, descriptor):
        self._array, self._descriptor = array, descriptor

    def as_arrow_array(self) -> pa.Array:
        return self._array

    def component_descriptor(self):
        return self._descriptor


def bar_chart_column(values: np.ndarray) -> rr.ComponentColumn:
    """``BarChart`` values as one column of ``n`` bar charts (rows of ``values [n, k]``, float64).

    rerun's Python API builds a bar chart's tensor one call at a time (about 1 ms each); this
    builds the same arrow layout (TensorData: shape ``[k]``, no names, an F64 buffer) for all
    rows at once, typed after a one-row sample.
    """
    values = np.ascontiguousarray(values, dtype=np.float64)
    n, k = values.shape
    sample = next(iter(rr.BarChart.columns(values=np.zeros(max(k, 1)))))
    st = sample.component_batch.as_arrow_array().type
    ut = st.field("buffer").type
    names = [f.name for f in ut]
    children = [pa.ListArray.from_arrays(pa.array(np.arange(0, n * k + 1, k, dtype=np.int32)), pa.array(values.reshape(-1)),
                                         type=f.type) if f.name == "F64" else pa.array([], type=f.type) for f in ut]
    buf = pa.UnionArray.from_dense(pa.array(np.full(n, ut.type_codes[names.index("F64")], dtype=np.int8)),
                                   pa.array(np.arange(n, dtype=np.int32)), children, field_names=names,
                                   type_codes=list(ut.type_codes)).view(ut)
    shape = pa.ListArray.from_arrays(pa.array(np.arange(n + 1, dtype=np.int32)), pa.array(np.full(n, k, dtype=np.uint64)),
                                     type=st.field("shape").type)
    arr = pa.StructArray.from_arrays([shape, pa.nulls(n, st.field("names").type), buf], fields=list(st))
    desc = sample.component_descriptor()
    return rr.ComponentColumn(desc, _ArrowBatch(arr, desc))


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
        self._labels: list[np.ndarray] = []
        self._foci: list[np.ndarray] = []

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
        strips = [np.asarray(ctx.lane_shapes[n], float)[:, :2] for n in names]
        rec.log("world/lanes", rr.LineStrips2D(strips, labels=[f"lane {n}" for n in names], draw_order=10.0,
                                               radii=rr.Radius.ui_points(1.0),
                                               colors=[[110, 110, 110, 255]] * len(strips)), static=True)
        rec.log("world", rr.AnnotationContext(
            [(i, name, tuple(int(c) for c in ROLE_COLORS[i][:3])) for name, i in ROLE_IDS.items()]), static=True)
        rec.log("world", rr.Transform3D(mat3x3=MIRROR_Y), static=True)
        if strips:
            pts = np.concatenate(strips) @ MIRROR_Y[:2, :2]
            lo, hi = pts.min(axis=0) - 30.0, pts.max(axis=0) + 30.0
            self._section = (float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1]))
            self._focus = 0.5 * (lo + hi)

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
            self._labels.append(self._labels_of(roles, frame.vehicle_id))
            self._foci.append(self._focus_of(frame, roles))
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
    def _roles_of(self, frame: FrameState) -> np.ndarray:
        roles = np.zeros(len(frame.sumo_ids), dtype=np.uint16)
        if self.controller is None:
            roles[frame.lane_id == RAMP_LANE] = ROLE_IDS["B"]
            return roles
        a_role = ROLE_IDS["A"] if getattr(self.controller.policy, "controls", True) else ROLE_IDS["A observed"]
        for row, role in self.controller.role_rows.items():
            roles[row] = a_role if role == "A" else ROLE_IDS[role]
        return roles

    @staticmethod
    def _labels_of(roles: np.ndarray, ids: np.ndarray) -> np.ndarray:
        """``[n]`` object array: "A 12" etc. on A, B and C, "" on the others."""
        labels = np.full(roles.size, "", dtype=object)
        for i in np.flatnonzero(roles):
            labels[i] = f"{ROLE_LABELS[roles[i]]} {int(ids[i])}"
        return labels

    def _focus_of(self, frame: FrameState, roles: np.ndarray) -> np.ndarray:
        """Centre (mirrored frame, ft) of the current merge's car A; the last one between merges."""
        a_rows = np.flatnonzero((roles == ROLE_IDS["A"]) | (roles == ROLE_IDS["A observed"]))
        if a_rows.size:
            i = a_rows[np.argmin(frame.vehicle_id[a_rows])]
            self._focus = np.array([float(frame.global_x[i]) - 0.5 * float(frame.length[i]), -float(frame.global_y[i])])
        return self._focus

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
        roles = np.concatenate(self._roles)
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
                                labels=pa.array(np.concatenate(self._labels), type=pa.string())).partition(lens),
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
