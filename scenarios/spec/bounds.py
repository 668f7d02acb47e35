"""Plausibility bounds of a scenario's fields: the ranges outside which a value is almost surely a
typo or a unit mix-up (65 mph typed as m/s, a demand of 1e12 veh/h, a 1e9 s run), refused with
the field named by :mod:`scenarios.spec.parse` unless the scenario says it means it
(``allow_implausible = true`` at the top of the file, or ``--allow-implausible`` on the command
line).

The hard limits (a number, finite, positive, a consistent geometry) are not bounds of this kind
and hold always (:mod:`scenarios.spec.fields`).
"""

from __future__ import annotations

from dataclasses import dataclass

from scenarios.spec.fields import FieldContext

#: How a scenario says that it means its implausible values (a top-level TOML key).
ALLOW_KEY = "allow_implausible"


@dataclass(frozen=True)
class Bound:
    """``low <= value <= high`` (inclusive), in ``unit``; ``why``: what the range rests on."""

    low: float
    high: float
    unit: str
    why: str


_ROAD_LENGTH = "a road section holds a few cars (5 m each) and is at most 20 km long"
_DEMAND = ("about 4x a lane's capacity of about 2,400 veh/h, enough to oversaturate on purpose; "
           "more only queues at the entry")
_SPEED = "45 m/s = 162 km/h, above every posted freeway limit"

#: The bounds, by field path (``section.field``; ``demand.main_veh_h`` applies to each lane's value).
BOUNDS: dict[str, Bound] = {
    "road.main_length_m": Bound(50.0, 20_000.0, "m", _ROAD_LENGTH),
    "road.merge_position_m": Bound(10.0, 20_000.0, "m", _ROAD_LENGTH),
    "road.ramp_length_m": Bound(20.0, 5_000.0, "m", _ROAD_LENGTH),
    "road.aux_length_m": Bound(10.0, 5_000.0, "m", _ROAD_LENGTH),
    "road.lane_width_m": Bound(2.5, 5.0, "m", "lanes are 2.5-5 m wide in practice"),
    "road.speed_limit_mps": Bound(1.0, 45.0, "m/s", _SPEED),
    "road.ramp_speed_limit_mps": Bound(1.0, 45.0, "m/s", _SPEED),
    "road.bottleneck_length_m": Bound(0.0, 20_000.0, "m", _ROAD_LENGTH),
    "road.bottleneck_speed_mps": Bound(0.0, 45.0, "m/s", _SPEED),
    "demand.main_veh_h": Bound(0.0, 10_000.0, "veh/h", _DEMAND + " (each main lane)"),
    "demand.ramp_veh_h": Bound(0.0, 10_000.0, "veh/h", _DEMAND),
    "simulation.duration_s": Bound(0.0, 21_600.0, "s",
                                   "6 hours of traffic; the NGSIM I-80 recordings span 45 minutes"),
}


def check_bound(ctx: FieldContext, path: str, value: float, *, allow: bool, key: str | None = None,
                given_as: str = "") -> None:
    """Refuse ``value`` of the field at ``path`` outside its :data:`BOUNDS` entry, unless ``allow``.

    Args:
        ctx: names the file in the message.
        path: where the value is (e.g. ``demand.main_veh_h[2]``); ``key``: its :data:`BOUNDS`
            key when it differs (``demand.main_veh_h``).
        given_as: how the user gave it when not in the file (e.g. ``"--duration"``), named first.

    Raises:
        SpecError: one line, ``file: field: value unit is implausible (...); expected low to high unit
            (why); to run it anyway ...``.
    """
    problem = bound_problem(key or path, value, allow=allow, given_as=given_as)
    if problem:
        raise ctx.fail(path, problem)


def bound_problem(key: str, value: float, *, allow: bool = False, given_as: str = "") -> str:
    """What is implausible about ``value`` of the :data:`BOUNDS` entry ``key`` (``""``: nothing,
    or ``allow``); the message of :func:`check_bound` without the file and field."""
    b = BOUNDS[key]
    if allow or b.low <= value <= b.high:
        return ""
    hint = ""
    if b.unit == "m/s" and value > b.high:
        hint = f" ({value * 3.6:.0f} km/h; {value:g} mph would be {value * 0.44704:.1f} m/s)"
    what = f"{given_as} {value:g} {b.unit}" if given_as else f"{value:g} {b.unit}"
    return (f"{what} is implausible{hint}; expected {b.low:g} to {b.high:g} {b.unit} ({b.why}); "
            f"if you mean it, set {ALLOW_KEY} = true at the top of the scenario file or pass --allow-implausible")


def allow_flag(ctx: FieldContext, data: dict) -> bool:
    """The scenario's ``allow_implausible`` key (default False).

    Raises:
        SpecError: it is not a boolean.
    """
    v = data.get(ALLOW_KEY, False)
    if not isinstance(v, bool):
        raise ctx.fail(ALLOW_KEY, f"must be true or false, got {v!r}")
    return v

