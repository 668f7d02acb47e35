"""Step hooks: user code called by :func:`sim.runtime.run.run_scenario` at every recorded frame.

A hook sees the frame just recorded (NGSIM units: ft, ft/s, ft/s^2) and may call SUMO through
the run's handle ``ctx.sumo`` to control vehicles (for example ``ctx.sumo.vehicle.setSpeedMode(sid, 0)``
then ``setAcceleration``); the commands take effect in the next simulation step. The handle is
the ``libsumo`` module for the process's first open run and a TraCI connection with the same
calls for a run started while another is open (:mod:`sim.runtime.session`): a hook that imports
``libsumo`` itself drives the wrong simulation in the second case.

Call order for one run::

    hook.on_start(ctx)                 # once, after SUMO started and the network is loaded
    hook.on_step(ctx, frame)           # once per recorded frame (after warm-up), in order
    hook.on_end(ctx)                   # once, before the SUMO session is closed, when the run succeeded
    hook.on_abort(ctx)                 # instead of on_end when the run ends with an error or Ctrl-C
                                       # (optional; hooks without it get on_end also then)

A hook that writes files commits them (renames them to their final names) only in ``on_end``,
so an aborted run never leaves a complete-looking output.

Hooks are called in the order given. Frames of the warm-up period are neither recorded nor
passed to hooks.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, Protocol, runtime_checkable

import numpy as np

from sim.runtime.sites import I80, SiteProfile


@dataclass(frozen=True)
class RunContext:
    """What a run knows that does not change from frame to frame.

    Attributes:
        spec: the :class:`scenarios.spec.model.ScenarioSpec` being simulated.
        seed: the SUMO random seed of this run.
        step_length_s: SUMO's simulation step (s).
        frame_s: time between two recorded frames (s), 0.1 (the NGSIM frame).
        lane_shapes: I-80 lane number as str ("1".."7") -> float64[P, 2] polyline of the lane
            centre, (Global_X, Global_Y) in ft. Lane "7" is the ramp followed by the
            auxiliary lane.
        lane_width_ft: width of one lane (ft).
        main_lanes: I-80 numbers of the main-road lanes, leftmost first (e.g. (1, ..., 6)).
        section_length_ft: length of the main road (ft); Local_Y runs over [0, this].
        vehicle_id_of: callable, SUMO id -> Vehicle_ID (int), or None if not yet assigned.
        sumo_id_of: callable, Vehicle_ID -> SUMO id, or None if unknown.
        work_dir: folder with the network and route files of this run (str).
        site: the lane coding of the run (:class:`sim.runtime.sites.SiteProfile`, from
            :func:`sim.runtime.sites.site_of`; I-80's by default): ``lane_id`` codes, the merge lane
            (I-80: 6) and the ramp lane (I-80: 7).
        sumo: the run's SUMO handle (libsumo's calls: ``sumo.vehicle``, ``sumo.simulation``, ...,
            and ``sumo.TraCIException``): the ``libsumo`` module or a
            :class:`sim.runtime.session.TraciHandle` (module docstring).
    """

    spec: Any
    seed: int
    step_length_s: float
    frame_s: float
    lane_shapes: Mapping[str, np.ndarray]
    lane_width_ft: float
    main_lanes: tuple[int, ...]
    section_length_ft: float
    vehicle_id_of: Callable[[str], int | None] = field(repr=False)
    sumo_id_of: Callable[[int], str | None] = field(repr=False)
    work_dir: str = ""
    site: SiteProfile = I80
    sumo: Any = field(default=None, repr=False, compare=False)


@dataclass(frozen=True)
class FrameState:
    """Every vehicle in the network at one recorded frame; V = number of vehicles.

    Arrays are aligned: entry i of every array is vehicle ``sumo_ids[i]``. Units: ft, ft/s,
    ft/s^2. ``lane_id`` uses I-80 numbering (1 leftmost .. 6 rightmost main lane, 7 ramp /
    auxiliary lane). ``v_class`` is NGSIM's (2 auto, 3 truck). The arrays are read-only and
    never written again after the frame (frames that see the same vehicles may share the id
    and static arrays), so a hook may keep references instead of copies; positions, speed and
    acceleration are column views of one ``[V, 4]`` array (``local_y`` and ``global_x`` are
    the same values).

    Attributes:
        frame: Frame_ID (int, 0.1 s units since the start of the simulation).
        time_s: simulated time (s).
        sumo_ids: tuple[str] of length V.
        vehicle_id: int64[V]  Vehicle_ID of the trajectory table.
        local_x, local_y, global_x, global_y: float64[V]  positions of the front bumper centre.
        speed: float64[V]; acc: float64[V]; length, width: float64[V].
        lane_id: int64[V]; v_class: int64[V].
    """

    frame: int
    time_s: float
    sumo_ids: tuple[str, ...]
    vehicle_id: np.ndarray
    local_x: np.ndarray
    local_y: np.ndarray
    global_x: np.ndarray
    global_y: np.ndarray
    speed: np.ndarray
    acc: np.ndarray
    length: np.ndarray
    width: np.ndarray
    lane_id: np.ndarray
    v_class: np.ndarray

    def lane_order(self, lane: int) -> tuple[list[float], list[int]]:
        """Vehicles of ``lane`` sorted by ``Local_Y`` (ascending; equal positions by row).

        Returns ``(local_y, rows)`` as two Python lists of the same length, ready for
        ``bisect``. Computed once per lane and frame, then cached on the frame.
        """
        hit = self._lane_orders.get(lane)
        if hit is None:
            rows = np.flatnonzero(self.lane_id == lane)
            rows = rows[np.argsort(self.local_y[rows], kind="stable")]
            hit = self._lane_orders[lane] = (self.local_y[rows].tolist(), rows.tolist())
        return hit

    @cached_property
    def _lane_orders(self) -> dict[int, tuple[list[float], list[int]]]:
        return {}



@runtime_checkable
class StepHook(Protocol):
    """Called by :func:`sim.runtime.run.run_scenario`; see the module docstring for the call order."""

    def on_start(self, ctx: RunContext) -> None: ...

    def on_step(self, ctx: RunContext, frame: FrameState) -> None: ...

    def on_end(self, ctx: RunContext) -> None: ...
