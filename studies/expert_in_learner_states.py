"""Diagnostic for the closed-loop collisions: do the learned driver's collisions come from states the demonstrators
never visit? DAgger with SUMO's car-following model as the expert (printed, not timed).

The default learned driver (Q-Avg at gamma 0 on the driver features: a conditional logit over
the driver-encoded states) crashes into its lead car C in states no demonstration covers (a
closing speed of 30-50 ft/s on a nearly stopped C; docs/closed-loop.md). This script asks the
expert in exactly those states (DAgger, Ross, Gordon & Bagnell 2011, AISTATS): the learned
driver drives A in SUMO on training seeds; at each of its decisions SUMO's own car-following
model of A's vehicle type is asked which speed it would drive next
(``libsumo.vehicle.getFollowSpeed`` behind C, or on a free road without C), and that
acceleration's action bin labels the learner's state. The logit is refitted on the
demonstrations plus every label so far, ``--rounds`` times, and every round's driver is
evaluated on the same episodes as the model it started from.

The expert is car following only (it does not yield to the merging car B as SUMO's
lane-change model makes the demonstrators do), so its labels also pull the held-out
log-likelihood down; the point is the collision count. Run after
``python -m studies.closed_loop_target --episodes 2 --out runs/clt`` (which writes the
model and the encounters)::

    python -m studies.expert_in_learner_states --from runs/clt

It prints (and writes to ``--out``/results.md) each round's driver: A collisions per evaluation
seed set, pooled, and its held-out log-likelihood per step. Cost with the defaults: about 20 s per
round of labelling and 20-40 s per driver and seed set (8 minutes for ``--rounds 5`` on 2 cores).
Bad options or a ``--from`` folder without the model or the encounters stop before any work with
one line (exit 2).
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

import numpy as np
import pandas as pd

from analysis.cli.commands._arg_types import non_negative_int, positive_int
from analysis.evaluation.evaluate import evaluate
from irl.boltzmann import log_policy
from irl.domains.merge.features import feature_array
from irl.domains.merge.mdp import resample_encounters
from irl.errors import IRLError
from irl.methods.conditional_logit import fit_state_logit
from irl.result import SavedModel
from scenarios.errors import ScenarioError
from scenarios.loader import load_scenario
from sim.closed_loop.config import ControllerConfig
from sim.closed_loop.controller import Controller
from sim.drivers.learned import LearnedPolicy
from sim.errors import SimError
from sim.merges.expert_labels import ExpertLabels
from sim.runtime.run import run_scenario


def policy_of(F: np.ndarray, theta: np.ndarray, base: LearnedPolicy, name: str) -> LearnedPolicy:
    """``base`` (its bins, encoding, actions' accelerations) driving with the logit ``theta [K]``
    on the features ``F [S, A, K]``: ``log_pi [S, A] = log softmax(F theta)``."""
    return dataclasses.replace(base, log_pi=log_policy(F @ theta, 1.0), name=name)


def _seeds(text: str) -> list[int]:
    try:
        seeds = [int(x) for x in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated whole numbers, got {text!r}") from None
    return seeds


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--from", dest="src", required=True,
                    help="output folder of closed_loop_target / merge-irl demo (models/qavg.json, data/)")
    ap.add_argument("--scenario", default="synthetic",
                    help="the scenario the model's demonstrations came from (default synthetic)")
    ap.add_argument("--rounds", type=non_negative_int, default=2, help="DAgger rounds (0: only the refitted logit)")
    ap.add_argument("--episodes-per-round", type=positive_int, default=15)
    ap.add_argument("--label-seed", type=int, default=500,
                    help="first SUMO seed of the labelling runs (round r, episode e: seed + r x episodes + e)")
    ap.add_argument("--eval-seeds", type=_seeds, default=[1, 2000],
                    help="first seed of each evaluation set, comma-separated (--episodes episodes each)")
    ap.add_argument("--episodes", type=positive_int, default=30, help="evaluation episodes per seed set")
    ap.add_argument("--duration", type=float, default=240.0, help="seconds per episode")
    ap.add_argument("--l2", type=float, default=1.0)
    ap.add_argument("--workers", type=positive_int, default=2)
    ap.add_argument("--out", default="runs/expert-in-learner-states", help="folder of the evaluations and results.md")
    args = ap.parse_args(argv)
    src = Path(args.src)
    needed = [src / "models" / "qavg.json", src / "data" / "train_encounters.parquet",
              src / "data" / "heldout_encounters.parquet"]
    missing = [str(p) for p in needed if not p.is_file()]
    if missing:
        ap.error(f"--from {src}: missing {', '.join(missing)} (run studies.closed_loop_target --out {src} first)")
    n_label = args.rounds * args.episodes_per_round
    label = range(args.label_seed, args.label_seed + n_label)
    if any(set(label) & set(range(s, s + args.episodes)) for s in args.eval_seeds):
        ap.error(f"the labelling seeds {args.label_seed}..{args.label_seed + n_label - 1} overlap --eval-seeds")
    try:
        spec = load_scenario(args.scenario)
        model = SavedModel.load(needed[0])
        base = LearnedPolicy.from_model(model, name="qavg")
        rows = run(args, spec, model, base, needed[1], needed[2])
    except (IRLError, ScenarioError, SimError) as e:
        print(f"expert_in_learner_states: {e}")
        return 2
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "results.md").write_text("\n".join(rows) + "\n")
    print(f"\nwritten: {out / 'results.md'}")
    return 0


def run(args, spec, model: SavedModel, base: LearnedPolicy, train_path: Path, held_path: Path) -> list[str]:
    """The DAgger rounds and the evaluations; returns the results table's lines (also printed)."""
    dt = base.decision_step_s
    F = feature_array(tuple(model.feature_names), base.encoder, base.state_encoding, decision_step_s=dt,
                      action_acc=base.action_acc_ft_s2)
    train = resample_encounters(pd.read_parquet(train_path), base.encoder, encoding=base.state_encoding,
                                decision_step_s=dt).demos
    held = resample_encounters(pd.read_parquet(held_path), base.encoder, encoding=base.state_encoding,
                               decision_step_s=dt).demos
    s_held, a_held = np.concatenate(held.states), np.concatenate(held.actions)
    S, A = [np.concatenate(train.states)], [np.concatenate(train.actions)]
    theta = fit_state_logit(F, S[0], A[0], l2=args.l2)
    policies = [policy_of(F, theta, base, "logit-round0")]
    for r in range(args.rounds):
        t0 = time.perf_counter()
        labels: list[tuple[int, int]] = []
        for e in range(args.episodes_per_round):
            ctl = Controller(policies[-1], ControllerConfig(decision_step_s=dt))
            hook = ExpertLabels(ctl)
            run_scenario(spec, seed=args.label_seed + r * args.episodes_per_round + e, duration_s=args.duration,
                         hooks=[ctl, hook])
            labels += hook.labels
        lab = np.array(labels, dtype=np.int64).reshape(-1, 2)
        S.append(lab[:, 0])
        A.append(lab[:, 1])
        theta = fit_state_logit(F, np.concatenate(S), np.concatenate(A), l2=args.l2, x0=theta)
        policies.append(policy_of(F, theta, base, f"logit-round{r + 1}"))
        print(f"round {r + 1}: {len(lab)} expert labels in the learner's states (actions "
              f"{np.bincount(lab[:, 1], minlength=5).tolist()}), {time.perf_counter() - t0:.0f} s", flush=True)
    rows = ["| driver | " + " | ".join(f"A collisions seeds {s}-{s + args.episodes - 1}" for s in args.eval_seeds)
            + " | pooled | held-out LL/step |", "|---|" + "---|" * (len(args.eval_seeds) + 2)]
    print("\n" + "\n".join(rows), flush=True)
    for pol in policies:
        cells, hit, n = [], 0, 0
        for seed in args.eval_seeds:
            rep = evaluate([], spec, args.episodes, seed, Path(args.out) / f"{pol.name}-{seed}",
                           duration_s=args.duration, baselines=(), policies=[pol], workers=args.workers,
                           rrd=False, progress=False)
            agg = rep.aggregates[pol.name]
            cells.append(f"{agg.a_collisions}/{agg.n_controls}")
            hit, n = hit + agg.a_collisions, n + agg.n_controls
        ll = float(pol.log_pi[s_held, a_held].mean())
        rows.append(f"| {pol.name} | " + " | ".join(cells) + f" | {hit}/{n} | {ll:.3f} |")
        print(rows[-1], flush=True)
    return rows


if __name__ == "__main__":
    raise SystemExit(main())
