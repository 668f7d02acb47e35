"""A SUMO run as a stepped session: start it, step it frame by frame, close it.

:class:`SumoSession` owns the libsumo loop that :func:`sim.runtime.run.run_scenario` used to own:
``start()`` writes the network and routes, starts SUMO and returns the run's
:class:`~sim.runtime.hooks.RunContext`; each ``step()`` advances SUMO to the next recorded frame (0.1 s
of simulated time; the first call runs the warm-up) and returns a :class:`SessionStep`, the
frame's :class:`~sim.runtime.hooks.FrameState` with SUMO's events since the previous frame; ``close()``
closes SUMO and removes the temporary folder (idempotent; the context manager calls it, also on
an error or Ctrl-C, and ``start`` does when it fails). Between two ``step()`` calls any code may call
SUMO through the session's handle, :attr:`SumoSession.sumo` (also ``context.sumo``), e.g.
``session.sumo.vehicle.setAcceleration(...)``; the commands act in the next step.

Several sessions in one process: libsumo holds one simulation per process, so the first open
session runs in libsumo (in the process, the fast path) and any session started while it is open
runs the ``sumo`` binary as a child process through TraCI (the ``traci`` package, a connection
of its own per session; :class:`TraciHandle` gives it libsumo's names). ``backend`` says which
(``"libsumo"`` or ``"traci"``; two threads starting sessions at once get one each). Both run the
same SUMO version on the same inputs, so a seed gives the same run in either. TraCI costs a
socket round trip per call, several times slower (an environment step about 6x), so parallel
runs still belong in processes of their own (one libsumo each), started with 'spawn': a process
forked while a session is open inherits that session, and its own runs go through TraCI. This is
what lets Gymnasium's and PettingZoo's checkers, which hold two environments at once, pass. Once
the libsumo session is closed, the next session started takes libsumo again.

Recording: at each recorded frame the session reads every vehicle's position, speed and
acceleration with direct calls (measured cheaper than per-vehicle subscriptions,
which SUMO updates at every step, and nothing to unsubscribe when a hook removes a vehicle);
each frame becomes one read-only ``[V, 4]`` array (plus id, lane and static arrays, rebuilt
only when the set of vehicles changes), which the frame state exposes as column views and
the optional recorder keeps by reference (``record=True``: :meth:`SumoSession.table`).

Coordinates, lanes and ids: as :mod:`sim.runtime.run` documents them (NGSIM units: ft, ft/s).
"""

from __future__ import annotations

import contextlib
import io
import math
import os
import shutil
import subprocess
import tempfile
import threading
import time
from dataclasses import dataclass
from itertools import chain, count
from pathlib import Path
from typing import Any

import numpy as np

from merge_irl.units import FRAME_S, FT_PER_M
from scenarios.routes import type_class_map
from scenarios.spec.model import ScenarioSpec
from scenarios.spec.parse import with_overrides
from sim.errors import SimulationError
from sim.runtime.hooks import FrameState, RunContext
from sim.runtime.lanes import LaneNumbering, lane_tables
from sim.runtime.recorder import TrajectoryRecorder
from sim.runtime.run_result import RunEvents
from sim.runtime.schema import V_CLASS_AUTO, V_CLASS_TRUCK
from sim.runtime.sites import site_of
from sim.runtime.sumo_inputs import prepare_inputs, sumo_args, sumo_binary

#: The session holding libsumo in this process (libsumo runs one simulation at a time), or None.
_OPEN: SumoSession | None = None
#: Held while a starting session claims libsumo.
_CLAIM = threading.Lock()


@dataclass(frozen=True)
class StepEvents:
    """SUMO's reports since the previous recorded frame (simulated seconds, SUMO ids).

    Attributes:
        teleports: ``(time_s, sumo_id)`` of teleports that started (``getStartingTeleportIDList``).
        collisions: ``(time_s, sumo_id)``, one per colliding vehicle and simulation step.
        emergency_stops: ``(time_s, sumo_id)`` of emergency stops.
        departed: vehicles that entered the network so far in the run (count).
        backlog: vehicles due but still waiting to be inserted now (``getPendingVehicles``).
    """

    teleports: tuple[tuple[float, str], ...]
    collisions: tuple[tuple[float, str], ...]
    emergency_stops: tuple[tuple[float, str], ...]
    departed: int
    backlog: int


