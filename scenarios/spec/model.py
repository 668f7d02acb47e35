"""The on-ramp merge scenario as frozen dataclasses (read, validated and overridden by
:mod:`scenarios.spec.parse`).

Layout of a scenario TOML file (SI units, as SUMO uses them)::

    name = "synthetic"
    site = "i-80"   (optional: the lane coding, a site profile of sim.runtime.sites by name or TOML path)
    allow_implausible = false   (optional: true runs values outside scenarios.spec.bounds)
    [road]          main_lanes, main_length_m, merge_position_m, ramp_length_m, aux_length_m,
                    lane_width_m, speed_limit_mps, ramp_speed_limit_mps, ramp_angle_deg,
                    bottleneck_length_m, bottleneck_speed_mps, bottleneck_lanes (optional, 0 = none),
                    bottleneck_drop ("right" | "left": the side whose lanes end)
    [demand]        main_veh_h (one value per main lane, leftmost first, or one value for all),
                    ramp_veh_h, truck_share, arrivals ("poisson" | "uniform"), depart_speed
    [simulation]    step_s, duration_s, warmup_s, seed
    [[drivers.car]] / [[drivers.truck]]   one table per vType of the class's distribution:
                    id, probability, car_follow_model, lane_change_model, length_m, width_m,
                    min_gap_m, max_speed_mps, accel, decel, emergency_decel, sigma, tau,
                    speed_factor, speed_dev, cf_params = {..}, lc_params = {..}

Geometry: the main road runs along +x from x = 0 (the section start) to ``main_length_m``. The
on-ramp (one lane, ``ramp_length_m`` long) joins from the right at ``merge_position_m`` and
continues as the auxiliary lane for ``aux_length_m``; ramp + auxiliary lane are I-80 lane 7.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Any

from scenarios.toml_write import dumps

VEHICLE_CLASSES = ("car", "truck")


@dataclass(frozen=True)
class RoadSpec:
    """Geometry of the merge section (metres, m/s, degrees)."""

    main_lanes: int = 3
    main_length_m: float = 600.0
    merge_position_m: float = 150.0
    ramp_length_m: float = 120.0
    aux_length_m: float = 200.0
    lane_width_m: float = 3.66
    speed_limit_mps: float = 29.0
    ramp_speed_limit_mps: float = 22.0
    ramp_angle_deg: float = 4.0
    #: A section past the study area (``main_length_m``) with fewer lanes (a lane drop) and / or
    #: a lower speed limit: the downstream bottleneck whose queue congests the section; length
    #: 0 = none, lanes 0 = as many as the main road.
    bottleneck_length_m: float = 0.0
    bottleneck_speed_mps: float = 0.0
    bottleneck_lanes: int = 0
    #: Which side's lanes end at the lane drop: ``"right"`` (the rightmost lanes, I-80 lane 6
    #: first) or ``"left"`` (the leftmost, I-80 lane 1 = the HOV lane first, so that the
    #: dropped lane's cars do not crowd the rightmost lanes the ramp merges into).
    bottleneck_drop: str = "right"


@dataclass(frozen=True)
class DemandSpec:
    """Traffic demand (veh/h). ``main_veh_h`` has one entry per main lane, leftmost first."""

    main_veh_h: tuple[float, ...] = (1200.0, 1200.0, 1000.0)
    ramp_veh_h: float = 500.0
    truck_share: float = 0.05
    arrivals: str = "poisson"
    depart_speed: str = "max"


@dataclass(frozen=True)
class VTypeSpec:
    """One SUMO vType of a class's distribution; ``probability`` is its weight in the class.

    ``cf_params`` / ``lc_params`` are extra SUMO vType attributes (name, value) for the
    car-following model (e.g. ``delta`` for IDM) and the lane-change model (``lc*``).
    """

    id: str
    probability: float = 1.0
    car_follow_model: str = "Krauss"
    lane_change_model: str = "LC2013"
    length_m: float = 4.5
    width_m: float = 1.8
    min_gap_m: float = 2.0
    max_speed_mps: float = 40.0
    accel: float = 2.6
    decel: float = 4.5
    emergency_decel: float = 9.0
    sigma: float = 0.5
    tau: float = 1.0
    speed_factor: float = 1.0
    speed_dev: float = 0.1
    cf_params: tuple[tuple[str, float | int | str | bool], ...] = ()
    lc_params: tuple[tuple[str, float | int | str | bool], ...] = ()


@dataclass(frozen=True)
class DriversSpec:
    """The driver population: a distribution of vTypes per vehicle class."""

    car: tuple[VTypeSpec, ...] = (VTypeSpec(id="car"),)
    truck: tuple[VTypeSpec, ...] = (
        VTypeSpec(id="truck", length_m=12.0, width_m=2.5, max_speed_mps=30.0, accel=1.3,
                  decel=4.0, emergency_decel=7.0, min_gap_m=2.5),
    )


@dataclass(frozen=True)
class SimulationSpec:
    """Time settings. Frames (0.1 s) of the first ``warmup_s`` seconds are not recorded.

    ``time_to_teleport_s`` is SUMO's ``--time-to-teleport``: a vehicle that has stood blocked
    at the front of its lane this long is teleported ahead (0 disables jam teleports).
    """

    step_s: float = 0.1
    duration_s: float = 300.0
    warmup_s: float = 60.0
    seed: int = 42
    time_to_teleport_s: float = 300.0


@dataclass(frozen=True)
class ScenarioSpec:
    """A complete on-ramp merge scenario."""

    name: str
    road: RoadSpec = RoadSpec()
    demand: DemandSpec = DemandSpec()
    drivers: DriversSpec = DriversSpec()
    simulation: SimulationSpec = SimulationSpec()
    #: The lane coding of the run's trajectory table and of the controller: a site profile of
    #: :mod:`sim.runtime.sites` by name (``"i-80"``: main lanes ``7 - n .. 6``, ramp and auxiliary lane 7)
    #: or a TOML path; written to TOML only when it is not the default.
    site: str = "i-80"
    source: str = field(default="", compare=False)  #: file read from; not saved, not compared
    #: Values outside the plausibility bounds (:mod:`scenarios.spec.bounds`) are meant: saved
    #: (when true), not compared (the simulation is the same).
    allow_implausible: bool = field(default=False, compare=False)

    def to_dict(self) -> dict[str, Any]:
        """Plain TOML-ready mapping (tuples become lists, param tuples become tables)."""
        return _to_plain(self)

    def to_toml(self) -> str:
        """The spec as TOML text; ``load_scenario`` of that text gives an equal spec."""
        return dumps(self.to_dict())


# ----------------------------------------------------------------------------- conversion


def _to_plain(obj: Any) -> Any:
    if isinstance(obj, ScenarioSpec):
        out: dict[str, Any] = {"name": obj.name}
        if obj.site != "i-80":  # every spec written before the field keeps its text (and hash)
            out["site"] = obj.site
        if obj.allow_implausible:
            out["allow_implausible"] = True
        for part in ("road", "demand", "simulation"):
            out[part] = _to_plain(getattr(obj, part))
        out["drivers"] = {c: [_to_plain(v) for v in getattr(obj.drivers, c)] for c in VEHICLE_CLASSES}
        return out
    if isinstance(obj, VTypeSpec):
        out = {}
        for f in fields(obj):
            val = getattr(obj, f.name)
            if f.name in ("cf_params", "lc_params"):
                val = dict(val)
            out[f.name] = val
        return out
    if hasattr(obj, "__dataclass_fields__"):
        return {f.name: (list(v) if isinstance(v := getattr(obj, f.name), tuple) else v) for f in fields(obj)}
    return obj
