"""``merge-irl generate``: simulate a scenario; write trajectories, encounters and the spec used."""

from __future__ import annotations

import argparse
import sys


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "generate", help="simulate a scenario in SUMO and write NGSIM-schema trajectories + merge encounters",
        description="Simulate a scenario headless in SUMO; write trajectories.parquet, encounters.parquet, "
                    "merges.parquet and scenario.toml (and trajectories.csv with --csv) into --out.",
    )
    p.add_argument("--scenario", default="synthetic", metavar="NAME|FILE.toml",
                   help="preset name (synthetic, i80) or a scenario TOML file (default: synthetic)")
    p.add_argument("--duration", type=float, default=None, metavar="S", help="simulated seconds (default: the spec's)")
    p.add_argument("--seed", type=int, default=None, metavar="N", help="SUMO seed (default: the spec's)")
    p.add_argument("--csv", action="store_true", help="also write trajectories.csv in NGSIM's text format")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--out", default=None, metavar="DIR", help="output folder (default: ./runs/<scenario>-<seed>)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from scenarios.loader import load_scenario
    from sim.generate import generate

    spec = load_scenario(args.scenario)
    res = generate(spec, args.out, seed=args.seed, duration_s=args.duration, csv=args.csv,
                   progress=not args.no_progress)
    sim = res.simulation
    print(f"{sim.spec.name} seed {sim.seed}: {sim.n_vehicles} vehicles, {sim.n_vehicle_steps} rows, "
          f"{len(res.encounters.merges)} merges, {len(res.encounters.frames)} encounter frames "
          f"in {sim.wall_time_s:.1f} s", file=sys.stderr)
    for f in res.files:
        print(f)
    return 0
