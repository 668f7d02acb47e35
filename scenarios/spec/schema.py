"""The schemas of a scenario's ``[road]``, ``[demand]`` and vType tables (pydantic models,
validated by :func:`merge_irl.json_file.validate` into :class:`scenarios.errors.SpecError` as
``file: field.path: problem``).

Each field's checks are the one-field checks of :mod:`scenarios.spec.fields` (a number, finite,
of sane magnitude, positive, ...) and its plausibility bound (:mod:`scenarios.spec.bounds`;
the validation context's ``allow`` lifts them); the checks that tie fields together (the
geometry, the bottleneck, one demand per main lane) stay in :mod:`scenarios.spec.parse`.
A field left out is left out of ``model_fields_set``: the spec's default then applies.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from functools import partial
from typing import Annotated, Any

from pydantic import AfterValidator, BaseModel, BeforeValidator, ConfigDict, Field, ValidationInfo

from scenarios.spec.bounds import bound_problem
from scenarios.spec.fields import is_float, non_negative_value, number_value, positive_value, string_value

CAR_FOLLOW_MODELS = (
    "Krauss", "KraussOrig1", "KraussPS", "KraussX", "EIDM", "IDM", "IDMM", "BKerner",
    "Wiedemann", "W99", "PWagner2009", "PWagner2012", "SmartSK", "Daniel1", "ACC", "CACC",
)
LANE_CHANGE_MODELS = ("LC2013", "SL2015", "DK2008")
DEPART_SPEEDS = ("desired", "max", "avg", "speedLimit", "random", "last")
#: A SUMO attribute name (and a vType id).
PARAM_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")
#: Attributes a vType table sets through its own fields, not through ``cf_params``/``lc_params``.
RESERVED_PARAMS = frozenset({"id", "vClass", "length", "width", "minGap", "maxSpeed", "accel", "decel",
                             "emergencyDecel", "sigma", "tau", "speedFactor", "speedDev", "carFollowModel",
                             "laneChangeModel", "probability"})


def _check(ok: Callable[[Any], bool], msg: str) -> AfterValidator:
    """Refuse a value for which ``ok`` is false, with ``msg`` (``{v}``: the value)."""
    def run(v: Any) -> Any:
        if not ok(v):
            raise ValueError(msg.format(v=v))
        return v
    return AfterValidator(run)


def _bounded(key: str) -> AfterValidator:
    """Refuse a value outside its plausibility bound ``key``, unless the context's ``allow``."""
    def run(v: Any, info: ValidationInfo) -> Any:
        problem = bound_problem(key, v, allow=bool((info.context or {}).get("allow")))
        if problem:
            raise ValueError(problem)
        return v
    return AfterValidator(run)


def _one_of(*choices: str) -> BeforeValidator:
    return BeforeValidator(partial(string_value, choices=choices))


Number = BeforeValidator(number_value)
Integer = BeforeValidator(partial(number_value, integer=True))
Positive = BeforeValidator(positive_value)
NonNegative = BeforeValidator(non_negative_value)


class RoadSchema(BaseModel):
    """``[road]``: :class:`~scenarios.spec.model.RoadSpec`'s fields."""

    model_config = ConfigDict(extra="forbid")

    main_lanes: Annotated[Any, BeforeValidator(partial(positive_value, integer=True)),
                          _check(lambda v: v <= 6, "must be at most 6 (I-80 numbering 1..6), got {v}")] = None
    main_length_m: Annotated[Any, Positive, _bounded("road.main_length_m")] = None
    merge_position_m: Annotated[Any, Positive, _bounded("road.merge_position_m")] = None
    ramp_length_m: Annotated[Any, Positive, _bounded("road.ramp_length_m")] = None
    aux_length_m: Annotated[Any, Positive, _bounded("road.aux_length_m")] = None
    lane_width_m: Annotated[Any, Positive, _bounded("road.lane_width_m")] = None
    speed_limit_mps: Annotated[Any, Positive, _bounded("road.speed_limit_mps")] = None
    ramp_speed_limit_mps: Annotated[Any, Positive, _bounded("road.ramp_speed_limit_mps")] = None
    ramp_angle_deg: Annotated[Any, Number, _check(lambda v: 0 < v < 45, "must be in (0, 45) degrees, got {v!r}")] = None
    bottleneck_length_m: Annotated[Any, Number, _check(lambda v: v >= 0, "must be >= 0, got {v!r}"),
                                   _bounded("road.bottleneck_length_m")] = None
    bottleneck_speed_mps: Annotated[Any, Number, _check(lambda v: v >= 0, "must be >= 0, got {v!r}"),
                                    _bounded("road.bottleneck_speed_mps")] = None
    bottleneck_lanes: Annotated[Any, Integer, _check(lambda v: 0 <= v <= 6,
                                                     "must be 0 (as the main road) to 6, got {v}")] = None
    bottleneck_drop: Annotated[Any, _one_of("right", "left")] = None


