"""Benchmark: the exact solvers alone, time per trial against the targets (quick, ~1 minute).

    python -m benchmarks.irl_exact_bench [--data ../shared/data/railusm] [--trials 3]

For each of the paper's three data sets (Table 1 gridworld, Table 2 gridworld 10% noise,
Table 3 NGSIM merge) and each Q-based method, the median wall time of ``--trials`` fits with the
paper's settings, the final log-likelihood and whether the fit converged, next to the target.
``irl_bench`` is the full side-by-side comparison with the faithful solver.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from analysis.cli.commands._arg_types import positive_int
from analysis.experiments.learn import fit_problem
from analysis.experiments.trials import cached_table_problem
from irl.config import IRLConfig

TARGETS_S = {"qavg": (0.05, 0.05, 0.05), "qsm": (1.0, 1.0, 10.0), "mlirl": (1.0, 1.0, 10.0)}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", default=os.environ.get("MERGE_IRL_RAILUSM", "../shared/data/railusm"))
    p.add_argument("--trials", type=positive_int, default=3)
    args = p.parse_args(argv)
    print(f"{'table':>5} {'method':>6} {'median s/trial':>15} {'target s':>9} {'ok':>3} "
          f"{'final LL':>10} converged")
    for t_index, table in enumerate((1, 2, 3)):
        problem = cached_table_problem(table, os.path.abspath(args.data))
        for method, targets in TARGETS_S.items():
            times, res = [], None
            for seed in range(args.trials):
                t0 = time.perf_counter()
                res = fit_problem(problem, method, IRLConfig.paper(), seed)
                times.append(time.perf_counter() - t0)
            assert res is not None  # --trials is at least 1
            med = float(np.median(times))
            target = targets[t_index]
            print(f"{table:>5} {method:>6} {med:>15.3f} {target:>9.2f} {'yes' if med < target else 'NO':>3} "
                  f"{res.loglik:>10.2f} {res.converged}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
