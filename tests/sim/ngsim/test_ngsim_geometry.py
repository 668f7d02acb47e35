"""The shipped I-80 geometry is what the derivation script computes from the raw NGSIM.jl
files, and the ``i80`` preset's road uses it."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest
from shared_data import GEOMETRY_DIR

from tools.derive_i80_geometry import derive, to_toml

ROOT = Path(__file__).resolve().parents[3]
SHIPPED = ROOT / "scenarios" / "data" / "i80_geometry.toml"


def test_shipped_geometry_is_reproducible() -> None:
    g = derive(GEOMETRY_DIR)  # the raw NGSIM.jl files, vendored in tests/data/i80_geometry
    assert g["main_lanes"] == 6
    assert g["lane_width_ft"] == pytest.approx(12.0, abs=0.2)
    assert 0 < g["merge_position_ft"] < g["merge_position_ft"] + g["aux_length_ft"] < g["section_length_ft"]
    assert to_toml(g, "sisl/NGSIM.jl data/ (centerlines80, boundaries80)") == SHIPPED.read_text()


def test_i80_preset_road_is_the_derived_geometry() -> None:
    from scenarios.loader import load_preset

    road = tomllib.loads(SHIPPED.read_text())["road"]
    spec = load_preset("i80").road
    for key, value in road.items():
        assert getattr(spec, key) == pytest.approx(value, abs=1e-6), key
