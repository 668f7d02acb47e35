"""Benchmark: held-out quality of the car-following calibration against issue 14's targets.

    python -m benchmarks.calibration_bench [--pairs DIR] [--holdout 0.3] [--seed 0] [--stride 2]
        [--models idm krauss] [--max-nfev 40]

Splits the pairs by follower (``--holdout`` share held out), fits the population parameters of
each model on every ``--stride``-th training pair, twice: with main's former parameter bounds and
with today's physical bounds (:data:`scenarios.calibration.BOUNDS`), and scores both on the
held-out pairs beside SUMO's defaults (spacing RMSE per pair, pairs weighted equally, 95 %
bootstrap intervals). Prints fit wall times side by side (ratio new / old) and the targets:

* held-out calibrated median and mean spacing RMSE both <= 0.8x SUMO's defaults.

Figures are printed, not asserted (the project's rule for speed and quality targets).
"""

from __future__ import annotations

import argparse
import time
from unittest import mock

from scenarios.calibration import (
    evaluate,
    fit_population,
    load_pairs,
    split_by_follower,
)
from scenarios.calibration import fit as fit_module

#: The bounds on main before issue 14 (kept here only for the side-by-side comparison).
OLD_BOUNDS = {"accel": (0.1, 6.0), "decel": (0.1, 8.9), "tau": (0.05, 4.0), "minGap": (0.1, 10.0),
              "maxSpeed": (5.0, 45.0), "delta": (1.0, 10.0)}
TARGET_RATIO = 0.8


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pairs", default="/work/shared/data/ngsim_i80_car_following")
    ap.add_argument("--holdout", type=float, default=0.3)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--stride", type=int, default=2, help="fit on every N-th training pair")
    ap.add_argument("--models", nargs="+", default=["idm", "krauss"])
    ap.add_argument("--max-nfev", type=int, default=40)
    a = ap.parse_args()
    train, test = split_by_follower(load_pairs(a.pairs), a.holdout, a.seed)
    train = train[::a.stride]
    print(f"{len(train)} training pairs, {len(test)} held-out pairs (followers disjoint)")
    for model in a.models:
        rows = {}
        for label, bounds in (("old bounds", OLD_BOUNDS), ("new bounds", fit_module.BOUNDS)):
            with mock.patch.dict(fit_module.BOUNDS, bounds, clear=True):
                t0 = time.perf_counter()
                pop, _ = fit_population(train, model=model, max_nfev=a.max_nfev)
                secs = time.perf_counter() - t0
            ev = evaluate(pop, test, model=model, seed=a.seed)
            rows[label] = (secs, ev)
            p = pop
            print(f"\n[{model}, {label}] fit {secs:.1f} s: accel={p.accel:.2f} decel={p.decel:.2f} tau={p.tau:.2f} "
                  f"minGap={p.minGap:.2f} maxSpeed={p.maxSpeed:.1f}")
            for name, iv in ev.intervals:
                print(f"  {name:<22} {iv.value:7.3f}  95% [{iv.low:.3f}, {iv.high:.3f}]")
            for stat in ("median_ratio", "mean_ratio"):
                v = ev.interval(stat).value
                print(f"  target {stat} <= {TARGET_RATIO}: {v:.3f} -> {'MET' if v <= TARGET_RATIO else 'not met'}")
        (s_old, _), (s_new, _) = rows["old bounds"], rows["new bounds"]
        print(f"[{model}] population fit time new/old: {s_new:.1f} / {s_old:.1f} s = {s_new / s_old:.2f}x")


if __name__ == "__main__":
    main()
