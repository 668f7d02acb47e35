"""``merge-irl reproduce``: the paper's Tables 1-3 on the authors' data."""

from __future__ import annotations

import argparse
import sys

from analysis.cli.commands._arg_types import DeprecatedAlias
from analysis.cli.commands.learn import add_config_arguments, config_from_args
from analysis.cli.options import DASK, EXECUTOR, PROGRESS, apply_dask_options, executor_from_args, seed_option
from analysis.experiments.reproduce import ReproduceConfig, reproduce_tables
from analysis.experiments.reproduce_report import format_report, save_reports_json
from irl.errors import ConfigError
from irl.methods.reirl import DEFAULT_EPSILON

#: Said when ``--data`` is missing: the demonstrations are not shipped (AGPL), users fetch them.
DATA_SOURCE = ("--data DIR is required: the authors' demonstrations are not shipped; get the folder data/ "
               "of their public repository https://github.com/RAILUSM/Model-free-IRL and pass it as --data")


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "reproduce", parents=[seed_option("master seed of the trials"), EXECUTOR, PROGRESS, DASK],
        description="Run MLIRL, Q-Avg, Q-SM and REIRL over N random initialisations on the authors' data and "
                    "print the paper's table: mean ± std of each weight and of the final log-likelihood, "
                    "the leave-one-trajectory-out log-likelihood with Wilcoxon p-values of the paired held-out "
                    "trajectories against MLIRL and the marginal, and the baselines uniform, marginal, markov "
                    "and bc as rows.")
    p.add_argument("--table", type=int, choices=(1, 2, 3), required=True, nargs="+",
                   help="1: gridworld no noise, 2: gridworld 10%% noise, 3: NGSIM merge "
                        "(several, e.g. '--table 1 2 3', run as one sweep)")
    p.add_argument("--data", default=None,
                   help="the authors' data directory (holding gridworld/ and merge_ngsim/): the folder data/ "
                        "of https://github.com/RAILUSM/Model-free-IRL")
    p.add_argument("--trials", type=int, help="random initialisations per method (default 30, 30, 10)")
    add_config_arguments(p)
    p.add_argument("--epsilon", type=float, default=None, help="REIRL L1 weight of the dual (default: per feature, the Hoeffding bound "
                                                           "of the experts' feature-count estimate)")
    p.add_argument("--no-holdout", action="store_true", help="skip the leave-one-trajectory-out evaluation")
    p.add_argument("--json-out", metavar="FILE.json", help="also write every trial and the summary to this JSON file "
                                  "(several tables: {\"tables\": [...]})")
    # the spelling before --json-out (--json is a flag elsewhere): one release more, with a note
    p.add_argument("--json", dest="json_out", action=DeprecatedAlias, use="--json-out")
    p.add_argument("--store", default=None, metavar="DIR",
                   help="keep each finished trial in DIR; a re-run skips them (resume)")
    p.add_argument("--retries", type=int, default=1, help="re-runs of a failing trial (default 1)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    if args.data is None:
        raise ConfigError(DATA_SOURCE)  # one line, exit 2 (analysis.cli.main)
    executor = executor_from_args(args)  # a bad --executor is a one-line error before any work
    apply_dask_options(args)
    run_ = reproduce_tables(args.table, ReproduceConfig(
        args.data, trials=args.trials, irl_config=config_from_args(args), seed=args.seed,
        holdout=not args.no_holdout, epsilon=DEFAULT_EPSILON if args.epsilon is None else args.epsilon,
        executor=executor, store=args.store, retries=args.retries,
        progress=not args.no_progress,
    ))
    print("\n\n".join(format_report(r) for r in run_.reports))
    print(run_.sweep.summary().splitlines()[0], file=sys.stderr)
    if args.json_out:
        if len(run_.reports) == 1:
            run_.reports[0].save_json(args.json_out)
        else:
            save_reports_json(run_.reports, args.json_out)
        print(f"wrote {args.json_out}")
    if not run_.ok:
        print(run_.sweep.summary(), file=sys.stderr)
        return 1
    return 0