def _depart_speed(v: Any) -> str:
    if isinstance(v, str) and is_float(v):  # a speed written back as text by to_toml
        v = float(v)
    if isinstance(v, (int, float)) and not isinstance(v, bool):
        return str(non_negative_value(v))
    return string_value(v, DEPART_SPEEDS)


class DemandSchema(BaseModel):
    """``[demand]`` but ``main_veh_h`` (one value or one per main lane: checked in
    :mod:`scenarios.spec.parse`, which knows the lanes)."""

    model_config = ConfigDict(extra="forbid")

    main_veh_h: Any = None
    ramp_veh_h: Annotated[Any, NonNegative, _bounded("demand.ramp_veh_h")] = None
    truck_share: Annotated[Any, NonNegative, _check(lambda v: v <= 1, "must be in [0, 1], got {v!r}")] = None
    arrivals: Annotated[Any, _one_of("poisson", "uniform")] = None
    depart_speed: Annotated[Any, BeforeValidator(_depart_speed)] = None


def _vtype_id(v: Any) -> str:
    if v is None:
        raise ValueError("missing (every vType needs an id)")
    v = string_value(v)
    if not PARAM_NAME.match(v):
        raise ValueError(f"must be letters, digits and _, got {v!r}")
    return v


def _param_key(prefix: str) -> AfterValidator:
    def run(k: str) -> str:
        if not PARAM_NAME.match(k) or k in RESERVED_PARAMS or (prefix and not k.startswith(prefix)):
            need = f"a SUMO attribute name starting with {prefix!r}" if prefix else "a SUMO attribute name"
            raise ValueError(f"must be {need}, not one of the spec's own fields")
        return k
    return AfterValidator(run)


def _param_value(v: Any) -> Any:
    if not isinstance(v, (int, float, str, bool)):
        raise ValueError(f"must be a number, string or boolean, got {type(v).__name__}")
    if isinstance(v, (int, float)) and not isinstance(v, bool):
        number_value(v)  # finite, of sane magnitude
    return v


def _table(v: Any) -> Any:
    if not isinstance(v, dict):
        raise ValueError(f"must be a table of SUMO attributes, got {type(v).__name__}")
    return v


ParamValue = Annotated[Any, BeforeValidator(_param_value)]


class VTypeSchema(BaseModel):
    """One ``[[drivers.<class>]]`` table: :class:`~scenarios.spec.model.VTypeSpec`'s fields."""

    model_config = ConfigDict(extra="forbid")

    id: Annotated[Any, BeforeValidator(_vtype_id)] = Field(default=None, validate_default=True)
    probability: Annotated[Any, Positive] = None
    car_follow_model: Annotated[Any, _one_of(*CAR_FOLLOW_MODELS)] = None
    lane_change_model: Annotated[Any, _one_of(*LANE_CHANGE_MODELS)] = None
    length_m: Annotated[Any, Positive] = None
    width_m: Annotated[Any, Positive] = None
    min_gap_m: Annotated[Any, Positive] = None
    max_speed_mps: Annotated[Any, Positive] = None
    accel: Annotated[Any, Positive] = None
    decel: Annotated[Any, Positive] = None
    emergency_decel: Annotated[Any, Positive] = None
    sigma: Annotated[Any, NonNegative, _check(lambda v: v <= 1, "must be in [0, 1], got {v!r}")] = None
    tau: Annotated[Any, Positive] = None
    speed_factor: Annotated[Any, Positive] = None
    speed_dev: Annotated[Any, NonNegative] = None
    cf_params: Annotated[dict[Annotated[str, _param_key("")], ParamValue], BeforeValidator(_table)] = {}
    lc_params: Annotated[dict[Annotated[str, _param_key("lc")], ParamValue], BeforeValidator(_table)] = {}


def given(model: BaseModel) -> dict[str, Any]:
    """The fields a table gave (the others take the spec's defaults)."""
    return {k: getattr(model, k) for k in model.model_fields_set}
