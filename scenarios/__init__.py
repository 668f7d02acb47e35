"""On-ramp merge scenarios: frozen specs loaded from TOML, presets, and SUMO networks.

    from scenarios import load_scenario, with_overrides
    spec = load_scenario("synthetic")          # a preset, or a path to a .toml file
    spec = with_overrides(spec, seed=3, duration_s=120)

Layering: ``scenarios`` imports nothing of ours but :mod:`merge_irl.units`, a leaf module of unit
constants (feet and metres) that itself imports nothing, and :mod:`merge_irl.moved`, the table of
moved import paths (standard library only).
"""

from merge_irl.moved import install as _install_moved_paths
from scenarios.errors import ScenarioError, SpecError
from scenarios.loader import DEFAULT_SCENARIO, load_preset, load_scenario, preset_names
from scenarios.spec.model import (
    DemandSpec,
    DriversSpec,
    RoadSpec,
    ScenarioSpec,
    SimulationSpec,
    VTypeSpec,
)
from scenarios.spec.parse import spec_from_dict, spec_from_file, spec_from_toml, with_overrides

_install_moved_paths()  # old import paths (scenarios.calibration, ...) fail naming their new home

__all__ = [
    "DEFAULT_SCENARIO",
    "DemandSpec",
    "DriversSpec",
    "RoadSpec",
    "ScenarioError",
    "ScenarioSpec",
    "SimulationSpec",
    "SpecError",
    "VTypeSpec",
    "load_preset",
    "load_scenario",
    "preset_names",
    "spec_from_dict",
    "spec_from_file",
    "spec_from_toml",
    "with_overrides",
]
