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
from dataclasses import asdict, fields
from pathlib import Path

from analysis.calibration.classes import DriverClasses
from analysis.calibration.models import CALIBRATION_MODELS, PARAM_NAMES, SUMO_DEFAULTS, CFParams
from analysis.calibration.objective import DEFAULT_OBJECTIVE, OBJECTIVES
from analysis.calibration.result import CalibrationResult, PairFit, ParamSpread
from merge_irl.atomic import write_text_atomic
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


def _params(src: str, where: str, d: object) -> CFParams:
    if not isinstance(d, dict):
        raise SpecError(f"{src}: [{where}] must be a table of SUMO vType attributes")
    unknown = sorted(set(d) - set(PARAM_NAMES))
    if unknown:
        raise SpecError(f"{src}: [{where}] unknown parameter(s) {unknown}; expected {list(PARAM_NAMES)}")
    vals = {}
    for k, v in d.items():
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0 < v < math.inf:
            raise SpecError(f"{src}: [{where}] {k} = {v!r}; expected a positive finite number")
        vals[k] = float(v)
    missing = [k for k in PARAM_NAMES if k not in vals]
    if missing:  # a hand-written table may name only some: say which values are SUMO's defaults
        warnings.warn(f"{src}: [{where}] has no {', '.join(missing)}: SUMO's defaults are used "
                      f"({', '.join(f'{k} = {getattr(SUMO_DEFAULTS, k):g}' for k in missing)})",
                      DefaultParamsWarning, stacklevel=3)
    return CFParams(**vals)


class DefaultParamsWarning(UserWarning):
    """A parameter table of a params file leaves parameters out: they take SUMO's defaults."""


def _classes(src: str, d: object) -> DriverClasses:
    if not isinstance(d, dict) or "edges_s" not in d or "member" not in d:
        raise SpecError(f"{src}: [classes] needs edges_s = [...] (s) and [[classes.member]] parameter tables")
    edges, members = d["edges_s"], d["member"]
    if not isinstance(edges, list) or any(isinstance(e, bool) or not isinstance(e, (int, float)) for e in edges):
        raise SpecError(f"{src}: [classes] edges_s = {edges!r}; expected a list of numbers (s)")
    if not isinstance(members, list) or len(members) != len(edges) + 1:
        raise SpecError(f"{src}: [classes] {len(edges)} edges_s need {len(edges) + 1} [[classes.member]] tables, "
                        f"got {len(members) if isinstance(members, list) else members!r}")
    params = tuple(_params(src, f"classes.member {i + 1}", m) for i, m in enumerate(members))
    try:
        return DriverClasses(edges_s=tuple(float(e) for e in edges), params=params)
    except SpecError as e:
        raise SpecError(f"{src}: [classes] {e}") from None


def _number(v: object) -> float:
    """``v`` as a float; TOML strings and booleans are not numbers (TypeError)."""
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise TypeError(f"{v!r} is not a number")
    return float(v)


def load_result(path: str | os.PathLike) -> CalibrationResult:
    """Read a params TOML written by :func:`save_result` (or hand-written with at least
    ``model`` and ``[population]``; ``objective`` defaults to :data:`~.objective.DEFAULT_OBJECTIVE`;
    parameters a table leaves out take SUMO's defaults, named in a :class:`DefaultParamsWarning`).

    Raises:
        FileNotFoundError: ``path`` does not exist.
        SpecError: not valid TOML, no or an unknown ``model``, no ``[population]`` table, a parameter
            that is not a positive finite number, a malformed
            ``[spread.*]``, ``[[pair]]`` or ``[classes]`` entry, ``fitted`` not a list of parameter
            names, or a non-numeric ``n_pairs``, ``population_median_rmse_m`` or ``seconds_*``.
    """
    path = Path(path)
    src = str(path)
    try:
        data = tomllib.loads(path.read_text())
    except FileNotFoundError:
        raise
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
        raise SpecError(f"{src}: not valid TOML: {e}") from e
    if "model" not in data:
        raise SpecError(f"{src}: missing model = \"...\" (the car-following model the parameters are for; "
                        f"one of {sorted(CALIBRATION_MODELS)})")
    model = data["model"]
    if model not in CALIBRATION_MODELS:
        raise SpecError(f"{src}: model = {model!r}; expected one of {sorted(CALIBRATION_MODELS)}")
    objective = data.get("objective", DEFAULT_OBJECTIVE)
    if objective not in OBJECTIVES:
        raise SpecError(f"{src}: objective = {objective!r}; expected one of {sorted(OBJECTIVES)}")
    if "population" not in data:
        raise SpecError(f"{src}: missing [population] table")
    pop = _params(src, "population", data["population"])
    spread_tables = data.get("spread", {})
    if not isinstance(spread_tables, dict):
        raise SpecError(f"{src}: spread must be tables [spread.<parameter>]")
    spread = []
    for n, s in spread_tables.items():
        try:
            spread.append((n, ParamSpread(**{f.name: _number(s[f.name]) for f in fields(ParamSpread)})))
        except (KeyError, TypeError, ValueError) as e:
            raise SpecError(f"{src}: [spread.{n}] needs numbers mean, std, median, q10, q90") from e
    pair_tables = data.get("pair", [])
    if not isinstance(pair_tables, list):
        raise SpecError(f"{src}: pair must be an array of tables [[pair]]")
    pairs = []
    for i, p in enumerate(pair_tables):
        try:
            pairs.append(PairFit(name=str(p["name"]), group=str(p["group"]), rmse_m=_number(p["rmse_m"]),
                                 params=_params(src, f"pair {i} params", p["params"])))
        except KeyError as e:
            raise SpecError(f"{src}: [[pair]] number {i + 1} misses {e}") from e
        except (TypeError, ValueError) as e:
            raise SpecError(f"{src}: [[pair]] number {i + 1}: rmse_m = {p.get('rmse_m')!r}; expected a number"
                            if isinstance(p, dict) else f"{src}: [[pair]] number {i + 1} must be a table") from e
    fitted = data.get("fitted", [])
    if not isinstance(fitted, list) or not all(isinstance(f, str) and f in PARAM_NAMES for f in fitted):
        raise SpecError(f"{src}: fitted = {fitted!r}; expected a list of names from {list(PARAM_NAMES)}")
    followers = data.get("train_followers", [])
    if not isinstance(followers, list) or not all(isinstance(f, str) for f in followers):
        raise SpecError(f"{src}: train_followers must be a list of follower names (strings)")
    numbers = {}
    for key, default in (("population_median_rmse_m", float("nan")), ("seconds_population", 0.0),
                         ("seconds_per_pair", 0.0), ("n_pairs", len(pairs))):
        try:
            numbers[key] = _number(data.get(key, default))
        except (TypeError, ValueError) as e:
            raise SpecError(f"{src}: {key} = {data[key]!r}; expected a number") from e
    if numbers["n_pairs"] != int(numbers["n_pairs"]) or numbers["n_pairs"] < 0:
        raise SpecError(f"{src}: n_pairs = {data['n_pairs']!r}; expected a whole number >= 0")
    return CalibrationResult(
        model=model, fitted=tuple(fitted), population=pop,
        population_median_rmse_m=numbers["population_median_rmse_m"],
        per_pair=tuple(pairs), spread=tuple(spread), n_pairs=int(numbers["n_pairs"]),
        seconds_population=numbers["seconds_population"],
        seconds_per_pair=numbers["seconds_per_pair"], objective=objective,
        classes=_classes(src, data["classes"]) if "classes" in data else None,
        train_followers=tuple(sorted(set(followers))),
    )
