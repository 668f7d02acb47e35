"""Benchmark: `merge-irl calibrate fit` of this checkout beside a baseline checkout (speed and
held-out quality), against the calibration targets.

    python -m benchmarks.calibration_bench [--baseline /work/main] [--pairs DIR] [--holdout 0.3]
        [--seed 0] [--models idm krauss eidm] [--workers N] [--out-dir DIR] [--reuse]

For each model and each checkout (the baseline first, then this one), runs
``merge-irl calibrate fit --holdout H --seed S`` in a fresh process with that checkout first on
``PYTHONPATH`` (population + per-pair fits through the sweep runner), times it (wall clock), and
scores the fitted population on the held-out followers with *this* checkout's
``analysis.calibration.evaluate`` (the same replica and the same SUMO defaults for both, 95 %
bootstrap intervals over pairs). Prints, side by side with ratios this / baseline:

* wall time and CPU time (all its processes) of the whole fit, and the population / per-pair
  wall seconds the fit recorded (targets: population < 60 s, whole fit < 180 s on 2 cores; on
  a machine shared with other jobs the wall times grow, the CPU times much less);
* held-out median and mean spacing RMSE, calibrated over SUMO's defaults (target: both <= 0.8)
  and the share of pairs where calibrated beats the defaults.

``--reuse`` takes params files already in ``--out-dir`` instead of fitting again (their
recorded seconds are printed; the wall time is then unknown). Figures are printed, not asserted
(the project's rule for speed and quality targets). On a shared machine run it once, alone.
A model the baseline cannot fit (``eidm`` against a checkout before it) is fitted by this
checkout only (the baseline column shows "-"). EIDM is fitted through SUMO (population only,
60 SUMO runs by default), so its "per-pair fits" are 0 s.
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from analysis.calibration import CalibrationResult, Evaluation, evaluate, load_pairs, load_result, split_by_follower

TARGET_RATIO = 0.8
TARGET_POPULATION_S = 60.0
TARGET_FIT_S = 180.0


def _fit(checkout: Path, pairs: str, model: str, out: Path, holdout: float, seed: int,
         workers: int | None) -> tuple[float, float]:
    """Run ``calibrate fit`` of ``checkout``: (wall seconds, CPU seconds of the fit's processes)."""
    env = {**os.environ, "PYTHONPATH": str(checkout)}
    cmd = [sys.executable, "-m", "analysis", "calibrate", "fit", "--pairs", pairs, "--out", str(out),
           "--model", model, "--holdout", str(holdout), "--seed", str(seed), "--no-progress"]
    if workers:
        cmd += ["--workers", str(workers)]
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, env=env, cwd=checkout, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise SystemExit(f"{checkout}: calibrate fit failed: {proc.stderr.strip()[-2000:]}")
    return wall, (r1.ru_utime + r1.ru_stime) - (r0.ru_utime + r0.ru_stime)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--baseline", default="/work/main", help="checkout to compare with (default /work/main)")
    ap.add_argument("--pairs", default=str(Path(os.environ.get("MERGE_IRL_SHARED", "/work/shared"))
                                           / "data" / "ngsim_i80_car_following"))
    ap.add_argument("--holdout", type=float, default=0.3)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--models", nargs="+", default=["idm", "krauss"])
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--out-dir", default=None, help="where the params files go (default: a new temporary folder)")
    ap.add_argument("--reuse", action="store_true", help="use params files already in --out-dir")
    a = ap.parse_args()
    here = Path(__file__).resolve().parents[1]
    checkouts = {"baseline": Path(a.baseline).resolve(), "this": here}
    out_dir = Path(a.out_dir) if a.out_dir else Path(tempfile.mkdtemp(prefix="calibration-bench-"))
    out_dir.mkdir(parents=True, exist_ok=True)
    _, test = split_by_follower(load_pairs(a.pairs), a.holdout, a.seed)
    print(f"held-out: {len(test)} pairs (holdout {a.holdout}, seed {a.seed}); baseline {checkouts['baseline']}, "
          f"this {here}; params files in {out_dir}")
    for model in a.models:
        rows: dict[str, tuple[float | None, float | None, CalibrationResult, Evaluation] | None] = {}
        for label, checkout in checkouts.items():
            out = out_dir / f"{label}_{model}.toml"
            wall = cpu = None
            if not (a.reuse and out.exists()):
                try:
                    wall, cpu = _fit(checkout, a.pairs, model, out, a.holdout, a.seed, a.workers)
                except SystemExit as e:
                    if label != "baseline":
                        raise
                    print(f"[{model}] the baseline cannot fit it ({str(e).splitlines()[-1][:200]}); this checkout only")
                    rows[label] = None
                    continue
            res = load_result(out)
            ev = evaluate(res.population, test, model=model, seed=a.seed, workers=a.workers)
            rows[label] = (wall, cpu, res, ev)
        print(f"\n[{model}]  {'baseline':>24} {'this':>24} {'this/baseline':>14}")

        def line(name: str, b: float | None, t: float | None, fmt: str = "{:.3f}") -> None:
            bs = fmt.format(b) if b is not None else "-"
            ts = fmt.format(t) if t is not None else "-"
            ratio = f"{t / b:.2f}" if b and t is not None else "-"
            print(f"  {name:<22} {bs:>20} {ts:>24} {ratio:>14}")

        base_row, this_row = rows["baseline"], rows["this"]
        assert this_row is not None, "this checkout's fit either ran or raised"
        wb, cb = base_row[:2] if base_row else (None, None)
        rb, eb = (base_row[2], base_row[3]) if base_row else (None, None)
        (wt, ct, rt, et) = this_row
        line("fit wall (s)", wb, wt, "{:.1f}")
        line("fit CPU, all procs (s)", cb, ct, "{:.1f}")
        line("population fit (s)", rb.seconds_population if rb else None, rt.seconds_population, "{:.1f}")
        line("per-pair fits (s)", rb.seconds_per_pair if rb else None, rt.seconds_per_pair, "{:.1f}")
        for stat in ("median_rmse_m", "default_median_rmse_m", "mean_rmse_m", "default_mean_rmse_m",
                     "win_fraction", "median_ratio", "mean_ratio"):
            line(stat, eb.interval(stat).value if eb else None, et.interval(stat).value)
        for label, (_, _, _, ev) in ((k, v) for k, v in rows.items() if v is not None):
            ivs = "; ".join(f"{k} [{ev.interval(k).low:.3f}, {ev.interval(k).high:.3f}]"
                            for k in ("median_ratio", "mean_ratio", "win_fraction"))
            print(f"  {label} 95% intervals: {ivs}")
        print(f"  targets (this): population {rt.seconds_population:.1f} s <= {TARGET_POPULATION_S:.0f}: "
              f"{'MET' if rt.seconds_population <= TARGET_POPULATION_S else 'not met'}; whole fit "
              f"{'-' if wt is None else f'{wt:.1f}'} s <= {TARGET_FIT_S:.0f}: "
              f"{'-' if wt is None else 'MET' if wt <= TARGET_FIT_S else 'not met'}; "
              + "; ".join(f"{s} {et.interval(s).value:.3f} <= {TARGET_RATIO}: "
                          f"{'MET' if et.interval(s).value <= TARGET_RATIO else 'not met'}"
                          for s in ("median_ratio", "mean_ratio")))


if __name__ == "__main__":
    main()