@dataclass(frozen=True)
class SessionStep:
    """One recorded frame of a session: the frame's state and the events that led to it."""

    frame: FrameState
    events: StepEvents


class SumoSession:
    """One SUMO run of ``spec``, stepped from outside (see the module docstring).

    Args:
        spec: the scenario.
        seed, duration_s: override the spec's (None: the spec's).
        work_dir: folder for the network and route files (None: a temporary folder, removed on close).
        progress: the progress of simulated time on stderr (:func:`merge_irl.progress.progress_bar`:
            a bar on a terminal, lines elsewhere).
        record: keep every frame for :meth:`table` (the trajectory table); off for an environment.

    Attributes:
        backend: ``"libsumo"`` or ``"traci"`` once started (``""`` before; module docstring).

    Raises (from ``start`` / ``step``):
        SimulationError: SUMO fails to start or to step.
    """

    def __init__(self, spec: ScenarioSpec, seed: int | None = None, *, duration_s: float | None = None,
                 work_dir: Path | str | None = None, progress: bool = False, record: bool = True):
        if seed is not None or duration_s is not None:
            spec = with_overrides(spec, seed=seed, duration_s=duration_s)
        self.spec = spec
        self.seed = int(spec.simulation.seed)
        self.progress = progress
        self.recorder: TrajectoryRecorder | None = TrajectoryRecorder() if record else None
        self.context: RunContext | None = None
        self.sumo_time_s = 0.0  # wall time spent inside simulationStep (s)
        self._work_dir_arg = Path(work_dir) if work_dir is not None else None
        self._tmp: str | None = None
        self._ls: Any = None
        self.backend = ""  # "libsumo" or "traci" once started (module docstring)
        self._started = self._closed = False
        self._step = 0
        self._teleports: list[tuple[float, str]] = []
        self._collisions: list[tuple[float, str]] = []
        self._emergency: list[tuple[float, str]] = []
        self._depart_seq: dict[str, int] = {}
        self._vid_of: dict[str, int] = {}
        self._sumo_ids: list[str] = []
        self._static: dict[str, tuple[float, float, int]] = {}
        self._type_static: dict[str, tuple[float, float, int]] = {}
        self._prev_sids: tuple[str, ...] | None = None
        self._bar: Any = None
        self._shown = 0
        self._backlog = 0
        sim = spec.simulation
        self._record_every = int(round(FRAME_S / sim.step_s))
        self._n_steps = int(round(sim.duration_s / sim.step_s))
        self._warmup_frame = int(math.ceil(sim.warmup_s / FRAME_S - 1e-9))

    # -- life cycle ---------------------------------------------------------------------
    def start(self) -> RunContext:
        """Write the inputs, start SUMO and load the network; returns the run's context.

        Raises:
            SimulationError: SUMO fails to start, or the session was started before.
        """
        if self._started:
            raise SimulationError("SumoSession.start: this session was started already; make a new one")
        self._started = True
        spec = self.spec
        errors: tuple[type[BaseException], ...] = ()  # the backend's exceptions, once it is chosen
        try:
            site = site_of(spec)  # an unknown site fails before SUMO starts
            if self._work_dir_arg is None:
                self._tmp = tempfile.mkdtemp(prefix="merge-irl-run-")
                wd = Path(self._tmp)
            else:
                wd = self._work_dir_arg
                wd.mkdir(parents=True, exist_ok=True)
            net, routes = prepare_inputs(spec, wd)
            ls = self._open(sumo_args(spec, net, routes))
            errors = (ls.TraCIException, ls.FatalTraCIError)
            self._cls_of_type = type_class_map(spec)
            self._lane_of = LaneNumbering(spec.road.main_lanes, spec.road.lane_width_m * FT_PER_M, site)
            _, lane_shapes = lane_tables(ls, spec, site)
            vid_of, sumo_ids = self._vid_of, self._sumo_ids
            self.context = RunContext(
                spec=spec, seed=self.seed, step_length_s=spec.simulation.step_s, frame_s=FRAME_S,
                lane_shapes=lane_shapes, lane_width_ft=spec.road.lane_width_m * FT_PER_M,
                main_lanes=tuple(self._lane_of.numbers[:-1].tolist()),
                section_length_ft=spec.road.main_length_m * FT_PER_M,
                vehicle_id_of=vid_of.get,
                sumo_id_of=lambda v: sumo_ids[v - 1] if 1 <= v <= len(sumo_ids) else None,
                work_dir=str(wd), site=site, sumo=ls,
            )
            if self.progress:
                from merge_irl.progress import progress_bar

                self._bar = progress_bar(round(spec.simulation.duration_s), unit="sim s", desc=f"simulating {spec.name}")
        except BaseException as e:
            self.close()
            if isinstance(e, errors):
                raise SimulationError(f"SUMO error in scenario {spec.name!r}: {e}") from e
            raise
        return self.context

    def _open(self, args: list[str]) -> Any:
        """SUMO started with ``args``: in libsumo when no other session of this process holds it,
        else through TraCI (module docstring); the handle (``self.sumo``) is set only on success.

        Raises:
            SimulationError: SUMO fails to start.
        """
        global _OPEN
        with _CLAIM:  # two threads starting at once: one takes libsumo, the other TraCI
            take_libsumo = _OPEN is None or _OPEN._closed
            if take_libsumo:
                _OPEN = self
        if not take_libsumo:
            self._ls = _start_traci(args, self.spec.name)
            self.backend = "traci"
            return self._ls
        import libsumo as ls

        try:
            ls.start(["sumo", *args])
        except BaseException as e:  # libsumo raises its own TraCIException / FatalTraCIError
            _safe_close(ls)
            _OPEN = None
            if not isinstance(e, Exception):
                raise
            raise SimulationError(f"SUMO failed to start scenario {self.spec.name!r}: {e}") from e
        self._ls, self.backend = ls, "libsumo"
        return ls

    @property
    def sumo(self) -> Any:
        """The handle of this session's SUMO (None before ``start``): the ``libsumo`` module, or a
        :class:`TraciHandle` (module docstring); also ``context.sumo``."""
        return self._ls

    def close(self) -> None:
        """Close SUMO and remove the temporary folder; safe to call again and before ``start``."""
        global _OPEN
        if self._closed:
            return
        self._closed = True
        try:
            if self._bar is not None:
                self._bar.close()
        finally:
            if self.backend == "traci":
                _safe_close(self._ls)
            elif self._ls is not None and _OPEN is self:
                _safe_close(self._ls)
                _OPEN = None
            if self._tmp is not None:
                shutil.rmtree(self._tmp, ignore_errors=True)

    def __enter__(self) -> SumoSession:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def done(self) -> bool:
        """The run reached its duration (or was closed): ``step()`` returns None."""
        return self._closed or self._step >= self._n_steps

    # -- stepping -----------------------------------------------------------------------
    def step(self) -> SessionStep | None:
        """Advance SUMO to the next recorded frame after the warm-up; None once the run's
        duration is reached. SUMO stays open after an error (hooks may still release their
        vehicles): the context manager, or ``close()``, closes it, also on Ctrl-C.

        Raises:
            SimulationError: SUMO fails to step, or the session is not running.
        """
        if not self._started or self._closed:
            raise SimulationError("SumoSession.step: the session is not running (start() it; it may be closed)")
        ls = self._ls
        try:
            return self._advance(ls)
        except (ls.TraCIException, ls.FatalTraCIError) as e:
            raise SimulationError(f"SUMO error in scenario {self.spec.name!r}: {e}") from e

    def _advance(self, ls: Any) -> SessionStep | None:
        step_s = self.spec.simulation.step_s
        simulation = ls.simulation
        n_tel, n_col, n_em = len(self._teleports), len(self._collisions), len(self._emergency)
        while self._step < self._n_steps:
            self._step += 1
            step = self._step
            ts = time.perf_counter()
            ls.simulationStep()
            self.sumo_time_s += time.perf_counter() - ts
            now = step * step_s
            for lst, get in ((self._teleports, simulation.getStartingTeleportIDList),
                             (self._collisions, simulation.getCollidingVehiclesIDList),
                             (self._emergency, simulation.getEmergencyStoppingVehiclesIDList)):
                ids = get()
                if ids:
                    lst.extend((now, s) for s in ids)
            for sid in simulation.getDepartedIDList():
                self._depart_seq[sid] = len(self._depart_seq)
                tid = ls.vehicle.getTypeID(sid)
                if tid not in self._type_static:
                    cls = self._cls_of_type.get(tid, "car")
                    self._type_static[tid] = (ls.vehicletype.getLength(tid) * FT_PER_M,
                                              ls.vehicletype.getWidth(tid) * FT_PER_M,
                                              V_CLASS_TRUCK if cls == "truck" else V_CLASS_AUTO)
                self._static[sid] = self._type_static[tid]
            if self._bar is not None and int(step * step_s) > self._shown:
                self._bar.update(int(step * step_s) - self._shown)
                self._shown = int(step * step_s)
            if step % self._record_every:
                continue
            frame = step // self._record_every
            if frame < self._warmup_frame:
                continue
            fs = self._frame(ls, frame, step * step_s)
            self._backlog = len(simulation.getPendingVehicles())
            events = StepEvents(tuple(self._teleports[n_tel:]), tuple(self._collisions[n_col:]),
                                tuple(self._emergency[n_em:]), len(self._depart_seq), self._backlog)
            return SessionStep(fs, events)
        self._backlog = len(simulation.getPendingVehicles())
        return None

    def _frame(self, ls: Any, frame: int, time_s: float) -> FrameState:
        veh = ls.vehicle
        get_pos, get_speed, get_acc = veh.getPosition, veh.getSpeed, veh.getAcceleration
        sids = veh.getIDList()
        if sids != self._prev_sids:  # who is in the network changed: new id and static arrays
            vid_of = self._vid_of
            new = [s for s in sids if s not in vid_of]
            if new:
                new.sort(key=self._depart_seq.__getitem__)
                for s in new:
                    self._sumo_ids.append(s)
                    vid_of[s] = len(self._sumo_ids)
            self._vid = _frozen(np.array([vid_of[s] for s in sids], dtype=np.int64))
            st = _frozen(np.array([self._static[s] for s in sids], dtype=np.float64).reshape(-1, 3))
            self._st = st
            self._v_class = _frozen(st[:, 2].astype(np.int64))
            self._prev_sids = sids
        vid, st = self._vid, self._st
        # one array per frame: x, y (m), speed (m/s), acceleration (m/s^2) -> ft units
        kin = np.fromiter(chain.from_iterable((*get_pos(s), get_speed(s), get_acc(s)) for s in sids),
                          dtype=np.float64, count=4 * len(sids)).reshape(-1, 4)
        kin *= FT_PER_M
        local_x = _frozen(-kin[:, 1])
        lane = _frozen(self._lane_of(local_x))
        _frozen(kin)
        if self.recorder is not None:
            self.recorder.add(frame, vid, kin, lane, st)
        return FrameState(
            frame=frame, time_s=time_s, sumo_ids=sids, vehicle_id=vid,
            local_x=local_x, local_y=kin[:, 0], global_x=kin[:, 0], global_y=kin[:, 1],
            speed=kin[:, 2], acc=kin[:, 3], length=st[:, 0], width=st[:, 1],
            lane_id=lane, v_class=self._v_class,
        )

    # -- what the run leaves ------------------------------------------------------------
    @property
    def sumo_ids(self) -> tuple[str, ...]:
        """SUMO id of each Vehicle_ID (index ``Vehicle_ID - 1``), so far."""
        return tuple(self._sumo_ids)

    def events(self) -> RunEvents:
        """The run's events so far (whole run, warm-up included); the backlog as of the last frame."""
        spec = self.spec
        return RunEvents(tuple(self._teleports), tuple(self._collisions), tuple(self._emergency),
                         len(self._depart_seq), self._backlog, spec.simulation.duration_s,
                         float(sum(spec.demand.main_veh_h) + spec.demand.ramp_veh_h))

    def table(self):
        """The trajectory table of the recorded frames (``record=True``), a DataFrame of
        :data:`sim.runtime.schema.COLUMNS`.

        Raises:
            SimulationError: the session was made with ``record=False``.
        """
        if self.recorder is None:
            raise SimulationError("SumoSession.table: this session does not record (record=False)")
        return self.recorder.table()


