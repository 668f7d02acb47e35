"""Calibration results as TOML (``merge-irl calibrate fit --out params.toml``).

Layout::

    model = "idm"
    objective = "log"         # the population fit's objective (objective.OBJECTIVES)
    fitted = ["accel", "decel", "tau", "minGap", "maxSpeed"]
    n_pairs = 211
    population_median_rmse_m = 3.41
    seconds_population = 40.2
    seconds_per_pair = 160.0
    train_followers = ["period/follower", ...]   # the training pairs' followers (evaluate checks
                                                 # that its held-out pairs are none of them)

    [population]            # SUMO vType attributes, SI units
    accel = 1.15
    ...
    [spread.accel]          # over the per-pair fits
    mean = 1.46
    std = 1.13
    median = 1.15
    q10 = 0.53
    q90 = 2.99

    [[pair]]                # one per training pair
    name = "..."
    group = "..."
    rmse_m = 1.2
    params = { accel = 1.1, ... }

    [classes]               # optional (calibrate fit --classes C, C > 1): driver classes
    edges_s = [1.2, 2.0]    # C-1 edges of the initial time headway (s), classes.DriverClasses
    [[classes.member]]      # C tables, class order; SUMO vType attributes, SI units
    accel = 0.9
    ...
"""

from __future__ import annotations

import math
import os
import tomllib
import warnings
from dataclasses import asdict
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationInfo, create_model, field_validator

from analysis.calibration.classes import DriverClasses
from analysis.calibration.models import CALIBRATION_MODELS, PARAM_NAMES, SUMO_DEFAULTS, CFParams
from analysis.calibration.objective import DEFAULT_OBJECTIVE, OBJECTIVES
from analysis.calibration.result import CalibrationResult, PairFit, ParamSpread
from merge_irl.atomic import write_text_atomic
from merge_irl.json_file import STRICT, validate
from scenarios.errors import SpecError
from scenarios.toml_write import dumps


def result_to_dict(r: CalibrationResult) -> dict:
    return {
        "model": r.model,
        "objective": r.objective,
        "fitted": list(r.fitted),
        "n_pairs": r.n_pairs,
        "population_median_rmse_m": r.population_median_rmse_m,
        "seconds_population": r.seconds_population,
        "seconds_per_pair": r.seconds_per_pair,
        "population": r.population.as_dict(),
        "spread": {n: asdict(s) for n, s in r.spread},
        "pair": [
            {"name": f.name, "group": f.group, "rmse_m": f.rmse_m, "params": f.params.as_dict()}
            for f in r.per_pair
        ],
        **({"classes": {"edges_s": list(r.classes.edges_s), "member": [p.as_dict() for p in r.classes.params]}}
           if r.classes is not None else {}),
        "train_followers": list(r.train_followers),
    }


def save_result(r: CalibrationResult, path: str | os.PathLike) -> Path:
    """Write ``r`` as TOML, atomically."""
    path = Path(path)
    data = result_to_dict(r)
    if not data["pair"]:
        del data["pair"]
    if not data["spread"]:
        del data["spread"]
    if not data["train_followers"]:
        del data["train_followers"]
    text = dumps(data)
    return write_text_atomic(path, text)


class DefaultParamsWarning(UserWarning):
    """A parameter table of a params file leaves parameters out: they take SUMO's defaults."""


Positive = Annotated[float, Field(gt=0, allow_inf_nan=False)]
#: A parameter table: SUMO vType attributes (:data:`PARAM_NAMES`), each a positive finite number;
#: those left out take SUMO's defaults (named in a :class:`DefaultParamsWarning`).
_PARAM_FIELDS: dict[str, Any] = {n: (Positive | None, None) for n in PARAM_NAMES}
ParamsTable = create_model("ParamsTable", __config__=ConfigDict(strict=True, extra="forbid"), **_PARAM_FIELDS)


class SpreadSchema(BaseModel):
    """``[spread.<parameter>]``: :class:`ParamSpread`'s numbers."""

    model_config = STRICT
    mean: float
    std: float
    median: float
    q10: float
    q90: float


class PairSchema(BaseModel):
    """One ``[[pair]]``: :class:`PairFit`'s fields."""

    model_config = STRICT
    name: str
    group: str
    rmse_m: float
    params: ParamsTable  # type: ignore[valid-type]  # built from PARAM_NAMES


class ClassesSchema(BaseModel):
    """``[classes]``: ``edges_s`` (s) and one ``[[classes.member]]`` table more than edges."""

    model_config = STRICT
    edges_s: list[float]
    member: list[ParamsTable]  # type: ignore[valid-type]

    @field_validator("member")
    @classmethod
    def _one_more_than_edges(cls, member: list[Any], info: ValidationInfo) -> list[Any]:
        edges = info.data.get("edges_s")
        if edges is not None and len(member) != len(edges) + 1:
            raise ValueError(f"{len(edges)} edges_s need {len(edges) + 1} [[classes.member]] tables, got {len(member)}")
        return member


