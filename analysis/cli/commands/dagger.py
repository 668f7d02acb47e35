"""``merge-irl dagger``: train the car-following logit driver with DAgger on critical labels."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from analysis.cli.commands._arg_types import DeprecatedAlias, add_allow_implausible, non_negative_int, positive_int
from analysis.cli.options import PROGRESS, WORKERS
from analysis.experiments.dagger import DaggerConfig, train_cf_driver
from irl.domains.merge.actions import ACTION_NAMES
from irl.domains.merge.car_following import car_following_decisions
from irl.domains.merge.mdp import DEFAULT_DECISION_STEP_S, read_encounters
from merge_irl.run_folder import check_writable, locked
from scenarios.loader import load_scenario

#: Where ``--out`` defaults to.
DEFAULT_OUT = "runs/dagger"

#: Action names as ``--critical`` takes them (``high_brake`` ... ``high_accel``).
ACTION_KEYS = tuple(n.lower().replace(" ", "_") for n in ACTION_NAMES)


def _actions(text: str) -> tuple[int, ...]:
    names = [t.strip().lower().replace(" ", "_") for t in text.split(",") if t.strip()]
    bad = [n for n in names if n not in ACTION_KEYS]
    if bad or not names:
        raise argparse.ArgumentTypeError(f"expected comma-separated actions among {', '.join(ACTION_KEYS)}, got {text!r}")
    return tuple(sorted({ACTION_KEYS.index(n) for n in names}))


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "dagger", parents=[WORKERS, PROGRESS],
        description="Fit the car-following logit (features of A's speed, gaps and closing speeds) on "
                    "training encounters, then for --rounds rounds let it drive in SUMO, ask SUMO's "
                    "car-following model for its action at every decision, keep the labels whose action "
                    "is critical (default High Brake) and refit (DAgger). Writes cf-logit.json (round 0) "
                    "and cf-dagger.json (the last round; not with --rounds 0); evaluate them with 'merge-irl evaluate "
                    "--driver'.")
    p.add_argument("--train", required=True, metavar="ENCOUNTERS",
                   help="training encounter table (.parquet/.csv) with A's speed v_A (and, optional, the "
                        "lengths len_C and len_B: without them every leader is taken for a car), e.g. "
                        "runs/demo/data/train_encounters.parquet")
    p.add_argument("--scenario", default="synthetic",
                   help="preset or scenario TOML of the labelling runs: the one the encounters came from")
    p.add_argument("--rounds", type=non_negative_int, default=4, help="DAgger rounds (default 4; 0: the logit alone)")
    p.add_argument("--episodes-per-round", type=positive_int, default=15, help="SUMO runs per round (default 15)")
    p.add_argument("--label-seed", type=int, default=500,
                   help="seed of the first labelling run (default 500; round r, run e: seed + r x episodes + e); "
                        "keep the evaluation seeds apart")
    p.add_argument("--duration", type=float, default=None, metavar="S",
                   help="simulated seconds per labelling run, warm-up included (default: the scenario's warm-up + "
                        "180 s, at most its duration: synthetic 240 s, i80 420 s)")
    add_allow_implausible(p)
    p.add_argument("--l2", type=float, default=None, help=f"L2 penalty of the fits (default {DaggerConfig.l2})")
    p.add_argument("--critical", type=_actions, default=(0,), metavar="ACTIONS",
                   help=f"expert actions whose labels are kept, comma-separated among {', '.join(ACTION_KEYS)} "
                        "(default high_brake; all five: plain DAgger)")
    p.add_argument("--decision-step-s", dest="decision_step_s", type=float, default=None,
                   help="seconds per decision (default: the merge domain's, 0.3)")
    # the older spelling of --decision-step-s: one release more, with a note
    p.add_argument("--decision-step", dest="decision_step_s", type=float, action=DeprecatedAlias, use="--decision-step-s")
    p.add_argument("--out", default=None, help=f"output folder (default {DEFAULT_OUT})")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    config = DaggerConfig(rounds=args.rounds, episodes_per_round=args.episodes_per_round,
                          label_seed=args.label_seed, duration_s=args.duration,
                          l2=DaggerConfig.l2 if args.l2 is None else args.l2,
                          critical_actions=args.critical, decision_step_s=DEFAULT_DECISION_STEP_S if args.decision_step_s is None else args.decision_step_s)
    spec = load_scenario(args.scenario, allow_implausible=args.allow_implausible)  # errors before any work
    train = read_encounters(args.train)
    car_following_decisions(train, decision_step_s=config.decision_step_s, where=str(args.train))  # before --out is made
    out = Path(args.out or DEFAULT_OUT)
    check_writable(out / "cf-logit.json")
    with locked(out):  # a second run into the same folder fails at once
        models = train_cf_driver(train, spec, config, workers=args.workers, where=str(args.train),
                                 progress=not args.no_progress)
        first = last = models[0].save(out / "cf-logit.json")
        if args.rounds > 0:
            last = models[-1].save(out / "cf-dagger.json")
        else:  # the logit alone: no DAgger driver, and an earlier one in the folder would not match it
            (out / "cf-dagger.json").unlink(missing_ok=True)
    n = models[-1].info["n_demo_steps"]
    print(f"round 0 (demonstrations alone): training LL/step {models[0].loglik / n:.3f} -> {first}")
    if args.rounds > 0:
        print(f"round {args.rounds}: critical labels per round {models[-1].info.get('labels_per_round', [])}, "
              f"training LL/step {models[-1].loglik / n:.3f} -> {last}")
    if not all(m.converged for m in models):
        print("warning: a fit did not converge (see 'converged' in the files); check the encounters' v_A and --l2",
              file=sys.stderr)
    print(f"evaluate: merge-irl evaluate --driver {last} --scenario {args.scenario} --demos HELDOUT_ENCOUNTERS")
    return 0
