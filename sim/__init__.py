"""SUMO runs through libsumo, the NGSIM-schema trajectory table, and merge encounters.

    from scenarios import load_scenario
    from sim import demonstrator_hooks, encounters_of_run, extract_encounters, run_scenario
    result = run_scenario(load_scenario("synthetic"), seed=1, duration_s=120, hooks=demonstrator_hooks("in-lane"))
    encounters = encounters_of_run(result)  # as the closed-loop controller observes them
    ngsim = extract_encounters(table)  # any NGSIM-schema table: A is B's lag car at its merge

Names are imported lazily, so ``import sim`` (e.g. for ``extract_encounters`` on real NGSIM
data) does not start or even load SUMO.
"""

from __future__ import annotations

import importlib
from typing import Any

_EXPORTS = {
    "run_scenario": "sim.run",
    "SimulationResult": "sim.run_result",
    "SumoSession": "sim.session",
    "generate": "sim.generate",
    "GenerateResult": "sim.generate",
    "encounters_of_run": "sim.demonstrators",
    "simulate_demonstrations": "sim.demonstrators",
    "demonstrator_hooks": "sim.demonstrators",
    "TakeOverRule": "sim.take_over",
    "extract": "sim.encounters",
    "extract_encounters": "sim.encounters",
    "find_merges": "sim.encounters",
    "EncounterWindow": "sim.encounters",
    "Encounters": "sim.encounters",
    "RunContext": "sim.hooks",
    "FrameState": "sim.hooks",
    "StepHook": "sim.hooks",
    "SimError": "sim.errors",
    "SimulationError": "sim.errors",
    "TrajectoryFormatError": "sim.errors",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'sim' has no attribute {name!r}")
    return getattr(importlib.import_module(module), name)