def _frozen(a: np.ndarray) -> np.ndarray:
    a.flags.writeable = False
    return a


def _safe_close(ls: Any) -> None:
    try:
        ls.close()
    except Exception:
        pass


class TraciHandle:
    """A TraCI connection with the names callers use on the ``libsumo`` module: the domains
    (``vehicle``, ``simulation``, ``lane``, ...), ``simulationStep``, ``close`` and the exception
    classes ``TraCIException`` / ``FatalTraCIError`` (TraCI's own, raised by its calls).

    Attributes:
        connection: the ``traci.connection.Connection``.
        process: its SUMO, a child process (``subprocess.Popen``).
    """

    def __init__(self, connection: Any, process: subprocess.Popen[bytes]):
        import traci

        self.connection = connection
        self.process = process
        self.TraCIException = traci.TraCIException
        self.FatalTraCIError = traci.FatalTraCIError

    def __getattr__(self, name: str) -> Any:
        return getattr(self.connection, name)

    def close(self) -> None:
        """Close the connection and end its SUMO (killed if it has not ended within 10 s or the
        connection was broken)."""
        try:
            self.connection.close(wait=False)
        finally:
            try:
                self.process.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()


#: Tries to start SUMO through TraCI (a port taken between choosing it and SUMO binding it).
_TRACI_TRIES = 3
#: Seconds between two attempts to connect to a starting SUMO, and the attempts (30 s in all).
_CONNECT_WAIT_S, _CONNECT_TRIES = 0.02, 1500
_TRACI_LABELS = count(1)


