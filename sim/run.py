"""Run a scenario headless through libsumo and record the NGSIM-schema trajectory table.

Recording: at each recorded frame (every 0.1 s of simulated time after the warm-up) the
runner reads every vehicle's position, speed and acceleration with direct libsumo calls
(measured cheaper than per-vehicle subscriptions, which SUMO updates at every step, and
nothing to unsubscribe when a hook removes a vehicle); each frame becomes one read-only
``[V, 4]`` array (plus id, lane and static arrays, rebuilt only when the set of vehicles
changes), which the step hooks see as :class:`sim.hooks.FrameState` column views and the
recorder keeps by reference; the DataFrame is built once at the end, with
Preceding/Following/headways computed vectorised (``sim.table``).

Coordinates: ``Local_Y`` = SUMO x (distance along the main road from the section start),
``Local_X`` = -SUMO y (lateral distance from the left road edge), ``Global_X/Global_Y`` = SUMO
x/y; all in feet, of the front bumper centre. Lanes: SUMO lane -> I-80 number by the lane's
lateral position (main lanes 7 - n .. 6 from left to right, ramp and auxiliary lane 7).
Vehicle_ID: consecutive from 1 in insertion order, assigned when a vehicle first appears in
a recorded frame. Frame_ID = simulated time / 0.1 s; Global_Time = Frame_ID * 100 (ms since
the simulation started). Frames before ``warmup_s`` are not recorded and not passed to hooks.

libsumo allows one simulation per process at a time; ``run_scenario`` always closes it
(``try/finally``, also on Ctrl-C), so runs can follow each other in one process.
"""

from __future__ import annotations

import math
import sys
import tempfile
import time
from collections.abc import Sequence
from itertools import chain
from pathlib import Path

import numpy as np

from scenarios.routes import type_class_map
from scenarios.spec.model import ScenarioSpec
from scenarios.spec.parse import with_overrides
from sim.errors import SimulationError
from sim.hooks import FrameState, RunContext, StepHook
from sim.lanes import LaneNumbering, aux_lane_start_ft, lane_tables
from sim.recorder import TrajectoryRecorder
from sim.run_result import RunEvents, SimulationResult
from sim.schema import FRAME_S, FT_PER_M, RIGHTMOST_MAIN_LANE, V_CLASS_AUTO, V_CLASS_TRUCK
from sim.sumo_inputs import prepare_inputs, sumo_args


def run_scenario(
    spec: ScenarioSpec,
    *,
    seed: int | None = None,
    duration_s: float | None = None,
    hooks: Sequence[StepHook] = (),
    progress: bool = False,
    work_dir: Path | None = None,
) -> SimulationResult:
    """Simulate ``spec`` and record every vehicle at every 0.1 s frame after the warm-up.

    ``seed`` / ``duration_s`` override the spec's. ``hooks`` are called at every recorded
    frame (see :mod:`sim.hooks`). ``progress`` shows a tqdm bar of simulated time on stderr.

    Raises:
        SimulationError: SUMO fails to start or to step.
    """
    if seed is not None or duration_s is not None:
        spec = with_overrides(spec, seed=seed, duration_s=duration_s)
    sim = spec.simulation
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="merge-irl-run-") as tmp:
        wd = Path(work_dir) if work_dir is not None else Path(tmp)
        wd.mkdir(parents=True, exist_ok=True)
        net, routes = prepare_inputs(spec, wd)
        table, sumo_time, sumo_ids, events, aux_start = _simulate(spec, net, routes, hooks, progress, str(wd))
    return SimulationResult(
        table=table, spec=spec, seed=sim.seed, wall_time_s=time.perf_counter() - t0,
        sumo_time_s=sumo_time, n_vehicle_steps=len(table), sumo_ids=sumo_ids, events=events,
        aux_lane_start_ft=aux_start,
    )


