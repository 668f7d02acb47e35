"""The fingerprint of a short closed-loop run: sha256 of every output of ``run_scenario`` and of
the controller's records, recorded before the session refactor (``tests/data/run_fingerprints.json``)
and checked against it by ``test_run_fingerprint.py::test_run_scenario_outputs_are_byte_identical``.

Regenerate (only when a change of outputs is intended)::

    PYTHONPATH=. python tests/sim/runtime/run_fingerprint.py > tests/data/run_fingerprints.json
"""

from __future__ import annotations

import hashlib
import json
import sys

import numpy as np

SEEDS = (1, 2)
DURATION_S = 110.0
#: Columns the control table gained after the recording, each by an intended change (left out of
#: the fingerprint so the recording before the session refactor stays the reference):
#: ``collision_pair`` (the colliding pair, so A collisions count distinct pairs).
ADDED_CONTROL_COLUMNS = ("collision_pair",)


def _sha(*parts: bytes) -> str:
    h = hashlib.sha256()
    for p in parts:
        h.update(p)
    return h.hexdigest()


def _frame_sha(df) -> str:
    parts = [",".join(map(str, df.columns)).encode()]
    for c in df.columns:
        col = df[c]
        arr = col.to_numpy()
        parts.append(np.ascontiguousarray(arr).tobytes() if arr.dtype != object else repr(arr.tolist()).encode())
    return _sha(*parts)


def fingerprint(seed: int) -> dict[str, str]:
    """sha256 of the table, SUMO ids, events, auxiliary lane start, decisions and control episodes
    of a ``DURATION_S`` synthetic run with a uniform-random driver (sampled: the generator path)."""
    from scenarios.loader import load_scenario
    from sim.closed_loop.config import ControllerConfig
    from sim.closed_loop.controller import Controller
    from sim.drivers.policy import UniformPolicy
    from sim.runtime.run import run_scenario

    ctl = Controller(UniformPolicy(), ControllerConfig(high_brake="need"))
    res = run_scenario(load_scenario("synthetic"), seed=seed, duration_s=DURATION_S, hooks=[ctl])
    return {
        "table": _frame_sha(res.table),
        "sumo_ids": _sha(repr(res.sumo_ids).encode()),
        "events": _sha(repr(res.events).encode()),
        "aux_lane_start_ft": repr(res.aux_lane_start_ft),
        "decisions": _frame_sha(ctl.decision_table()),
        "controls": _frame_sha(ctl.control_table().drop(columns=list(ADDED_CONTROL_COLUMNS), errors="ignore")),
        "n_rows": str(len(res.table)),
        "n_decisions": str(len(ctl.decision_table())),
    }


if __name__ == "__main__":
    json.dump({str(s): fingerprint(s) for s in SEEDS}, sys.stdout, indent=1, sort_keys=True)
    sys.stdout.write("\n")