def _start_traci(args: list[str], name: str) -> TraciHandle:
    """The ``sumo`` binary started with ``args`` as a TraCI server, connected under a label of its
    own (the module-level ``traci`` connection is left alone).

    Raises:
        SimulationError: SUMO fails to start or to accept the connection (its own message goes to
            stderr).
    """
    import traci
    from sumolib.miscutils import getFreeSocketPort

    binary = sumo_binary("sumo")
    label = f"merge-irl-session-{os.getpid()}-{next(_TRACI_LABELS)}"
    err: Exception | None = None
    for _ in range(_TRACI_TRIES):
        port = getFreeSocketPort()
        proc = subprocess.Popen([binary, *args, "--remote-port", str(port)], stdout=subprocess.DEVNULL)
        try:
            with contextlib.redirect_stdout(io.StringIO()):  # traci prints each retry
                conn = traci.connect(port, _CONNECT_TRIES, "localhost", proc, _CONNECT_WAIT_S, label=label)
            return TraciHandle(conn, proc)
        except (traci.TraCIException, traci.FatalTraCIError, OSError) as e:
            err = e
            if proc.poll() is None:
                proc.kill()
            proc.wait()
    raise SimulationError(f"SUMO failed to start scenario {name!r} through TraCI (a second session in this "
                          f"process; SUMO's own message, if any, is on stderr): {err}") from err
