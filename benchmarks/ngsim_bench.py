"""Benchmark: NGSIM loader throughput and peak memory vs plain pandas; calibration time.

    python -m benchmarks.ngsim_bench [--size-mb 520] [--order sorted|frame|shuffled] [--pairs DIR] [--keep]

1. Generates an NGSIM-format CSV of at least ``--size-mb`` MB in the temp folder (deleted
   afterwards unless ``--keep``): vehicles driving along Local_Y in lanes 1..7, written with
   :func:`sim.ngsim.write.write_ngsim_csv_blocks`.
2. In a fresh subprocess each: ``read_ngsim`` of the whole file, ``read_ngsim`` with a lane
   filter (lanes 6 and 7, the merge lanes), and ``pandas.read_csv`` of the whole file. Each
   child reports its wall time and its peak resident memory (``VmHWM`` of /proc/self/status:
   ``getrusage(RUSAGE_CHILDREN).ru_maxrss`` would also count the parent's memory copied at
   fork, so it cannot separate the children); an import-only child gives the baseline.
3. Times the population fit of the IDM calibration on the real pairs (``--pairs``).

Also ``merge-irl encounters`` on the file (the whole command: read, find the merges, write).
For each: the peak resident memory above the import-only child's, over the file's size (the
memory a read costs per byte of file; the imports are the same whatever the file).

Targets: >= 1 million rows/s, peak memory < 1/4 of pandas', and reading at most 2x the file's
size above the imports.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import numpy as np
import pandas as pd

from analysis.calibration import fit_population, load_pairs
from sim.ngsim.write import write_ngsim_csv_blocks
from sim.runtime.schema import COLUMNS

_CHILD = textwrap.dedent("""
    import json, sys, time
    import numpy, pandas, pyarrow, pyarrow.csv
    from sim.ngsim.io import read_ngsim
    mode, path = sys.argv[1], sys.argv[2]
    t0 = time.perf_counter()
    rows = 0
    if mode == "ngsim":
        rows = read_ngsim(path).report.rows_read
    elif mode == "ngsim_lanes_6_7":
        rows = read_ngsim(path, lanes=(6, 7)).report.rows_read
    elif mode == "pandas":
        rows = len(pandas.read_csv(path))
    elif mode == "encounters":  # the whole command: read, find the merges, write the tables
        import tempfile
        from analysis.cli.main import main
        with tempfile.TemporaryDirectory() as tmp:
            assert main(["encounters", path, "--out", tmp + "/enc.parquet"]) == 0
        with open(path, "rb") as fh:  # rows: line ends, counted a MB at a time
            rows = sum(block.count(b"\\n") for block in iter(lambda: fh.read(1 << 20), b"")) - 1
    dt = time.perf_counter() - t0
    with open("/proc/self/status") as fh:
        hwm = next(int(l.split()[1]) for l in fh if l.startswith("VmHWM:"))
    print(json.dumps({"mode": mode, "rows": rows, "seconds": dt, "peak_rss_mb": hwm / 1024}))
