"""IRL benchmark: ``faithful`` vs ``exact`` time per trial and final log-likelihood.

    python -m benchmarks.irl_bench [--data DIR] [--trials 3] [--grid-outer 50]
                                            [--ngsim-outer 3] [--markdown FILE]

For each data set (gridworld 0 %, gridworld 10 %, NGSIM merge), each method and both settings
(paper: gamma 0.99, alpha 0.01; reference code: gamma 0.9, alpha 0.1) it runs the ``exact``
solver over ``--trials`` random initialisations (median time, best and worst final LL) and one
``faithful`` trial capped at ``--grid-outer`` / ``--ngsim-outer`` outer steps and 1000 inner
sweeps, so the whole benchmark takes minutes, not the hours the uncapped paper-literal loop
needs. It prints both side by side with the time ratio, the targets (exact Q-Avg < 50 ms per
trial on each data set; Q-SM and MLIRL < 1 s on gridworld, < 10 s on NGSIM) and the authors'
measured numbers (their Java code run on 2 cores, OpenJDK 17: :data:`AUTHORS`). REIRL is one convex solve: no faithful/exact distinction.
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from analysis.experiments.learn import fit_problem
from analysis.experiments.trials import table_problem, trial_seeds
from irl.config import IRLConfig
from irl.fit import method_names
from irl.problems import Problem

DATASETS = {1: "grid 0%", 2: "grid 10%", 3: "NGSIM"}
#: Targets for one exact trial (seconds) by (method, is_ngsim).
TARGETS = {("qavg", False): 0.05, ("qavg", True): 0.05, ("qsm", False): 1.0, ("qsm", True): 10.0,
           ("mlirl", False): 1.0, ("mlirl", True): 10.0}
#: The authors' Java code measured here (OpenJDK 17, 2 cores; reference settings, gamma 0.9): time per
#: trial, outer steps, final LL.
AUTHORS = {("qavg", 1): "0.8-1.0 s, ~19,330 steps, LL -27.0", ("qsm", 1): "15-17 s, ~7,165 steps, LL -30.2",
           ("qavg", 2): "743 s (20,000-step cap), LL -43.6", ("qsm", 2): "~73 min (projected)",
           ("qavg", 3): "hours (1.7 s per outer step)"}
#: The paper's reported mean final LL (its settings, gamma 0.99).
PAPER_LL = {1: {"mlirl": -36.50, "qavg": -29.25, "qsm": -40.39, "reirl": -43.58},
            2: {"mlirl": -45.05, "qavg": -40.49, "qsm": -57.35, "reirl": -72.11},
            3: {"mlirl": -1927.09, "qavg": -1891.34, "qsm": -1914.56, "reirl": -1920.48}}


@dataclass(frozen=True)
class Cell:
    """One benchmark measurement."""

    time_s: float
    ll_best: float
    ll_worst: float
    n_iterations: int
    converged: int
    trials: int
    note: str = ""


def measure(problem: Problem, method: str, config: IRLConfig, seeds: list[int]) -> Cell:
    times, lls, iters, conv, notes = [], [], [], 0, set()
    for seed in seeds:
        t0 = time.perf_counter()
        try:
            fit = fit_problem(problem, method, config, seed)
        except Exception as e:  # a benchmark reports failures instead of stopping
            notes.add(f"{type(e).__name__}")
            times.append(time.perf_counter() - t0)
            continue
        times.append(time.perf_counter() - t0)
        lls.append(fit.loglik)
        iters.append(fit.n_iterations)
        conv += bool(fit.converged)
        if fit.unbounded:
            notes.add("unbounded")
    finite = [x for x in lls if math.isfinite(x)]
    if len(finite) < len(lls):
        notes.add("LL nan")
    return Cell(float(np.median(times)), max(finite) if finite else float("nan"),
                min(finite) if finite else float("nan"), int(np.median(iters)) if iters else 0, conv, len(seeds),
                ",".join(sorted(notes)))


def run(data: Path, trials: int, grid_outer: int, ngsim_outer: int, tables=(1, 2, 3),
        methods: tuple[str, ...] | None = None, skip_faithful: bool = False) -> list[dict]:
    methods = method_names() if methods is None else methods
    rows = []
    for table in tables:
        problem = table_problem(table, data)
        ngsim = table == 3
        for settings in ("paper", "reference"):
            base = IRLConfig.paper() if settings == "paper" else IRLConfig.reference()
            for method in methods:
                seeds = trial_seeds(0, trials)
                exact = measure(problem, method, replace(base, solver="exact"), seeds)
                faithful = None
                if method != "reirl" and not skip_faithful:
                    cap = ngsim_outer if ngsim else grid_outer
                    faithful = measure(problem, method, replace(base, solver="faithful", max_outer=cap,
                                                                max_inner=1000), seeds[:1])
                row = dict(table=table, settings=settings, method=method, exact=exact, faithful=faithful,
                           cap=(ngsim_outer if ngsim else grid_outer))
                rows.append(row)
                print(format_row(row), flush=True)
    return rows


def _f(x: float, spec: str = ".2f") -> str:
    return "-" if x is None or not math.isfinite(x) else format(x, spec)


def _t(x: float) -> str:
    return f"{x * 1000:.1f} ms" if x < 1 else f"{x:.2f} s"


HEADER = ("data", "settings", "method", "exact s/trial", "exact LL best/worst", "target", "faithful s/trial (cap)",
          "faithful LL", "time ratio f/e", "authors (ref. code)", "paper LL")


def format_row(row: dict) -> str:
    return " | ".join(row_cells(row))


def row_cells(row: dict) -> tuple[str, ...]:
    e: Cell = row["exact"]
    f: Cell | None = row["faithful"]
    ngsim = row["table"] == 3
    target = TARGETS.get((row["method"], ngsim))
    tcell = "-" if target is None else (f"<{_t(target)} " + ("OK" if e.time_s < target else "MISSED"))
    note = f" [{e.note}]" if e.note else ""
    fcell = "convex (one solve)" if f is None else \
        f"{_t(f.time_s)} ({f.n_iterations} steps, {_t(f.time_s / max(f.n_iterations, 1))}/step)"
    fll = "-" if f is None else _f(f.ll_best) + (f" [{f.note}]" if f.note else "")
    ratio = "-" if f is None or e.time_s <= 0 else f"{f.time_s / e.time_s:.0f}x"
    authors = AUTHORS.get((row["method"], row["table"]), "-") if row["settings"] == "reference" else "-"
    paper = _f(PAPER_LL[row["table"]][row["method"]]) if row["settings"] == "paper" else "-"
    return (DATASETS[row["table"]], row["settings"], row["method"], _t(e.time_s),
            f"{_f(e.ll_best)} / {_f(e.ll_worst)}{note}", tcell, fcell, fll, ratio, authors, paper)


def markdown(rows: list[dict], trials: int) -> str:
    lines = ["| " + " | ".join(HEADER) + " |", "|" + "---|" * len(HEADER)]
    lines += ["| " + " | ".join(row_cells(r)) + " |" for r in rows]
    head = (f"Measured {time.strftime('%Y-%m-%d')} on {platform.machine()} with {os.cpu_count()} cores "
            f"(shared), Python {platform.python_version()}; exact: median of {trials} trials.")
    return head + "\n\n" + "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m benchmarks.irl_bench", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--data", default=os.environ.get("MERGE_IRL_RAILUSM", "../shared/data/railusm"),
                   help="the authors' data directory (gridworld/, merge_ngsim/)")
    p.add_argument("--trials", type=int, default=3, help="exact trials per cell")
    p.add_argument("--grid-outer", type=int, default=50, help="faithful outer-step cap on gridworld")
    p.add_argument("--ngsim-outer", type=int, default=3, help="faithful outer-step cap on NGSIM")
    p.add_argument("--tables", default="1,2,3", help="data sets: 1 grid 0%%, 2 grid 10%%, 3 NGSIM")
    p.add_argument("--methods", default=",".join(method_names()))
    p.add_argument("--skip-faithful", action="store_true")
    p.add_argument("--markdown", help="also write the table as Markdown to this file")
    args = p.parse_args(argv)
    print(" | ".join(HEADER))
    rows = run(Path(args.data), args.trials, args.grid_outer, args.ngsim_outer,
               tuple(int(x) for x in args.tables.split(",")), tuple(args.methods.split(",")), args.skip_faithful)
    if args.markdown:
        Path(args.markdown).write_text(markdown(rows, args.trials))
        print(f"wrote {args.markdown}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
