"""Study: the planning driver's targets, printed side by side in one run (not timed).

1. **Synthetic closed loop, demonstrations only.** :func:`analysis.demo.pipeline.run_demo` makes
   the training encounters (seeds ``--train-seeds``) and ``--heldout-runs`` held-out runs and
   learns Q-Avg, the car-following logit (``cf-logit``, the demonstrations alone), ``cf-dagger``
   (with SUMO's labels: a control, not a driver learned from people) and the planning driver
   (``planner``, the demonstrations alone). Under the physical actuation (every action at the
   driver's own acceleration, capped at A's emergency deceleration; safety filter off), every
   driver and the baselines ``uniform``, ``bc`` and ``sumo-in-lane`` (the demonstrators' own
   driver, the floor of the Wasserstein figures) drive seeds ``1..--episodes``; the planner also
   drives seeds ``2000..2000+--extra-episodes-1``. Printed: A collisions by kind with the Wilson
   95 % upper bound, held-out LL per step, W1 of TTC to C (s) and of A's speed (ft/s and x the
   floor), the need-actuation counts (0 here), and the targets: 0 A-into-C collisions pooled
   with at least 2,800 controlled As, LL >= -0.75, W1 TTC <= 1.5 s, W1 speed <= 1.2x the floor.
2. **Safety weights.** ``--bootstrap`` resamples of the training encounters (by encounter): how
   many times each safety weight (gap need, inverse TTC, headway to C) is negative.
3. **Real pairs** (``--pairs``, default the vendored ones or ``$MERGE_IRL_SHARED``'s): trained on
   70 % of the followers (seed 0), replayed on the other 30 % (most likely action): spacing RMSE
   median / mean (m) and collisions beside IDM with SUMO's defaults and, with ``--params``, a
   calibration (e.g. ``calibrate fit --classes 3 --holdout 0.3 --seed 0``).

Run: ``python -m studies.planning_driver_target [--episodes 30] [--extra-episodes 60]``.
"""

from __future__ import annotations

import argparse
import math
import os
import time
from pathlib import Path

import numpy as np
import pandas as pd

from analysis.calibration import load_pairs, load_result, split_by_follower
from analysis.calibration.driver_eval import evaluate_driver
from analysis.demo.config import DemoConfig
from analysis.demo.pipeline import run_demo
from analysis.evaluation.aggregate import rate_ci95
from analysis.evaluation.evaluate import evaluate
from analysis.experiments.learn_driver import pair_frames
from irl.domains.merge.mdp import read_encounters
from irl.planning.decisions import encounter_decisions, pair_decisions
from irl.planning.driver import learn_planning_driver
from irl.planning.model import PlannerConfig
from sim.closed_loop.records import COLLISION_KINDS
from sim.drivers.formats import driver_policy

SAFETY = ("gap_need_C", "inv_ttc_C", "headway_C")


def _f(x, nd: int = 3) -> str:
    return "-" if x is None or not math.isfinite(x) else f"{x:.{nd}f}"


