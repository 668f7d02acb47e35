"""Parsing and validating scenario specs: TOML text or a plain mapping -> :class:`ScenarioSpec`.

Every problem raises :class:`scenarios.errors.SpecError` of the form ``file: field.path: problem``
before anything is simulated. The file layout is described in :mod:`scenarios.spec.model`.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import fields, replace
from pathlib import Path
from typing import Any, TypeVar

from pydantic import BaseModel

from merge_irl.json_file import validate
from scenarios.errors import SpecError
from scenarios.spec.bounds import ALLOW_KEY, allow_flag, check_bound
from scenarios.spec.fields import (
    FieldContext,
    check_keys,
    non_negative,
    number,
    positive,
    string,
)
from scenarios.spec.model import (
    VEHICLE_CLASSES,
    DemandSpec,
    DriversSpec,
    RoadSpec,
    ScenarioSpec,
    SimulationSpec,
    VTypeSpec,
)
from scenarios.spec.schema import (
    PARAM_NAME,
    DemandSchema,
    RoadSchema,
    VTypeSchema,
    given,
)

M = TypeVar("M", bound=BaseModel)

def _road(ctx: FieldContext, data: Any, allow: bool) -> RoadSpec:
    d = check_keys(ctx, "road", data, [f.name for f in fields(RoadSpec)])
    r = RoadSpec(**given(_schema(ctx, RoadSchema, d, "road", allow)))
    _check_geometry(ctx, r)
    _check_bottleneck(ctx, r, d)
    return r


def _schema(ctx: FieldContext, schema: type[M], data: dict[str, Any], at: str, allow: bool = False) -> M:
    return validate(schema, data, ctx.source, error=SpecError, at=at, context={"allow": allow})


def _check_geometry(ctx: FieldContext, r: RoadSpec) -> None:
    if r.merge_position_m + r.aux_length_m >= r.main_length_m:
        raise ctx.fail(
            "road.aux_length_m",
            f"merge_position_m + aux_length_m = {r.merge_position_m + r.aux_length_m:g} m must be "
            f"shorter than main_length_m = {r.main_length_m:g} m (the auxiliary lane ends on the road)",
        )
    ramp_dx = r.ramp_length_m * math.cos(math.radians(r.ramp_angle_deg))
    if ramp_dx > r.merge_position_m:
        raise ctx.fail(
            "road.ramp_length_m",
            f"the ramp ({r.ramp_length_m:g} m at {r.ramp_angle_deg:g} deg) would start before the section "
            f"start: its length along the road, {ramp_dx:.1f} m, must be at most merge_position_m = "
            f"{r.merge_position_m:g} m",
        )


def _check_bottleneck(ctx: FieldContext, r: RoadSpec, d: dict[str, Any]) -> None:
    if r.bottleneck_length_m > 0 and "bottleneck_speed_mps" not in d:  # its default 0 means "no bottleneck"
        raise ctx.fail("road.bottleneck_speed_mps",
                       f"missing: a bottleneck of {r.bottleneck_length_m:g} m needs its speed limit (for a lane "
                       f"drop alone, the road's speed_limit_mps = {r.speed_limit_mps:g})")
    if r.bottleneck_length_m > 0 and not r.bottleneck_speed_mps >= 1.0:
        raise ctx.fail("road.bottleneck_speed_mps",
                       f"a bottleneck of {r.bottleneck_length_m:g} m needs a speed limit of at least 1 m/s, "
                       f"got {r.bottleneck_speed_mps:g}")
    if not r.bottleneck_length_m > 0:
        no_bottleneck = RoadSpec()
        given_ = sorted(k for k in d if k.startswith("bottleneck_") and k != "bottleneck_length_m"
                        and getattr(r, k) != getattr(no_bottleneck, k))  # a written spec repeats the defaults
        if given_:
            raise ctx.fail("road.bottleneck_length_m",
                           f"{', '.join(given_)} given but no bottleneck: set bottleneck_length_m > 0 "
                           f"(the bottleneck's length past main_length_m) or remove them")
    elif (r.bottleneck_lanes in (0, r.main_lanes) and r.bottleneck_speed_mps >= r.speed_limit_mps):
        raise ctx.fail("road.bottleneck_speed_mps",
                       f"the bottleneck changes nothing: no lane drop (bottleneck_lanes {r.bottleneck_lanes or r.main_lanes}"
                       f" of {r.main_lanes}) and a speed limit of {r.bottleneck_speed_mps:g} m/s, not below the road's "
                       f"{r.speed_limit_mps:g} m/s")
    if r.bottleneck_lanes > r.main_lanes:
        raise ctx.fail("road.bottleneck_lanes", f"{r.bottleneck_lanes} lanes: a bottleneck has at most main_lanes = "
                                                f"{r.main_lanes}")


def _main_veh_h(ctx: FieldContext, d: dict[str, Any], main_lanes: int, allow: bool) -> tuple[float, ...]:
    """``demand.main_veh_h``: one value for every main lane, or one per lane (checked, bounded)."""
    if "main_veh_h" not in d:
        base = DemandSpec().main_veh_h
        return tuple(base[min(i, len(base) - 1)] for i in range(main_lanes))
    v = d["main_veh_h"]
    if not isinstance(v, list):
        x = non_negative(ctx, "demand.main_veh_h", v)
        check_bound(ctx, "demand.main_veh_h", x, allow=allow)
        return (x,) * main_lanes
    if len(v) != main_lanes:
        raise ctx.fail("demand.main_veh_h", f"must have one value per main lane ({main_lanes}), got {len(v)}")
    out = tuple(non_negative(ctx, f"demand.main_veh_h[{i}]", x) for i, x in enumerate(v))
    for i, x in enumerate(out):
        check_bound(ctx, f"demand.main_veh_h[{i}]", x, allow=allow, key="demand.main_veh_h")
    return out


def _demand(ctx: FieldContext, data: Any, main_lanes: int, allow: bool) -> DemandSpec:
    d = check_keys(ctx, "demand", data, [f.name for f in fields(DemandSpec)])
    main = _main_veh_h(ctx, d, main_lanes, allow)
    dem = DemandSpec(**{**given(_schema(ctx, DemandSchema, d, "demand", allow)), "main_veh_h": main})
    if sum(dem.main_veh_h) + dem.ramp_veh_h <= 0:
        raise ctx.fail("demand", "zero demand everywhere: main_veh_h and ramp_veh_h are all 0")
    return dem


def _vtype(ctx: FieldContext, path: str, data: Any, cls: str) -> VTypeSpec:
    d = check_keys(ctx, path, data, [f.name for f in fields(VTypeSpec)])
    kw = given(_schema(ctx, VTypeSchema, d, path))
    for name in ("cf_params", "lc_params"):
        if name in kw:
            kw[name] = tuple(sorted(kw[name].items()))
    defaults = DriversSpec().truck[0] if cls == "truck" else VTypeSpec(id="car")
    return replace(defaults, **kw)


def _drivers(ctx: FieldContext, data: Any) -> DriversSpec:
    d = check_keys(ctx, "drivers", data, list(VEHICLE_CLASSES))
    kw: dict[str, Any] = {}
    seen: set[str] = set()
    for cls in VEHICLE_CLASSES:
        if cls not in d:
            kw[cls] = getattr(DriversSpec(), cls)
        else:
            items = d[cls]
            if isinstance(items, dict):
                items = [items]
            if not isinstance(items, list) or not items:
                raise ctx.fail(f"drivers.{cls}", f"must be a non-empty array of vType tables ([[drivers.{cls}]])")
            kw[cls] = tuple(_vtype(ctx, f"drivers.{cls}[{i}]", it, cls) for i, it in enumerate(items))
        for i, vt in enumerate(kw[cls]):
            if vt.id in seen:
                raise ctx.fail(f"drivers.{cls}[{i}].id", f"duplicate vType id {vt.id!r}")
            seen.add(vt.id)
    return DriversSpec(**kw)


def _simulation(ctx: FieldContext, data: Any, allow: bool) -> SimulationSpec:
    names = [f.name for f in fields(SimulationSpec)]
    d = check_keys(ctx, "simulation", data, names)
    kw: dict[str, Any] = {}
    if "step_s" in d:
        kw["step_s"] = positive(ctx, "simulation.step_s", d["step_s"])
        ratio = 0.1 / kw["step_s"]
        if not ratio <= 1000 or abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
            raise ctx.fail("simulation.step_s", f"must divide the 0.1 s NGSIM frame (0.1, 0.05, 0.02, ...), got {d['step_s']!r}")
    if "duration_s" in d:
        kw["duration_s"] = positive(ctx, "simulation.duration_s", d["duration_s"])
        check_bound(ctx, "simulation.duration_s", kw["duration_s"], allow=allow)
    if "warmup_s" in d:
        kw["warmup_s"] = non_negative(ctx, "simulation.warmup_s", d["warmup_s"])
    if "seed" in d:
        kw["seed"] = number(ctx, "simulation.seed", d["seed"], integer=True)
        if not 0 <= kw["seed"] < 2**31:
            raise ctx.fail("simulation.seed", f"must be in [0, 2**31), got {d['seed']!r}")
    if "time_to_teleport_s" in d:
        kw["time_to_teleport_s"] = non_negative(ctx, "simulation.time_to_teleport_s", d["time_to_teleport_s"])
    sim = SimulationSpec(**kw)
    if sim.warmup_s >= sim.duration_s:
        raise ctx.fail("simulation.warmup_s", f"must be shorter than duration_s = {sim.duration_s:g} s, got {sim.warmup_s:g}")
    return sim


def spec_from_dict(data: dict[str, Any], *, source: str = "<dict>", allow_implausible: bool = False) -> ScenarioSpec:
    """Validate a parsed TOML mapping and build the spec; raises ``SpecError`` naming the field.

    Args:
        data: the mapping (the TOML file's layout, :mod:`scenarios.spec.model`).
        source: how messages name it (the file).
        allow_implausible: accept values outside :data:`scenarios.spec.bounds.BOUNDS` (as the
            mapping's own ``allow_implausible = true`` does); the spec keeps it.

    Raises:
        SpecError: a missing or invalid field, or an implausible one (the message names it and
            what was expected).
    """
    ctx = FieldContext(source)
    d = check_keys(ctx, "", data, ["name", "site", ALLOW_KEY, "road", "demand", "drivers", "simulation"])
    allow = allow_flag(ctx, d) or bool(allow_implausible)
    if "name" not in d:
        raise ctx.fail("name", "missing (the scenario needs a name)")
    name = string(ctx, "name", d["name"])
    if not PARAM_NAME.match(name.replace("-", "_")):
        raise ctx.fail("name", f"must be letters, digits, - and _, got {name!r}")
    road = _road(ctx, d.get("road", {}), allow)
    return ScenarioSpec(
        name=name,
        road=road,
        demand=_demand(ctx, d.get("demand", {}), road.main_lanes, allow),
        drivers=_drivers(ctx, d.get("drivers", {})),
        simulation=_simulation(ctx, d.get("simulation", {}), allow),
        site=string(ctx, "site", d.get("site", "i-80")).strip() or "i-80",
        source=source,
        allow_implausible=allow,
    )


def spec_from_toml(text: str, *, source: str = "<toml>", allow_implausible: bool = False) -> ScenarioSpec:
    """Parse TOML text and validate it (``allow_implausible``: as :func:`spec_from_dict`'s).

    Raises:
        SpecError: invalid TOML, or a missing or invalid field (see :func:`spec_from_dict`).
    """
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise SpecError(f"{source}: invalid TOML: {e}") from e
    return spec_from_dict(data, source=source, allow_implausible=allow_implausible)


def spec_from_file(path: str | Path, *, allow_implausible: bool = False) -> ScenarioSpec:
    """The scenario in the UTF-8 TOML file ``path`` (``allow_implausible``: as :func:`spec_from_dict`'s).

    Raises:
        SpecError: the file cannot be read, is not UTF-8 text, or does not hold a valid scenario (see
            :func:`spec_from_toml`).
    """
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as e:
        raise SpecError(f"{p}: cannot read scenario file: {e.strerror}") from e
    except UnicodeDecodeError as e:
        raise SpecError(f"{p}: not a UTF-8 text file (byte {e.start}); expected scenario TOML") from None
    return spec_from_toml(text, source=p.name, allow_implausible=allow_implausible)


def with_overrides(
    spec: ScenarioSpec, *, seed: int | None = None, duration_s: float | None = None,
    demand_scale: float | None = None, allow_implausible: bool | None = None,
) -> ScenarioSpec:
    """A copy of ``spec`` with another seed, duration and/or demand, validated again (the
    plausibility bounds included, :mod:`scenarios.spec.bounds`).

    Args:
        spec: the scenario.
        seed: SUMO's random seed.
        duration_s: simulated seconds, warm-up included.
        demand_scale: multiplies every demand flow (each ``main_veh_h`` entry and
            ``ramp_veh_h``); a positive finite number.
        allow_implausible: set (True) or clear (False) the spec's ``allow_implausible``
            (None: keep it).

    Raises:
        SpecError: if an override is invalid or implausible (naming the field).
    """
    source = spec.source or "<overrides>"
    data = spec.to_dict()
    allow = spec.allow_implausible if allow_implausible is None else bool(allow_implausible)
    data.pop(ALLOW_KEY, None)
    if allow:
        data[ALLOW_KEY] = True
    if seed is not None:
        data["simulation"]["seed"] = seed
    if duration_s is not None:
        warmup = spec.simulation.warmup_s
        if isinstance(duration_s, (int, float)) and not isinstance(duration_s, bool) and 0 < duration_s <= warmup:
            # name the override, not the scenario file's warmup_s, which is fine as it is
            raise SpecError(f"{source}: simulation.duration_s: overridden (e.g. --duration) with {duration_s:g} s; "
                            f"must be longer than the scenario's simulation.warmup_s = {warmup:g} s")
        if isinstance(duration_s, (int, float)) and not isinstance(duration_s, bool) and math.isfinite(duration_s) \
                and duration_s > 0:  # a non-positive one is impossible, not implausible: the spec's check names it
            check_bound(FieldContext(source), "simulation.duration_s", float(duration_s), allow=allow,
                        given_as="overridden (e.g. --duration) with")
        data["simulation"]["duration_s"] = duration_s
    if demand_scale is not None:
        k = positive(FieldContext(source), "demand_scale", demand_scale)
        data["demand"]["main_veh_h"] = [x * k for x in data["demand"]["main_veh_h"]]
        data["demand"]["ramp_veh_h"] = data["demand"]["ramp_veh_h"] * k
        try:
            return spec_from_dict(data, source=source)
        except SpecError as e:
            if ": demand." not in str(e):
                raise
            raise SpecError(f"{e} (after demand_scale {k:g})") from None
    return spec_from_dict(data, source=source)