def _simulate(spec, net, routes, hooks, progress, work_dir):
    import libsumo as ls

    sim = spec.simulation
    record_every = int(round(FRAME_S / sim.step_s))
    n_steps = int(round(sim.duration_s / sim.step_s))
    warmup_frame = int(math.ceil(sim.warmup_s / FRAME_S - 1e-9))
    cls_of_type = type_class_map(spec)
    # lane numbers come from the lateral position (SUMO without sublanes keeps every vehicle on
    # its lane's centre line), which saves a fourth call per vehicle
    veh = ls.vehicle
    get_pos, get_speed, get_acc = veh.getPosition, veh.getSpeed, veh.getAcceleration
    lane_of = LaneNumbering(spec.road.main_lanes, spec.road.lane_width_m * FT_PER_M)

    try:
        ls.start(["sumo", *sumo_args(spec, net, routes)])
    except Exception as e:  # libsumo raises its own TraCIException / FatalTraCIError
        _safe_close(ls)
        raise SimulationError(f"SUMO failed to start scenario {spec.name!r}: {e}") from e

    recorder = TrajectoryRecorder()
    vid_of: dict[str, int] = {}
    sumo_ids: list[str] = []
    depart_seq: dict[str, int] = {}
    static: dict[str, tuple[float, float, int]] = {}  # sid -> (length ft, width ft, v_class)
    sumo_time = 0.0
    ctx: RunContext | None = None
    bar = None
    started_hooks: list[StepHook] = []
    teleports: list[tuple[float, str]] = []
    collisions: list[tuple[float, str]] = []
    emergency: list[tuple[float, str]] = []
    departed = backlog = 0
    ok = False  # set once every step ran: hooks then commit their outputs
    simulation = ls.simulation
    try:
        _, lane_shapes = lane_tables(ls, spec)
        ctx = RunContext(
            spec=spec, seed=sim.seed, step_length_s=sim.step_s, frame_s=FRAME_S,
            lane_shapes=lane_shapes, lane_width_ft=spec.road.lane_width_m * FT_PER_M,
            main_lanes=tuple(range(RIGHTMOST_MAIN_LANE - spec.road.main_lanes + 1, RIGHTMOST_MAIN_LANE + 1)),
            section_length_ft=spec.road.main_length_m * FT_PER_M,
            vehicle_id_of=vid_of.get,
            sumo_id_of=lambda v: sumo_ids[v - 1] if 1 <= v <= len(sumo_ids) else None,
            work_dir=work_dir,
        )
        for h in hooks:
            h.on_start(ctx)
            started_hooks.append(h)
        if progress:
            from tqdm import tqdm

            bar = tqdm(total=round(sim.duration_s), unit="sim s", file=sys.stderr,
                       disable=not sys.stderr.isatty(), desc=f"simulating {spec.name}")
        shown = 0
        prev_sids: tuple[str, ...] | None = None
        type_static: dict[str, tuple[float, float, int]] = {}
        for step in range(1, n_steps + 1):
            ts = time.perf_counter()
            ls.simulationStep()
            sumo_time += time.perf_counter() - ts
            now = step * sim.step_s
            for lst, get in ((teleports, simulation.getStartingTeleportIDList),
                             (collisions, simulation.getCollidingVehiclesIDList),
                             (emergency, simulation.getEmergencyStoppingVehiclesIDList)):
                ids = get()
                if ids:
                    lst.extend((now, s) for s in ids)
            for sid in ls.simulation.getDepartedIDList():
                depart_seq[sid] = len(depart_seq)
                tid = ls.vehicle.getTypeID(sid)
                if tid not in type_static:
                    cls = cls_of_type.get(tid, "car")
                    type_static[tid] = (ls.vehicletype.getLength(tid) * FT_PER_M,
                                        ls.vehicletype.getWidth(tid) * FT_PER_M,
                                        V_CLASS_TRUCK if cls == "truck" else V_CLASS_AUTO)
                static[sid] = type_static[tid]
            if bar is not None and int(step * sim.step_s) > shown:
                bar.update(int(step * sim.step_s) - shown)
                shown = int(step * sim.step_s)
            if step % record_every:
                continue
            frame = step // record_every
            if frame < warmup_frame:
                continue
            sids = veh.getIDList()
            if sids != prev_sids:  # who is in the network changed: new id and static arrays
                new = [s for s in sids if s not in vid_of]
                if new:
                    new.sort(key=depart_seq.__getitem__)
                    for s in new:
                        sumo_ids.append(s)
                        vid_of[s] = len(sumo_ids)
                vid = _frozen(np.array([vid_of[s] for s in sids], dtype=np.int64))
                st = _frozen(np.array([static[s] for s in sids], dtype=np.float64).reshape(-1, 3))
                v_class = _frozen(st[:, 2].astype(np.int64))
                prev_sids = sids
            # one array per frame: x, y (m), speed (m/s), acceleration (m/s^2) -> ft units
            kin = np.fromiter(chain.from_iterable((*get_pos(s), get_speed(s), get_acc(s)) for s in sids),
                              dtype=np.float64, count=4 * len(sids)).reshape(-1, 4)
            kin *= FT_PER_M
            local_x = _frozen(-kin[:, 1])
            lane = _frozen(lane_of(local_x))
            _frozen(kin)
            recorder.add(frame, vid, kin, lane, st)
            fs = FrameState(
                frame=frame, time_s=step * sim.step_s, sumo_ids=sids, vehicle_id=vid,
                local_x=local_x, local_y=kin[:, 0], global_x=kin[:, 0], global_y=kin[:, 1],
                speed=kin[:, 2], acc=kin[:, 3], length=st[:, 0], width=st[:, 1],
                lane_id=lane, v_class=v_class,
            )
            for h in hooks:
                h.on_step(ctx, fs)
        departed = len(depart_seq)
        backlog = len(simulation.getPendingVehicles())
        ok = True
    except (KeyboardInterrupt, SimulationError):
        raise
    except (ls.TraCIException, ls.FatalTraCIError) as e:
        raise SimulationError(f"SUMO error in scenario {spec.name!r}: {e}") from e
    finally:
        try:
            if ctx is not None:
                for h in started_hooks:
                    # an aborted run (error, Ctrl-C) must not publish outputs: on_abort if defined
                    (getattr(h, "on_abort", h.on_end) if not ok else h.on_end)(ctx)
        finally:
            if bar is not None:
                bar.close()
            _safe_close(ls)
    events = RunEvents(tuple(teleports), tuple(collisions), tuple(emergency), departed, backlog, sim.duration_s,
                       float(sum(spec.demand.main_veh_h) + spec.demand.ramp_veh_h))
    aux_start = aux_lane_start_ft(ctx) if ctx is not None else math.nan
    return recorder.table(), sumo_time, tuple(sumo_ids), events, aux_start


def _frozen(a: np.ndarray) -> np.ndarray:
    a.flags.writeable = False
    return a


def _safe_close(ls) -> None:
    try:
        ls.close()
    except Exception:
        pass