def closed_loop(args) -> None:
    out = Path(args.out)
    cfg = DemoConfig(train_seeds=args.train_seeds, heldout_runs=args.heldout_runs, eval_episodes=1,
                     eval_duration_s=args.eval_duration, workers=args.workers)
    t0 = time.perf_counter()
    demo = run_demo(out / "demo", cfg, quiet=True, progress=False)
    m = demo.models
    print(f"training: {demo.n_train_encounters} encounters, {demo.n_train_steps} steps; models learned in "
          f"{time.perf_counter() - t0:.0f} s")
    train, held = out / "demo" / "data" / "train_encounters.parquet", out / "demo" / "data" / "heldout_encounters.parquet"
    drivers = [driver_policy(m[k], name=k) for k in ("planner", "cf-logit", "cf-dagger")]
    rep = evaluate([m["qavg"]], cfg.scenario, args.episodes, 1, out / "seeds-1", duration_s=args.eval_duration,
                   demos=held, train_demos=train, baselines=("uniform", "bc", "sumo-in-lane"), policies=drivers,
                   workers=args.workers, rrd=False, progress=False)
    extra = evaluate([], cfg.scenario, args.extra_episodes, 2000, out / "seeds-2000", duration_s=args.eval_duration,
                     demos=held, baselines=(), policies=drivers[:1], workers=args.workers, rrd=False,
                     progress=False) if args.extra_episodes else None
    floor = rep.aggregates["sumo-in-lane"]
    print(f"\nphysical actuation, safety filter off; seeds 1-{args.episodes}"
          + (f" (and 2000-{1999 + args.extra_episodes} for the planner)" if extra else ""))
    print("| policy | As | A collisions [95 % CI] | A into C | held-out LL/step | W1 TTC (s) | W1 speed (ft/s) "
          "| x floor | need brakes |")
    print("|---|---|---|---|---|---|---|---|---|")
    into_c: dict[str, int] = {}
    for name, a in rep.aggregates.items():
        ctl = pd.concat([e.controls for e in rep.episodes[name]], ignore_index=True)
        into_c[name] = int(((ctl["reason"] == "collision") & (ctl["collision_kind"] == "A into C")).sum())
        print(f"| {name} | {a.n_controls} | {a.a_collisions} [{_f(a.a_collision_ci95[0])}, {_f(a.a_collision_ci95[1])}] "
              f"| {into_c[name]} | {_f(a.heldout_loglik_per_step)} | {_f(a.w1_ttc_s, 2)} | {_f(a.w1_speed_A_ft_s, 2)} "
              f"| {_f(a.w1_speed_A_ft_s / floor.w1_speed_A_ft_s, 2)} | {a.need_brakes} |")
    print("\nA collisions by kind: | policy | " + " | ".join(COLLISION_KINDS) + " |")
    for name in rep.aggregates:
        ctl = pd.concat([e.controls for e in rep.episodes[name]], ignore_index=True)
        kinds = ctl.loc[ctl["reason"] == "collision", "collision_kind"].value_counts()
        print(f"| {name} | " + " | ".join(str(int(kinds.get(k, 0))) for k in COLLISION_KINDS) + " |")
    p = rep.aggregates["planner"]
    n, c = p.n_controls, into_c["planner"]
    if extra is not None:
        e = extra.aggregates["planner"]
        ctl = pd.concat([x.controls for x in extra.episodes["planner"]], ignore_index=True)
        n += e.n_controls
        c += int(((ctl["reason"] == "collision") & (ctl["collision_kind"] == "A into C")).sum())
        print(f"\nplanner on seeds 2000-{1999 + args.extra_episodes}: {e.a_collisions}/{e.n_controls} A collisions, "
              f"W1 TTC {_f(e.w1_ttc_s, 2)} s, W1 speed {_f(e.w1_speed_A_ft_s, 2)} ft/s")
    _, _, hi = rate_ci95(c, n)
    checks = [
        (f"0 A-into-C collisions pooled: {c}/{n} (95 % upper bound {_f(hi, 4)}), at least 2,800 As", c == 0 and n >= 2800),
        (f"held-out LL/step {_f(p.heldout_loglik_per_step)} >= -0.75", p.heldout_loglik_per_step >= -0.75),
        (f"W1 TTC {_f(p.w1_ttc_s, 2)} s <= 1.5 s", p.w1_ttc_s <= 1.5),
        (f"W1 speed {_f(p.w1_speed_A_ft_s, 2)} <= 1.2 x floor {_f(floor.w1_speed_A_ft_s, 2)}",
         p.w1_speed_A_ft_s <= 1.2 * floor.w1_speed_A_ft_s),
    ]
    print("\ntargets (planner, synthetic):")
    for text, ok in checks:
        print(f"  [{'met' if ok else 'NOT met'}] {text}")
    if args.bootstrap:
        safety_signs(train, args.bootstrap)


