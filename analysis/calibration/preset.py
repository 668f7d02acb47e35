"""Write a scenario preset whose car drivers are a calibrated driver distribution.

:func:`preset_with_drivers` replaces a scenario's car vTypes by ``n`` members resampled from
the per-pair fits of a params file (:func:`analysis.calibration.vtypes.resample_members`,
deterministic per seed) and returns the scenario TOML text with a header comment naming the
source; the ``i80`` preset's ``[[drivers.car]]`` tables were written this way::

    python -c "from analysis.calibration.preset import write_preset; \
        write_preset('i80', 'params.toml', 'scenarios/presets/i80.toml', header=...)"
"""

from __future__ import annotations

import os
from dataclasses import replace
from pathlib import Path

from analysis.calibration.check import N_MEMBERS, calibrated_spec
from merge_irl.atomic import write_text_atomic
from analysis.calibration import load_result
from scenarios.loader import load_scenario


def preset_with_drivers(scenario: str | os.PathLike, params_path: str | os.PathLike, *, n: int = N_MEMBERS,
                        seed: int | None = None, header: str = "", car_follow_model: str | None = None) -> str:
    """TOML text of ``scenario`` with its car drivers resampled from ``params_path``.

    ``seed`` None = the scenario's own seed. ``header`` (several lines allowed) goes first as
    ``#`` comments. ``car_follow_model`` None = the params file's model; otherwise the SUMO
    ``carFollowModel`` the written car types use with the fitted parameters as they are (the
    ``i80`` preset: ``"EIDM"`` over per-pair IDM fits; EIDM extends the IIDM with the same
    accel, decel, tau, minGap, maxSpeed and delta, and its driver noise, ``sigmaleader``,
    ``sigmagap``, ``sigmaerror``, stays at SUMO's defaults since no noise key is written).

    Raises:
        FileNotFoundError: ``params_path`` does not exist.
        SpecError: an invalid scenario or params file.
        ValueError: the params file holds no per-pair fits.
    """
    spec = load_scenario(str(scenario))
    result = load_result(params_path)
    if not result.per_pair:
        raise ValueError(f"{params_path}: no per-pair fits to resample drivers from (fit without --no-per-pair)")
    out = calibrated_spec(spec, result, n_members=n, seed=spec.simulation.seed if seed is None else seed)
    if car_follow_model is not None:
        cars = tuple(replace(c, car_follow_model=car_follow_model) for c in out.drivers.car)
        out = replace(out, drivers=replace(out.drivers, car=cars))
    lines = [f"# {x}".rstrip() for x in header.splitlines()] if header else []
    return "\n".join(lines + [out.to_toml()]) + ("\n" if not out.to_toml().endswith("\n") else "")


def write_preset(scenario: str | os.PathLike, params_path: str | os.PathLike, out: str | os.PathLike,
                 **kw) -> Path:
    """:func:`preset_with_drivers` written to ``out`` atomically."""
    return write_text_atomic(out, preset_with_drivers(scenario, params_path, **kw))
