"""``merge-irl check-metrics``: exit 1 if an evaluation's metrics.json breaches a threshold."""

from __future__ import annotations

import argparse

from analysis.evaluation.thresholds import gate, parse_thresholds


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "check-metrics",
        description="Read METRICS.json written by 'merge-irl evaluate' and exit 1 if any --fail-if "
                    "threshold holds for any policy (or the named one). Syntax: [POLICY.]METRIC OP NUMBER, "
                    "OP one of > >= < <= == !=; e.g. --fail-if 'collisions>0' --fail-if 'qavg.min_ttc_s<1.5'. "
                    "A NaN metric counts as a breach. Exit 0: all pass; 1: a threshold holds; 2: bad input.")
    p.add_argument("metrics", metavar="METRICS.json", help="metrics.json of an evaluation")
    p.add_argument("--fail-if", action="append", default=[], required=True, metavar="EXPR",
                   help="failure condition (repeat, or separate with commas)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    return gate(parse_thresholds(args.fail_if), args.metrics)
