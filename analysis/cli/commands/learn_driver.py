"""``merge-irl learn-driver``: a planning driver whose reward is learned from demonstrations alone."""

from __future__ import annotations

import argparse
import sys

from analysis.cli.commands._arg_types import DeprecatedFlag
from analysis.cli.options import PROGRESS, demos_option, seed_option
from analysis.experiments.learn_driver import flag_lines, learn_driver, learn_driver_by_replay, resolve_fit
from irl.domains.merge.mdp import DEFAULT_DECISION_STEP_S
from irl.errors import DemonstrationError
from irl.planning.replay_fit import ReplayFitConfig
from merge_irl.run_folder import check_writable


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "learn-driver", parents=[demos_option(
            "an encounter table (.parquet/.csv, with v_A) or a folder of car-following pair CSVs (several "
            "sources, kept apart)", required=True), seed_option("seed of the held-out split"), PROGRESS],
        description="Fit a planning driver (a reward over continuous merge features, acted on by a short-horizon "
                    "planner on a kinematic model) from demonstrations alone (no simulator labels). "
                    "--fit replay (the default for folders of real car-following pair CSVs): the reward's weights "
                    "and gap shape are chosen by replaying the training pairs from their recorded initial "
                    "states (Nelder-Mead on the average of the mean and the median spacing RMSE over pairs, a collision costing 30 m), then its "
                    "temperature by the training likelihood; --holdout scores held-out followers beside IDM "
                    "with SUMO's defaults. --fit likelihood (the default for merge encounter tables): the "
                    "weights by maximum likelihood, the settings by held-out likelihood. Writes DRIVER.json "
                    "(format merge-irl-planner/1), which 'merge-irl evaluate --driver' and "
                    "'merge-irl calibrate evaluate --driver' take.")
    p.add_argument("--out", required=True, metavar="DRIVER.json", help="driver file to write")
    p.add_argument("--decision-step-s", dest="decision_step_s", type=float, default=None,
                   help="seconds per decision, a multiple of 0.1 (default: the merge domain's, 0.3)")
    p.add_argument("--fit", choices=("auto", "replay", "likelihood"), default="auto",
                   help="the criterion: replay (pairs only) or likelihood; auto (default): replay when every "
                        "--demos is a folder of pairs, else likelihood")
    p.add_argument("--holdout", type=float, default=0.0, metavar="FRACTION",
                   help="--fit replay: hold out this fraction of the followers (split as 'calibrate fit --holdout' "
                        "splits them with the same --seed) and score them beside IDM with SUMO's defaults")
    p.add_argument("--max-evals", dest="max_evals", type=int, default=None, metavar="N",
                   help="--fit replay: replays the optimiser may spend (default 100; each replays every "
                        "training pair)")
    p.add_argument("--no-selection", action="store_true",
                   help="skip the held-out selection of the planner's settings: fit the defaults (faster)")
    # the spelling before --no-progress, which every other command uses: one release more, with a note
    p.add_argument("--quiet", dest="no_progress", action=DeprecatedFlag, use="--no-progress")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    check_writable(args.out)  # an unwritable --out fails now, not after the fit

    def log(line: str) -> None:
        if not args.no_progress:
            print(line, file=sys.stderr, flush=True)

    step = DEFAULT_DECISION_STEP_S if args.decision_step_s is None else args.decision_step_s
    fit = resolve_fit(args.fit, args.demos)
    if fit == "replay":

        cfg = ReplayFitConfig(max_evals=args.max_evals) if args.max_evals is not None else None
        driver = learn_driver_by_replay(args.demos, args.out, holdout=args.holdout, seed=args.seed,
                                        decision_step_s=step, config=cfg, log=log)
    else:
        if args.holdout:
            raise DemonstrationError("--holdout scores held-out followers of pair folders: it goes with --fit replay")
        driver = learn_driver(args.demos, args.out, seed=args.seed, decision_step_s=step,
                              select=not args.no_selection, log=log)
    c = driver.config
    weights = ", ".join(f"{n}={t:.3g}" for n, t in zip(driver.feature_names, driver.theta))
    print(f"planning driver: {driver.info['n_decisions']} decisions, loglik {driver.loglik:.1f} "
          f"({driver.loglik / driver.info['n_decisions']:.3f} per decision){'' if driver.converged else '  (NOT converged)'}")
    print(f"  fitted by {driver.info.get('fit', 'likelihood')}; settings: backup {c.backup}, horizon {c.horizon_s} s, "
          f"C {c.c_model}, gamma {c.gamma}, temperature {c.temperature:.3g}; gap shape T {driver.shape.T_s:.2f} s, "
          f"s0 {driver.shape.s0_ft:.1f} ft, v0 {driver.shape.v0_ft_s:.1f} ft/s")
    if "heldout" in driver.info:
        h = driver.info["heldout"]
        print(f"  held out ({h['pairs']} pairs): median spacing RMSE {h['median_rmse_m']:.2f} m (IDM with SUMO's "
              f"defaults {h['idm_defaults_median_rmse_m']:.2f} m), mean {h['mean_rmse_m']:.2f} m "
              f"({h['idm_defaults_mean_rmse_m']:.2f} m), collisions {h['collisions']}, LL {h['ll_per_decision']:.3f}")
    print(f"  weights: {weights}")
    print(f"  wrote {args.out}")
    for line in flag_lines(driver):
        print(line, file=sys.stderr)
    return 0
