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

from merge_irl.moved import install as _install_moved_paths

_install_moved_paths()  # old import paths (sim.controller, ...) fail naming their new home

_EXPORTS = {
    "run_scenario": "sim.runtime.run",
    "SimulationResult": "sim.runtime.run_result",
    "SumoSession": "sim.runtime.session",
    "generate": "sim.merges.generate",
    "GenerateResult": "sim.merges.generate",
    "encounters_of_run": "sim.merges.demonstrators",
    "simulate_demonstrations": "sim.merges.demonstrators",
    "demonstrator_hooks": "sim.merges.demonstrators",
    "TakeOverRule": "sim.merges.take_over",
    "extract": "sim.merges.encounters",
    "extract_encounters": "sim.merges.encounters",
    "find_merges": "sim.merges.encounters",
    "EncounterWindow": "sim.merges.encounters",
    "Encounters": "sim.merges.encounters",
    "RunContext": "sim.runtime.hooks",
    "FrameState": "sim.runtime.hooks",
    "StepHook": "sim.runtime.hooks",
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
