"""Benchmark: the ``generate`` sweep through each executor, and the cost of a resumed rerun.

Runs the same sweep (seeds x demand scales of one scenario) serially, through the process pool
and through a Dask ``LocalCluster`` (loopback), each into a fresh folder; prints wall times,
the speed-up over serial (parallel efficiency = speed-up / workers), the Dask overhead over the
process pool, checks that every executor wrote identical tables, and times a rerun that finds
everything in the store::

    python -m benchmarks.generate_sweep_bench [--scenario synthetic] [--seeds 1-4]
        [--demand-scale 1] [--duration 240] [--workers 2] [--no-dask]
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

from analysis.sweep.generate import generate_many, parse_scales, parse_seeds
from scenarios.loader import load_scenario


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="synthetic")
    ap.add_argument("--seeds", default="1-4")
    ap.add_argument("--demand-scale", default="1")
    ap.add_argument("--duration", type=float, default=240.0)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--no-dask", action="store_true")
    args = ap.parse_args(argv)
    spec = load_scenario(args.scenario)
    seeds, scales = parse_seeds(args.seeds), parse_scales(args.demand_scale)
    executors = ["serial", f"process:{args.workers}"] + ([] if args.no_dask else [f"dask-local:{args.workers}"])
    n = len(seeds) * len(scales)
    print(f"sweep: {spec.name}, {n} runs ({len(seeds)} seeds x {len(scales)} demand scales), "
          f"{args.duration:g} s simulated each; {os.cpu_count()} CPUs")
    times: dict[str, float] = {}
    sums: dict[str, list[str]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        os.environ.setdefault("MERGE_IRL_CACHE", str(Path(tmp) / "cache"))
        for ex in executors:
            out = Path(tmp) / ex.replace(":", "-")
            t0 = time.perf_counter()
            rep = generate_many(spec, seeds, scales, out, duration_s=args.duration, executor=ex, progress=False)
            times[ex] = time.perf_counter() - t0
            if not rep.ok:
                print(rep.summary())
                return 1
            sums[ex] = [r["table_sha256"] for r in rep.results.values()]
            sim_s = sum(r["sim_wall_time_s"] for r in rep.results.values())
            print(f"  {ex:<14} {times[ex]:7.2f} s wall   (sum of per-run simulation times {sim_s:6.2f} s)")
        t0 = time.perf_counter()
        rep = generate_many(spec, seeds, scales, Path(tmp) / executors[1].replace(":", "-"), duration_s=args.duration,
                            executor=executors[1], progress=False)
        rerun = time.perf_counter() - t0
    same = all(v == sums["serial"] for v in sums.values())
    pool = executors[1]
    speedup = times["serial"] / times[pool]
    print(f"identical tables across executors: {same}")
    print(f"process pool speed-up vs serial: {speedup:.2f}x on {args.workers} workers "
          f"(parallel efficiency {speedup / args.workers:.0%})")
    if not args.no_dask:
        d = executors[2]
        print(f"Dask LocalCluster vs process pool: {times[d]:.2f} s vs {times[pool]:.2f} s "
              f"(overhead {times[d] - times[pool]:+.2f} s, ratio {times[d] / times[pool]:.2f}x)")
    print(f"rerun with everything in the store: {rerun:.2f} s ({rep.n_cached} of {n} skipped)")
    return 0 if same else 1


if __name__ == "__main__":
    raise SystemExit(main())
