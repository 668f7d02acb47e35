"""Write a scenario preset whose car drivers are a calibrated driver distribution.

:func:`preset_with_drivers` replaces a scenario's car vTypes by the per-pair fits of a params
file, one equally likely type per fit (:func:`analysis.calibration.vtypes.every_member`), or
``n`` resampled (:func:`analysis.calibration.vtypes.resample_members`, deterministic per seed;
the population alone when the file holds no per-pair fits), and returns
the scenario TOML text with a header comment naming the source. The cars are driven by the
scenario's own car-following model when it takes the fitted parameters
(:func:`analysis.calibration.vtypes.scenario_car_model`: IDM fits in the ``i80`` preset run
under its EIDM, with SUMO's default driver noise). ``merge-irl calibrate preset --params P.toml
--out my_i80.toml`` writes one; the ``i80`` preset's ``[[drivers.car]]`` tables were written
this way (32 resampled with seed 80: ``--drivers 32``).
"""

from __future__ import annotations

import os
from dataclasses import replace
from pathlib import Path

from analysis.calibration import load_result
from analysis.calibration.check import calibrated_spec
from analysis.calibration.models import CALIBRATION_MODELS
from analysis.calibration.vtypes import IDM_FAMILY, scenario_car_model
from merge_irl.atomic import write_text_atomic
from scenarios.errors import SpecError
from scenarios.loader import load_scenario

#: SUMO car-following models that take each fitted model's parameters with the same meaning.
COMPATIBLE_MODELS: dict[str, tuple[str, ...]] = {"idm": IDM_FAMILY, "eidm": IDM_FAMILY, "krauss": ("Krauss",)}


def preset_with_drivers(scenario: str | os.PathLike, params_path: str | os.PathLike, *, n: int | None = None,
                        seed: int | None = None, header: str = "", car_follow_model: str | None = None,
                        name: str | None = None) -> str:
    """TOML text of ``scenario`` with its car drivers resampled from ``params_path``.

    ``n`` None: one driver type per per-pair fit, equally likely (the fitted distribution
    itself); else ``n`` types, whole per-pair parameter vectors drawn with replacement with
    ``seed`` (None = the scenario's own seed; the ``i80`` preset: 32, seed 80). One type, the
    population, when the params file has no per-pair fits. ``header`` (several lines allowed)
    goes first as ``#`` comments. ``car_follow_model`` None = :func:`~analysis.calibration.vtypes.scenario_car_model` (the scenario's own model when
    it takes the fitted parameters: ``"EIDM"`` for IDM fits in the ``i80`` preset, with SUMO's
    default driver noise since no noise key is written; else the fitted model's); otherwise a
    SUMO ``carFollowModel`` of :data:`COMPATIBLE_MODELS` for the fitted model. ``name`` None =
    the scenario's name.

    Raises:
        FileNotFoundError: ``params_path`` does not exist.
        SpecError: an invalid scenario or params file, ``n`` < 1, or a ``car_follow_model`` the
            fitted parameters do not mean the same in.
    """
    spec = load_scenario(str(scenario))
    result = load_result(params_path)
    if n is not None and n < 1:
        raise SpecError(f"driver types: expected at least 1, got {n}")
    allowed = COMPATIBLE_MODELS[result.model]
    if car_follow_model is not None and car_follow_model not in allowed:
        raise SpecError(f"car-following model {car_follow_model!r}: {params_path} holds {result.model} parameters, "
                        f"which mean the same in {', '.join(allowed)} only")
    if car_follow_model is None:
        car_follow_model = scenario_car_model(result.model, [c.car_follow_model for c in spec.drivers.car])
    out = calibrated_spec(spec, result, n_members=n, seed=spec.simulation.seed if seed is None else seed,
                          car_follow_model=car_follow_model)
    if name is not None:
        out = replace(out, name=name)
    lines = [f"# {x}".rstrip() for x in header.splitlines()] if header else []
    text = out.to_toml()
    return "\n".join(lines + [text]) + ("" if text.endswith("\n") else "\n")


def default_header(scenario: str | os.PathLike, params_path: str | os.PathLike, *, n: int | None, seed: int,
                   car_follow_model: str) -> str:
    """The header ``calibrate preset`` writes: source, drivers and how to check."""
    result = load_result(params_path)
    k = len(result.per_pair)
    drivers = (f"{k} car driver types, one per per-pair {result.model} fit (equally likely)" if result.per_pair and n is None
               else f"{n} car driver types resampled (seed {seed}) from the {k} per-pair {result.model} fit(s)"
               + (f" (at most {k} distinct: a resample repeats fits)" if n is not None and n > k else "")
               if result.per_pair else
               f"one car driver type, the {result.model} population (no per-pair fits: no driver spread)")
    return (f"Scenario {scenario} with calibrated car drivers, written by merge-irl calibrate preset from "
            f"{params_path}:\n{drivers} of {result.n_pairs} real pairs, driven by SUMO's {car_follow_model} "
            f"(fitted as {CALIBRATION_MODELS[result.model]}).\n"
            f"Check against real pairs: merge-irl calibrate check --params {params_path} --pairs DIR "
            f"--scenario THIS.toml --keep-drivers")


def write_preset(scenario: str | os.PathLike, params_path: str | os.PathLike, out: str | os.PathLike,
                 **kw) -> Path:
    """:func:`preset_with_drivers` written to ``out`` atomically."""
    return write_text_atomic(out, preset_with_drivers(scenario, params_path, **kw))
