"""Study: a driver learned from real car-following pairs, against the pair-trained driver's targets
on the same pairs, side by side in one run.

    python -m studies.pair_driver_target --driver pairs-replay.json \
        --pairs ../shared/data/ngsim_i80_car_following --params cal-classes3.toml --holdout 0.3 --seed 0

``--driver`` is repeatable (e.g. the replay-fitted and the likelihood-fitted drivers). The held-out
followers are split as ``merge-irl calibrate fit --holdout`` and ``merge-irl learn-driver --fit
replay --holdout`` split them (same fraction and seed: the same followers). Per driver, on the
held-out pairs: median and mean spacing RMSE (m) with 95 % bootstrap intervals over pairs, beside
IDM with SUMO's defaults and, with ``--params``, a calibration of ``merge-irl calibrate fit``
(e.g. ``--classes 3 --holdout 0.3 --seed 0``: fitted on the training followers only); the share
of pairs whose simulated bumper gap fell below 2 m beside the recorded drivers'; the held-out
likelihood per decision. Over every pair (training and held-out): collisions. Then the targets:

* median <= 0.9x SUMO's defaults and below the calibration's; mean below the calibration's;
* 0 collisions over all pairs; the share closer than 2 m no higher than the recorded drivers'.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from analysis.calibration.driver_eval import evaluate_driver, replay_pairs
from analysis.calibration.pairs import load_split
from analysis.calibration.params_file import load_result
from analysis.experiments.learn_driver import CLOSE_GAP_M, pair_frames
from irl.planning.decisions import pair_decisions
from irl.planning.driver import PlanningDriver
from irl.planning.replay import replay


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--driver", action="append", required=True, metavar="DRIVER.json")
    ap.add_argument("--pairs", required=True, metavar="DIR")
    ap.add_argument("--params", default=None, metavar="CAL.toml", help="a calibration of 'calibrate fit'")
    ap.add_argument("--holdout", type=float, default=0.3)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", default=None, metavar="FILE")
    args = ap.parse_args(argv)
    pairs, train, test = load_split(args.pairs, args.holdout, args.seed)  # the folder's copies: not warned of
    cal = load_result(args.params) if args.params else None
    recorded_close = float(np.mean([float(np.min(p.spacing)) < CLOSE_GAP_M for p in test]))
    frames, groups = pair_frames(test)
    dec = pair_decisions(frames, 0.3, groups=groups)
    print(f"{len(train)} training pairs, {len(test)} held-out pairs (holdout {args.holdout}, seed {args.seed}); "
          f"recorded drivers closer than {CLOSE_GAP_M:g} m: {100 * recorded_close:.0f} % of held-out pairs")
    rows = []
    for path in args.driver:
        ev = evaluate_driver(path, test, calibration=cal, seed=args.seed)
        iv = dict(ev.intervals)
        drv = PlanningDriver.load(path)
        close = float(np.mean(ev.min_gap_m < CLOSE_GAP_M))  # the held-out replay's, not a second one
        every = replay(replay_pairs(pairs), drv.act, drv.decision_step_s)
        d_med, d_mean = float(np.median(ev.default_rmse_m)), float(np.mean(ev.default_rmse_m))
        c_med = float(np.median(ev.calibrated_rmse_m)) if ev.calibrated_rmse_m is not None else float("nan")
        c_mean = float(np.mean(ev.calibrated_rmse_m)) if ev.calibrated_rmse_m is not None else float("nan")
        med, mean = float(np.median(ev.rmse_m)), float(np.mean(ev.rmse_m))
        row = {"driver": path, "fit": drv.info.get("fit", "likelihood"), "median_rmse_m": med, "mean_rmse_m": mean,
               "median_ci95": [iv["median_rmse_m"].low, iv["median_rmse_m"].high] if "median_rmse_m" in iv else None,
               "idm_defaults_median_m": d_med, "idm_defaults_mean_m": d_mean, "calibrated_median_m": c_med,
               "calibrated_mean_m": c_mean, "close_share": close, "recorded_close_share": recorded_close,
               "collisions_all_pairs": int(every.collided.sum()), "n_all_pairs": len(pairs),
               "ll_per_decision": drv.heldout_ll_per_decision(dec)}
        row["targets"] = {
            "median <= 0.9x defaults": med <= 0.9 * d_med,
            "median < calibrated": med < c_med,
            "mean < calibrated": mean < c_mean,
            "0 collisions over all pairs": row["collisions_all_pairs"] == 0,
            "close share <= recorded": close <= recorded_close,
        }
        rows.append(row)
    print("| driver | fit | median / mean RMSE (m) | IDM defaults | calibrated | closer than 2 m | collisions, all "
          "pairs | held-out LL / decision |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {Path(r['driver']).name} | {r['fit']} | {r['median_rmse_m']:.2f} / {r['mean_rmse_m']:.2f} | "
              f"{r['idm_defaults_median_m']:.2f} / {r['idm_defaults_mean_m']:.2f} | "
              f"{r['calibrated_median_m']:.2f} / {r['calibrated_mean_m']:.2f} | {100 * r['close_share']:.0f} % "
              f"(recorded {100 * r['recorded_close_share']:.0f} %) | {r['collisions_all_pairs']}/{r['n_all_pairs']} | "
              f"{r['ll_per_decision']:.3f} |")
    for r in rows:
        print(f"{Path(r['driver']).name}: " + "; ".join(f"{k}: {'met' if ok else 'NOT met'}"
                                                       for k, ok in r["targets"].items()))
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