""")


def _blocks(n_vehicles: int, n_frames: int, per_block: int, seed: int):
    rng = np.random.default_rng(seed)
    for v0 in range(0, n_vehicles, per_block):
        nv = min(per_block, n_vehicles - v0)
        vid = np.repeat(np.arange(v0 + 1, v0 + nv + 1), n_frames)
        f0 = np.repeat(rng.integers(1, 9000, nv), n_frames)
        fr = f0 + np.tile(np.arange(n_frames), nv)
        vel = np.clip(30 + rng.normal(0, 3, nv * n_frames), 0, None)
        y = np.repeat(rng.uniform(0, 200, nv), n_frames) + np.tile(np.arange(n_frames), nv) * 3.0
        lane = np.repeat(rng.integers(1, 8, nv), n_frames)
        n = nv * n_frames
        yield pd.DataFrame({
            "Vehicle_ID": vid, "Frame_ID": fr, "Total_Frames": n_frames, "Global_Time": 1113433136100 + fr * 100,
            "Local_X": lane * 12.0 - 6 + rng.normal(0, 1, n), "Local_Y": y,
            "Global_X": 6042842.0 + rng.normal(0, 5, n), "Global_Y": 2133117.0 + y,
            "v_Length": np.repeat(rng.uniform(13, 40, nv), n_frames), "v_Width": np.repeat(rng.uniform(5.5, 8.5, nv), n_frames),
            "v_Class": 2, "v_Vel": vel, "v_Acc": rng.normal(0, 3, n), "Lane_ID": lane,
            "Preceding": 0, "Following": 0, "Space_Headway": rng.uniform(0, 200, n), "Time_Headway": rng.uniform(0, 5, n),
        }).astype(COLUMNS)


def generate_file(path: Path, size_mb: float, seed: int = 0, order: str = "sorted") -> tuple[int, float]:
    """Write an NGSIM CSV of at least ``size_mb`` MB; returns (rows, MB). ``order``: the rows
    ``sorted`` by vehicle and frame (NGSIM's order), by ``frame`` (vehicles interleaved, each in
    frame order: sorted after reading) or ``shuffled`` (any order: held, sorted, then validated);
    the last two hold the table in this process while writing."""
    bytes_per_row = 106.0  # measured on this generator's output
    n_frames = 1000
    n_vehicles = int(np.ceil(size_mb * 1e6 * 1.02 / bytes_per_row / n_frames))
    blocks = _blocks(n_vehicles, n_frames, 200, seed)
    if order != "sorted":
        t = pd.concat(list(blocks), ignore_index=True)
        t = (t.sort_values(["Frame_ID", "Vehicle_ID"], kind="stable") if order == "frame"
             else t.sample(frac=1.0, random_state=seed))
        blocks = (t.iloc[i:i + 500_000] for i in range(0, len(t), 500_000))
    write_ngsim_csv_blocks(blocks, path)
    return n_vehicles * n_frames, path.stat().st_size / 1e6


def measure(mode: str, path: Path) -> dict:
    out = subprocess.run([sys.executable, "-c", _CHILD, mode, str(path)], capture_output=True, text=True, check=True)
    return json.loads(out.stdout.splitlines()[-1])


def calibration_time(pairs_dir: Path) -> dict:
    pairs = load_pairs(pairs_dir)
    t0 = time.perf_counter()
    pop, med = fit_population(pairs, model="idm")
    return {"pairs": len(pairs), "seconds": time.perf_counter() - t0, "median_rmse_m": med}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size-mb", type=float, default=520.0)
    ap.add_argument("--pairs", type=Path, default=Path("../shared/data/ngsim_i80_car_following"),
                    help="folder of car-following pairs (default: ../shared/..., beside the checkout)")
    ap.add_argument("--skip-calibration", action="store_true")
    ap.add_argument("--order", choices=("sorted", "frame", "shuffled"), default="sorted",
                    help="row order of the generated file (default: NGSIM's, by vehicle and frame)")
    ap.add_argument("--keep", action="store_true", help="keep the generated file")
    args = ap.parse_args(argv)
    tmpdir = Path(tempfile.mkdtemp(prefix="merge-irl-ngsim-bench-"))
    path = tmpdir / "trajectories-bench.csv"
    try:
        t0 = time.perf_counter()
        rows, mb = generate_file(path, args.size_mb, order=args.order)
        print(f"generated {path} : {mb:.0f} MB, {rows:,} rows ({args.order}) in {time.perf_counter() - t0:.1f} s")
        base = measure("none", path)
        res = {m: measure(m, path) for m in ("ngsim", "ngsim_lanes_6_7", "pandas", "encounters")}
        pd_ = res["pandas"]
        size_mib = path.stat().st_size / 2**20

        def per_file(r: dict) -> float:
            return (r["peak_rss_mb"] - base["peak_rss_mb"]) / size_mib

        print(f"\n{'reader':<22}{'rows/s':>14}{'seconds':>10}{'peak RSS MB':>13}{'vs pandas':>11}"
              f"{'(peak-imports)/file':>21}")
        for m, r in res.items():
            rate = r["rows"] / r["seconds"]
            print(f"{m:<22}{rate:>14,.0f}{r['seconds']:>10.2f}{r['peak_rss_mb']:>13.0f}"
                  f"{r['peak_rss_mb'] / pd_['peak_rss_mb']:>11.2f}{per_file(r):>21.2f}")
        print(f"{'(imports only)':<22}{'':>14}{'':>10}{base['peak_rss_mb']:>13.0f}")
        for m in ("ngsim", "ngsim_lanes_6_7"):
            r = res[m]
            rate = r["rows"] / r["seconds"]
            print(f"\n{m}: {rate / 1e6:.2f} M rows/s (target >= 1.00: {'ok' if rate >= 1e6 else 'MISSED'}), "
                  f"speed {pd_['seconds'] / r['seconds']:.2f}x pandas; peak memory "
                  f"{r['peak_rss_mb'] / pd_['peak_rss_mb']:.3f} of pandas' (target < 0.25: "
                  f"{'ok' if r['peak_rss_mb'] < 0.25 * pd_['peak_rss_mb'] else 'MISSED'})")
        r = res["ngsim"]
        print(f"\nreading the whole file: peak {per_file(r):.2f}x the file's size above the imports (target <= 2.00: "
              f"{'ok' if per_file(r) <= 2.0 else 'MISSED'}); the encounters command: {per_file(res['encounters']):.2f}x")
    finally:
        if not args.keep:
            path.unlink(missing_ok=True)
            os.rmdir(tmpdir)
    if not args.skip_calibration:
        c = calibration_time(args.pairs)
        print(f"\ncalibration: IDM population fit on {c['pairs']} real pairs: {c['seconds']:.1f} s "
              f"(median spacing RMSE {c['median_rmse_m']:.2f} m)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
