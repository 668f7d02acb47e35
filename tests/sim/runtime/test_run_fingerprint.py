"""``run_scenario`` writes byte-identical outputs to those recorded before the stepped-session
refactor (``tests/data/run_fingerprints.json``, made by ``tests/sim/runtime/run_fingerprint.py`` on the code
before ``sim.runtime.session`` existed): table, SUMO ids, events, decisions and control episodes."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.sim.runtime.run_fingerprint import SEEDS, fingerprint

pytestmark = pytest.mark.sumo

RECORDED = json.loads((Path(__file__).resolve().parents[2] / "data" / "run_fingerprints.json").read_text())


@pytest.mark.parametrize("seed", SEEDS)
def test_run_scenario_outputs_are_byte_identical(seed):
    assert fingerprint(seed) == RECORDED[str(seed)]
