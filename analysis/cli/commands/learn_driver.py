"""``merge-irl learn-driver``: a planning driver whose reward is learned from demonstrations alone."""

from __future__ import annotations

# API imports sit inside the functions: `merge-irl --help` imports every command module (analysis/cli/commands/__init__.py).
import argparse
import sys

from analysis.cli.commands._arg_types import DeprecatedFlag


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "learn-driver", help="learn a planning driver (reward over continuous merge features) from demonstrations",
        description="Fit a planning driver's reward weights by maximum likelihood through a short-horizon planner "
                    "on a kinematic model, from demonstrations alone (no simulator labels): merge encounter "
                    "tables and/or folders of real car-following pair CSVs. The planner's settings (backup, "
                    "horizon, C's model, discount) are chosen by held-out likelihood on a split of the "
                    "encounters/pairs. Writes DRIVER.json (format merge-irl-planner/1), which "
                    "'merge-irl evaluate --driver' and 'merge-irl calibrate evaluate --driver' take.")
    p.add_argument("--demos", required=True, action="append", metavar="PATH",
                   help="an encounter table (.parquet/.csv, with v_A) or a folder of car-following pair CSVs "
                        "(repeat for several sources, kept apart)")
    p.add_argument("--out", required=True, metavar="DRIVER.json", help="driver file to write")
    p.add_argument("--decision-step-s", dest="decision_step_s", type=float, default=None,
                   help="seconds per decision, a multiple of 0.1 (default: the merge domain's, 0.3)")
    p.add_argument("--seed", type=int, default=0, help="seed of the held-out selection split (default 0)")
    p.add_argument("--no-selection", action="store_true",
                   help="skip the held-out selection of the planner's settings: fit the defaults (faster)")
    p.add_argument("--no-progress", action="store_true", help="no progress lines on stderr")
    # the spelling before --no-progress, which every other command uses: one release more, with a note
    p.add_argument("--quiet", dest="no_progress", action=DeprecatedFlag, use="--no-progress")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from analysis.experiments.learn_driver import learn_driver
    from irl.domains.merge.mdp import DEFAULT_DECISION_STEP_S
    from merge_irl.run_folder import check_writable

    check_writable(args.out)  # an unwritable --out fails now, not after the fit

    def log(line: str) -> None:
        if not args.no_progress:
            print(line, file=sys.stderr, flush=True)

    step = DEFAULT_DECISION_STEP_S if args.decision_step_s is None else args.decision_step_s
    driver = learn_driver(args.demos, args.out, seed=args.seed, decision_step_s=step, select=not args.no_selection,
                          log=log)
    c = driver.config
    weights = ", ".join(f"{n}={t:.3g}" for n, t in zip(driver.feature_names, driver.theta))
    print(f"planning driver: {driver.info['n_decisions']} decisions, loglik {driver.loglik:.1f} "
          f"({driver.loglik / driver.info['n_decisions']:.3f} per decision){'' if driver.converged else '  (NOT converged)'}")
    print(f"  settings: backup {c.backup}, horizon {c.horizon_s} s, C {c.c_model}, gamma {c.gamma}")
    print(f"  weights: {weights}")
    print(f"  wrote {args.out}")
    return 0