class ParamsFileSchema(BaseModel):
    """The schema of a params TOML (the module docstring's layout); unknown top-level keys are ignored."""

    model_config = STRICT
    model: Any = Field(default=None, validate_default=True)
    objective: str = DEFAULT_OBJECTIVE
    fitted: list[Literal[PARAM_NAMES]] = []  # type: ignore[valid-type]  # the names, from the models
    n_pairs: float | None = None
    population_median_rmse_m: float = math.nan
    seconds_population: float = 0.0
    seconds_per_pair: float = 0.0
    train_followers: list[str] = []
    population: ParamsTable  # type: ignore[valid-type]
    spread: dict[str, SpreadSchema] = {}
    pair: list[PairSchema] = []
    classes: ClassesSchema | None = None

    @field_validator("model")
    @classmethod
    def _known_model(cls, model: Any) -> Any:
        if model is None:
            raise ValueError(f'missing: model = "..." (the car-following model the parameters are for; one of '
                             f"{sorted(CALIBRATION_MODELS)})")
        if model not in CALIBRATION_MODELS:
            raise ValueError(f"expected one of {sorted(CALIBRATION_MODELS)}, got {model!r}")
        return model

    @field_validator("objective")
    @classmethod
    def _known_objective(cls, objective: str) -> str:
        if objective not in OBJECTIVES:
            raise ValueError(f"expected one of {sorted(OBJECTIVES)}, got {objective!r}")
        return objective

    @field_validator("n_pairs")
    @classmethod
    def _whole(cls, n: float | None) -> float | None:
        if n is not None and not (n >= 0 and n == int(n)):
            raise ValueError(f"expected a whole number >= 0, got {n!r}")
        return n


def _params(src: str, where: str, table: Any) -> CFParams:
    """The parameters of a validated table; warns naming the ones that take SUMO's defaults."""
    vals = {k: v for k, v in dict(table).items() if v is not None}
    missing = [k for k in PARAM_NAMES if k not in vals]
    if missing:  # a hand-written table may name only some: say which values are SUMO's defaults
        warnings.warn(f"{src}: {where}: has no {', '.join(missing)}: SUMO's defaults are used "
                      f"({', '.join(f'{k} = {getattr(SUMO_DEFAULTS, k):g}' for k in missing)})",
                      DefaultParamsWarning, stacklevel=3)
    return CFParams(**vals)


def load_result(path: str | os.PathLike) -> CalibrationResult:
    """Read a params TOML written by :func:`save_result` (or hand-written with at least
    ``model`` and ``[population]``; ``objective`` defaults to :data:`~.objective.DEFAULT_OBJECTIVE`;
    parameters a table leaves out take SUMO's defaults, named in a :class:`DefaultParamsWarning`),
    validated by :class:`ParamsFileSchema`.

    Raises:
        FileNotFoundError: ``path`` does not exist.
        SpecError: not valid TOML, or a field the schema refuses, as one line ``file: field.path:
            problem`` (no or an unknown ``model``, no ``[population]`` table, a parameter that is
            not a positive finite number, a malformed ``[spread.*]``, ``[[pair]]`` or
            ``[classes]`` entry, ``fitted`` not a list of parameter names, a non-numeric
            ``n_pairs``, ``population_median_rmse_m`` or ``seconds_*``).
    """
    path = Path(path)
    src = str(path)
    try:
        data = tomllib.loads(path.read_text())
    except FileNotFoundError:
        raise
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
        raise SpecError(f"{src}: not valid TOML: {e}") from e
    m = validate(ParamsFileSchema, data, src, error=SpecError)
    pairs = []
    for i, p in enumerate(m.pair):  # loops, not comprehensions: the warnings point at the caller
        pairs.append(PairFit(name=p.name, group=p.group, rmse_m=p.rmse_m, params=_params(src, f"pair[{i}].params",
                                                                                        p.params)))
    classes = None
    if m.classes is not None:
        members = []
        for i, t in enumerate(m.classes.member):
            members.append(_params(src, f"classes.member[{i}]", t))
        try:
            classes = DriverClasses(edges_s=tuple(m.classes.edges_s), params=tuple(members))
        except SpecError as e:
            raise SpecError(f"{src}: classes: {e}") from None
    return CalibrationResult(
        model=m.model, fitted=tuple(m.fitted), population=_params(src, "population", m.population),
        population_median_rmse_m=m.population_median_rmse_m, per_pair=tuple(pairs),
        spread=tuple((n, ParamSpread(**s.model_dump())) for n, s in m.spread.items()),
        n_pairs=len(pairs) if m.n_pairs is None else int(m.n_pairs),
        seconds_population=m.seconds_population, seconds_per_pair=m.seconds_per_pair, objective=m.objective,
        classes=classes, train_followers=tuple(sorted(set(m.train_followers))),
    )
