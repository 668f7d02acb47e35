"""``merge-irl demo``: the whole pipeline on the default scenario, in one command.

Generate synthetic merges, learn Q-Avg (MLIRL, Q-SM, REIRL on request), the planning driver and, with
``--with-dagger``, the car-following logit driver cf-dagger (DAgger: SUMO's labels, about half of the
demo's time, so left out by default), re-inject the learned drivers into SUMO, evaluate them against
SUMO's own driver and the trivial baselines, write the report
and the ``.rrd`` log, and print where they are. See :func:`analysis.demo.pipeline.run_demo`.
"""

from __future__ import annotations

import argparse
from dataclasses import replace

from analysis.cli.commands._arg_types import non_negative_int, positive_int
from analysis.cli.options import DASK, EPISODES, EXECUTOR, PROGRESS, WORKERS, apply_dask_options, executor_from_args
from analysis.demo.config import WITH_DAGGER_ROUNDS, DemoConfig
from analysis.demo.pipeline import run_demo
from analysis.sweep.executors import default_workers
from scenarios.loader import load_scenario
from scenarios.spec.parse import with_overrides
from sim.merges.rules import ENCOUNTER_RULES


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "demo", parents=[EPISODES, WORKERS, EXECUTOR, PROGRESS, DASK],
        description="Generate synthetic merges, learn with Q-Avg (--methods adds MLIRL, Q-SM, REIRL) and the "
                    "planning driver (--with-dagger adds the car-following logit driver cf-dagger, trained with "
                    "DAgger on SUMO's labels), re-inject the learned drivers into SUMO, evaluate them beside SUMO's driver and the baselines uniform, marginal, markov and bc, "
                    "write report.md, metrics.json and a rerun .rrd; print where they are.")
    p.add_argument("--out", default=None, metavar="DIR", help="output folder (default: ./runs/demo)")
    p.add_argument("--scenario", default="synthetic", metavar="NAME|FILE.toml",
                   help="scenario preset or TOML file (default: synthetic)")
    p.add_argument("--duration", type=float, default=None, metavar="S",
                   help="simulated seconds of each data run (default: the scenario's)")
    p.add_argument("--methods", default=None, metavar="LIST",
                   help="comma-separated IRL methods (default: qavg; mlirl, qsm and reirl are slower at the driver "
                        "encoding's 6250 states, add them here)")
    p.add_argument("--heldout-runs", type=positive_int, default=1, metavar="N",
                   help="held-out data runs (consecutive seeds) whose demonstrations score the drivers (held-out "
                        "log-likelihood, Wasserstein distances; default 1: one run is a noisy reference for the "
                        "distances, 10 rank the drivers, see docs/closed-loop.md)")
    dagger = p.add_mutually_exclusive_group()
    dagger.add_argument("--with-dagger", action="store_true",
                        help=f"also train the car-following logit driver cf-dagger ({WITH_DAGGER_ROUNDS} DAgger rounds) "
                             "and evaluate it beside the others: the driver that meets the closed-loop targets, but its "
                             "rounds need SUMO's High Brake labels in the states it reaches (15 SUMO runs of 240 s per "
                             "round), about half of the demo's wall time with them (default: left out)")
    dagger.add_argument("--dagger-rounds", type=non_negative_int, default=None, metavar="N",
                        help="as --with-dagger with N DAgger rounds (0: cf-dagger not trained, the default)")
    p.add_argument("--encounter-rule", choices=ENCOUNTER_RULES, default=ENCOUNTER_RULES[0],
                   help="how the data runs become demonstrations (default in-lane: as the closed-loop controller "
                        "observes SUMO's drivers, A's lane held; see merge-irl generate --help)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    config = DemoConfig(scenario=args.scenario, encounter_rule=args.encounter_rule, heldout_runs=args.heldout_runs)
    if args.duration is not None:

        with_overrides(load_scenario(args.scenario), duration_s=args.duration)  # one line, exit 2, before any run
        config = replace(config, data_duration_s=args.duration)
    config = replace(config, eval_episodes=args.episodes)
    if args.methods:
        config = replace(config, methods=tuple(m.strip() for m in args.methods.split(",") if m.strip()))
    if args.dagger_rounds is not None or args.with_dagger:
        config = replace(config, dagger_rounds=WITH_DAGGER_ROUNDS if args.with_dagger else args.dagger_rounds)
    # every core unless --workers or --executor says otherwise, as every command's --workers
    config = replace(config, workers=args.workers or default_workers(), executor=executor_from_args(args))
    apply_dask_options(args)
    result = run_demo(args.out, config, progress=not args.no_progress)
    print(result.format())
    return 0
