"""Diagnostic: is the demonstrators' speed set by the car in the lane to their left?

SUMO's lane-change model LC2013 keeps a car from passing a slower car in the lane to its left
(``lcOvertakeRight``, default 0): it adapts its speed to that car's. The merge observation
(``d_AC, v_AC, d_AB, v_AB`` and A's speed) has no left lane, so a driver learned from it cannot
see why the demonstrators drive slower than their lead car C allows. This probe runs one SUMO
run of the scenario and, for every car in the rightmost main lane from the start of the road to
the end of the auxiliary lane (edges ``main_in`` lane 0 and ``aux`` lane 1 of
:mod:`scenarios.network`), records its speed and acceleration, its leader C (``getLeader``) and
its nearest left leader L (``getLeftLeaders``). Printed: among the frames where C is far
(``--far`` m or none, so car following towards C does not bind), the share with an L within
``--left`` m, how often the car drives no faster than L (``v <= v_L + 0.5 m/s``), the median
speeds against the allowed speed, and the mean acceleration; beside them the frames without
such an L.

Run: ``python -m studies.left_lane_probe [--scenario synthetic] [--seed 101] [--duration S]``
(default the scenario's duration; the figures in the docs: 240 s); the same
scenario with ``lc_params = { lcOvertakeRight = 1.0 }`` in its car types is the control.
docs/closed-loop.md has the figures.
"""

from __future__ import annotations

import argparse
import math

import numpy as np
import pandas as pd

from analysis.cli.commands._arg_types import positive_int
from scenarios.errors import ScenarioError
from scenarios.loader import load_scenario
from scenarios.spec.parse import with_overrides
from sim.runtime.run import run_scenario

#: The rightmost main lane before the merge and along the auxiliary lane (scenarios.network).
RIGHT_MAIN_LANES = ("main_in_0", "aux_1")
COLUMNS = ("id", "v", "acc", "gap_C", "v_C", "gap_L", "v_L", "allowed")


class LeftLaneProbe:
    """Step hook: one row (:data:`COLUMNS`, m and m/s) per car in :data:`RIGHT_MAIN_LANES` per step."""

    def __init__(self) -> None:
        self.rows: list[tuple] = []

    def on_start(self, ctx) -> None:
        import libsumo

        self._veh = libsumo.vehicle

    def on_step(self, ctx, frame) -> None:
        veh = self._veh
        for vid in veh.getIDList():
            if veh.getLaneID(vid) not in RIGHT_MAIN_LANES:
                continue
            lead = veh.getLeader(vid, 300.0)
            gap_c, v_c = (lead[1], veh.getSpeed(lead[0])) if lead and lead[0] else (math.nan, math.nan)
            left = veh.getLeftLeaders(vid)
            if left:
                lid, gap_l = min(left, key=lambda t: t[1])
                v_l = veh.getSpeed(lid)
            else:
                gap_l, v_l = math.nan, math.nan
            self.rows.append((vid, veh.getSpeed(vid), veh.getAcceleration(vid), gap_c, v_c, gap_l, v_l,
                              veh.getAllowedSpeed(vid)))

    def on_end(self, ctx) -> None:
        pass

    def table(self) -> pd.DataFrame:
        return pd.DataFrame(self.rows, columns=list(COLUMNS))


def summary(df: pd.DataFrame, far_m: float, left_m: float) -> list[str]:
    """The printed lines of one probe table (module docstring)."""
    far = df[df.gap_C.isna() | (df.gap_C > far_m)]
    near = far[far.gap_L < left_m]
    alone = far[~(far.gap_L < left_m)]
    held = (near.v <= near.v_L + 0.5).mean() if len(near) else math.nan
    return [
        f"frames of cars in the rightmost main lane: {len(df)}; C farther than {far_m:g} m or none: {len(far)} "
        f"({100 * len(far) / max(len(df), 1):.0f} %); allowed speed {df.allowed.median():.1f} m/s",
        f"  with a left leader L within {left_m:g} m: {len(near)} ({100 * len(near) / max(len(far), 1):.0f} %); "
        f"no faster than L (v <= v_L + 0.5 m/s) in {100 * held:.0f} %; median v {near.v.median():.1f}, "
        f"v_L {near.v_L.median():.1f} m/s; mean acceleration {near.acc.mean():.2f} m/s^2",
        f"  without: {len(alone)}; median v {alone.v.median():.1f} m/s; mean acceleration {alone.acc.mean():.2f} m/s^2",
    ]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scenario", default="synthetic", help="preset name or TOML path")
    ap.add_argument("--seed", type=int, default=101)
    ap.add_argument("--duration", type=positive_int, default=None, help="simulated seconds (default: the scenario's)")
    ap.add_argument("--far", type=float, default=60.0, help="C counts as far beyond this gap (m)")
    ap.add_argument("--left", type=float, default=100.0, help="a left leader within this distance (m) counts")
    args = ap.parse_args(argv)
    if not (np.isfinite(args.far) and args.far > 0 and np.isfinite(args.left) and args.left > 0):
        ap.error("--far and --left must be positive distances in metres")
    try:  # a bad scenario name, file or duration: one line before any simulation
        spec = load_scenario(args.scenario)
        if args.duration is not None:
            spec = with_overrides(spec, duration_s=float(args.duration))
    except ScenarioError as e:
        ap.error(f"--scenario/--duration: {e}")
    probe = LeftLaneProbe()
    run_scenario(spec, seed=args.seed, hooks=[probe])
    print(f"left-lane probe: {args.scenario}, seed {args.seed}, {spec.simulation.duration_s:g} s")
    for line in summary(probe.table(), args.far, args.left):
        print(line)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
