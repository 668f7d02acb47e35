"""The outcome of a run (:func:`sim.runtime.run.run_scenario`): :class:`SimulationResult`, and the
events SUMO reported during it (:class:`RunEvents`: teleports, collisions, emergency stops,
served demand)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import pandas as pd

from scenarios.spec.model import ScenarioSpec

#: Served demand more than this share below the requested one is warned about.
DEMAND_SHORTFALL_WARN = 0.05


@dataclass(frozen=True)
class RunEvents:
    """SUMO's own reports of non-physical moves and of demand, read from its lists each step.

    Times are simulated seconds; ids are SUMO's. Teleports (``getStartingTeleportIDList``: a
    vehicle stuck ``time_to_teleport_s`` is moved ahead without driving), collisions
    (``getCollidingVehiclesIDList``, one event per vehicle and step) and emergency stops
    (``getEmergencyStoppingVehiclesIDList``) cover the whole run, warm-up included.
    ``departed`` vehicles entered the network; ``backlog`` were due by the end but still
    waiting to be inserted (``getPendingVehicles``): due = departed + backlog.
    ``requested_veh_h`` is the spec's demand (all flows, after any demand scale).
    """

    teleports: tuple[tuple[float, str], ...] = ()
    collisions: tuple[tuple[float, str], ...] = ()
    emergency_stops: tuple[tuple[float, str], ...] = ()
    departed: int = 0
    backlog: int = 0
    duration_s: float = 0.0
    requested_veh_h: float = 0.0

    @property
    def teleported_ids(self) -> frozenset[str]:
        return frozenset(s for _, s in self.teleports)

    @property
    def due_veh_h(self) -> float:
        """Vehicles due in the run (departed + backlog; random arrivals), per simulated hour."""
        return (self.departed + self.backlog) * 3600.0 / self.duration_s if self.duration_s else 0.0

    @property
    def served_veh_h(self) -> float:
        """Vehicles that entered the network, per hour of simulated time."""
        return self.departed * 3600.0 / self.duration_s if self.duration_s else 0.0

    @property
    def demand_shortfall(self) -> float:
        """Share of the vehicles due that could not enter: backlog / (departed + backlog)."""
        req = self.departed + self.backlog
        return self.backlog / req if req else 0.0

    def warnings(self) -> list[str]:
        """One line per condition a user must know about (empty when the run was clean)."""
        out = []
        if self.demand_shortfall > DEMAND_SHORTFALL_WARN:
            out.append(f"served demand {self.served_veh_h:.0f} veh/h against {self.requested_veh_h:.0f} veh/h "
                       f"requested: {self.backlog} vehicles ({self.demand_shortfall:.0%} of those due) were still "
                       "waiting to enter at the end; the network could not take the demand")
        if self.teleports:
            out.append(f"SUMO teleported {len(self.teleports)} vehicle(s) "
                       f"({', '.join(sorted(self.teleported_ids)[:5])}{', ...' if len(self.teleported_ids) > 5 else ''}): "
                       "their moves are not driving; merges by them are left out of the encounters")
        if self.collisions:
            out.append(f"SUMO reported {len(self.collisions)} collision event(s)")
        return out

    def as_dict(self) -> dict:
        """Plain values for a TOML / JSON run report."""
        return {
            "requested_veh_h": round(self.requested_veh_h, 1), "due_veh_h": round(self.due_veh_h, 1),
            "served_veh_h": round(self.served_veh_h, 1),
            "departed": self.departed, "insertion_backlog": self.backlog,
            "demand_shortfall": round(self.demand_shortfall, 4),
            "teleports": len(self.teleports), "teleported_vehicles": sorted(self.teleported_ids),
            "collisions": len(self.collisions), "colliding_vehicles": sorted({s for _, s in self.collisions}),
            "emergency_stops": len(self.emergency_stops),
        }


@dataclass(frozen=True)
class SimulationResult:
    """Outcome of :func:`~sim.runtime.run.run_scenario`.

    Attributes:
        table: trajectory table (NGSIM schema, sorted by Vehicle_ID, Frame_ID).
        spec: the spec simulated (with the seed and duration actually used).
        seed: SUMO seed.
        wall_time_s: wall-clock time of the whole run (network, SUMO, recording, table).
        sumo_time_s: wall-clock time spent inside ``simulationStep``.
        n_vehicle_steps: number of rows of the table (vehicle x recorded frame).
        sumo_ids: SUMO id of Vehicle_ID k at index k - 1.
        events: teleports, collisions, emergency stops and served demand, from SUMO's lists.
        aux_lane_start_ft: ``Local_Y`` (ft) where the auxiliary lane starts beside lane 6
            (:func:`sim.runtime.lanes.aux_lane_start_ft`; NaN if unknown): where the controller's
            take-over zone is measured from, in the run and in its encounters.
    """

    table: pd.DataFrame
    spec: ScenarioSpec
    seed: int
    wall_time_s: float
    sumo_time_s: float
    n_vehicle_steps: int
    sumo_ids: tuple[str, ...]
    events: RunEvents = RunEvents()
    aux_lane_start_ft: float = math.nan

    @property
    def n_vehicles(self) -> int:
        return len(self.sumo_ids)

    @property
    def teleported_vehicle_ids(self) -> frozenset[int]:
        """Vehicle_IDs (of this table) of the vehicles SUMO teleported."""
        vid = {s: i for i, s in enumerate(self.sumo_ids, start=1)}
        return frozenset(vid[s] for s in self.events.teleported_ids if s in vid)
