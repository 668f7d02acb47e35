"""Parallel efficiency of the sweep runner on the paper's reproduction (Tables 1-3, all methods).

Runs the same reproduction sweep on ``process:1``, ``process:2`` and ``dask-local:2`` and prints
wall times and ratios: parallel speed-up ``process:1 / process:2`` (target >= 1.8x on 2 cores),
Dask overhead ``dask-local:2 / process:2``, the total time of the whole reproduction on 2 cores
(target < 5 min with the paper's trial counts and the held-out folds), and where the time goes
(summed trial time per table and method, e.g. exact Q-SM on the NGSIM table).

    python -m benchmarks.sweep_bench                      # paper counts 30/30/10 + folds
    python -m benchmarks.sweep_bench --trials 3 --no-holdout   # quick variant

Every executor must give the same tables (checked here: trial by trial).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from collections import defaultdict
from dataclasses import replace
from pathlib import Path

from analysis.experiments.reproduce import ReproduceConfig, reproduce_tables
from irl.methods.registry import method_names

DEFAULT_DATA = Path(__file__).resolve().parents[3] / "shared" / "data" / "railusm"


def _trial_signature(run) -> list[tuple]:
    out = []
    for rep in run.reports:
        for o in (*rep.trials, *rep.holdout):
            held = None if math.isnan(o.heldout_loglik) else o.heldout_loglik
            out.append((rep.table, o.method, o.seed, o.holdout, o.theta, o.loglik, held))
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=str(DEFAULT_DATA), help="the authors' data (railusm/)")
    ap.add_argument("--tables", default="1,2,3", help="comma-separated tables (default 1,2,3)")
    ap.add_argument("--trials", type=int, default=None, help="trials per method (default: the paper's 30/30/10)")
    ap.add_argument("--methods", default=",".join(method_names()), help="comma-separated methods")
    ap.add_argument("--no-holdout", action="store_true", help="skip the leave-one-trajectory-out folds")
    ap.add_argument("--executors", default="process:1,process:2,dask-local:2",
                    help="executors to time (default process:1,process:2,dask-local:2)")
    args = ap.parse_args(argv)
    tables = [int(t) for t in args.tables.split(",") if t.strip()]
    methods = tuple(m.strip() for m in args.methods.split(",") if m.strip())
    executors = [e.strip() for e in args.executors.split(",") if e.strip()]
    config = ReproduceConfig(args.data, trials=args.trials, methods=methods, holdout=not args.no_holdout, progress=False)
    counts = "paper counts 30/30/10" if args.trials is None else f"{args.trials} trials per method"
    print(f"sweep_bench: tables {tables}, methods {list(methods)}, {counts}, "
          f"held-out folds {'off' if args.no_holdout else 'on'}")
    walls: dict[str, float] = {}
    runs = {}
    for ex in executors:
        t0 = time.perf_counter()
        run = reproduce_tables(tables, replace(config, executor=ex))
        walls[ex] = time.perf_counter() - t0
        runs[ex] = run
        print(f"  {ex:<14} {walls[ex]:8.1f} s wall  ({run.sweep.n_run} trials, {len(run.sweep.failures)} failed)",
              flush=True)
    ref = runs[executors[0]]
    same = all(_trial_signature(r) == _trial_signature(ref) for r in runs.values())
    print(f"  identical trials across executors: {same}")
    if "process:1" in walls and "process:2" in walls:
        speedup = walls["process:1"] / walls["process:2"]
        print(f"  parallel speed-up process:1 / process:2 = {speedup:.2f}x  (target >= 1.8x; "
              f"efficiency {speedup / 2:.0%})")
    if "dask-local:2" in walls and "process:2" in walls:
        print(f"  dask-local:2 / process:2 = {walls['dask-local:2'] / walls['process:2']:.2f}x  "
              f"(overhead {walls['dask-local:2'] - walls['process:2']:+.1f} s)")
    if "process:2" in walls:
        print(f"  whole run on 2 cores (process:2): {walls['process:2']:.1f} s  (target < 300 s)")
    times = ref.sweep.task_times_s
    total = sum(times.values())
    by: dict[tuple[str, str], float] = defaultdict(float)
    for key, t in times.items():
        table, method, _ = key.split("/")
        by[(table, method)] += t
    print(f"  summed trial time ({executors[0]}): {total:.1f} s; by table and method:")
    for (table, method), t in sorted(by.items(), key=lambda kv: -kv[1]):
        print(f"    {table:<7} {method:<6} {t:8.1f} s  {t / total:6.1%}")
    return 0 if same and all(r.ok for r in runs.values()) else 1


if __name__ == "__main__":
    sys.exit(main())