def safety_signs(train: Path, n: int) -> None:
    """How many of ``n`` bootstrap resamples (by encounter) of ``train`` give each safety weight
    a negative sign (the planner at its default settings)."""
    dec = encounter_decisions(read_encounters(train))
    groups = np.unique(dec.groups)
    rng = np.random.default_rng(0)
    neg = dict.fromkeys(SAFETY, 0)
    for _ in range(n):
        pick = rng.choice(groups, size=groups.size, replace=True)
        idx = np.concatenate([np.flatnonzero(dec.groups == g) for g in pick])
        d = learn_planning_driver(dec.take(idx), selection=PlannerConfig())
        for k in SAFETY:
            neg[k] += int(d.theta[d.feature_names.index(k)] < 0)
    print(f"\nsafety weights negative in {n} bootstrap resamples of {train}: "
          + ", ".join(f"{k} {v}/{n}" for k, v in neg.items()))


def real_pairs(args) -> None:
    pairs = load_pairs(args.pairs)
    train, test = split_by_follower(pairs, 0.3, 0)
    frames, groups = pair_frames(train)
    dec = pair_decisions(frames, groups=groups)
    t0 = time.perf_counter()
    driver = learn_planning_driver(dec, selection=PlannerConfig())
    path = Path(args.out) / "pairs-planner.json"
    driver.save(path)
    cal = load_result(args.params) if args.params else None
    ev = evaluate_driver(path, test, calibration=cal).to_json_dict()
    print(f"\nreal pairs ({args.pairs}): trained on {len(train)} pairs ({dec.n} decisions, "
          f"{time.perf_counter() - t0:.0f} s), scored on {ev['n_pairs']} held-out followers' pairs")
    print(f"  planner: median {_f(ev['median_rmse_m'])} m, mean {_f(ev['mean_rmse_m'])} m, collisions {ev['collisions']}")
    print(f"  IDM, SUMO's defaults: median {_f(ev['default_median_rmse_m'])} m, mean {_f(ev['default_mean_rmse_m'])} m")
    if cal is not None:
        print(f"  calibration {args.params}: median {_f(ev['calibrated_median_rmse_m'])} m, "
              f"mean {_f(ev['calibrated_mean_rmse_m'])} m")
    ok = ev["collisions"] == 0 and ev["median_rmse_m"] <= 0.9 * ev["default_median_rmse_m"] \
        and ev["mean_rmse_m"] <= 0.9 * ev["default_mean_rmse_m"]
    print(f"  [{'met' if ok else 'NOT met'}] 0 collisions, median and mean <= 0.9x SUMO's defaults")


def main(argv=None) -> int:
    shared = Path(os.environ.get("MERGE_IRL_SHARED", Path(__file__).resolve().parents[2] / "shared"))
    default_pairs = shared / "data" / "ngsim_i80_car_following"
    if not default_pairs.is_dir():
        default_pairs = Path(__file__).resolve().parents[1] / "tests" / "data" / "ngsim_i80_car_following"
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--episodes", type=int, default=30, help="evaluation seeds 1..N for every policy (default 30)")
    ap.add_argument("--extra-episodes", type=int, default=60, help="planner seeds 2000.. (default 60)")
    ap.add_argument("--train-seeds", type=lambda s: tuple(int(x) for x in s.split(",")), default=(101, 102, 103))
    ap.add_argument("--heldout-runs", type=int, default=10)
    ap.add_argument("--eval-duration", type=float, default=None, help="seconds per episode (default the scenario's)")
    ap.add_argument("--bootstrap", type=int, default=20, help="resamples for the safety-weight signs (0: skip)")
    ap.add_argument("--pairs", default=str(default_pairs), help="folder of real pair CSVs")
    ap.add_argument("--params", default=None, help="a calibration (calibrate fit) to show beside the pairs' figures")
    ap.add_argument("--skip-closed-loop", action="store_true",
                    help="only the safety-weight signs (on --train) and the real pairs")
    ap.add_argument("--train", default=None, help="with --skip-closed-loop: the training encounters of the signs")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", default="runs/planning-driver-target")
    args = ap.parse_args(argv)
    Path(args.out).mkdir(parents=True, exist_ok=True)
    if not args.skip_closed_loop:
        closed_loop(args)
    elif args.train and args.bootstrap:
        safety_signs(Path(args.train), args.bootstrap)
    real_pairs(args)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
