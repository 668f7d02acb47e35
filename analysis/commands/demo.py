"""``merge-irl demo``: generate the default scenario, extract merge encounters, print a summary."""

from __future__ import annotations

import argparse


def register(subparsers) -> None:
    p = subparsers.add_parser("demo", help="run the default scenario end to end and print a summary",
                              description="Generate the default scenario (synthetic), extract merge "
                                          "encounters, print vehicles, merges and mean speed per lane.")
    p.add_argument("--out", default=None, metavar="DIR", help="output folder (default: ./runs/demo-synthetic)")
    p.add_argument("--scenario", default="synthetic", metavar="NAME|FILE.toml", help="scenario (default synthetic)")
    p.add_argument("--duration", type=float, default=None, metavar="S", help="simulated seconds")
    p.add_argument("--seed", type=int, default=None, metavar="N", help="SUMO seed")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from analysis.demo_basic import run_basic_demo

    summary = run_basic_demo(args.out, scenario=args.scenario, seed=args.seed, duration_s=args.duration,
                             progress=not args.no_progress)
    print(summary.format())
    return 0
