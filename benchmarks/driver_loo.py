"""Leave-one-trajectory-out log-likelihood on the authors' NGSIM merge data, paper vs driver
features, beside the baselines (issue 11 target: the best method beats ``marginal`` by >= 300
nats with ``--features driver``). Prints a table; not a timed test.

    python benchmarks/driver_loo.py /work/shared/data/railusm/merge_ngsim \
        [--gamma 0.99] [--l2 0.01] [--methods qavg,qsm,mlirl,reirl] [--unvisited none,nearest]

The authors' files hold state indices only: features are computed on the bin representatives
of ``MergeBins.assumed_authors()``; the driver encoding takes A's previous action from the
sequence (Zero at a trajectory's first step). Fits use beta 1 (beta is not identifiable).
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace

import numpy as np

from analysis.learn import fit_problem
from irl.baselines import (
    BASELINES,
    TabularPolicy,
    baseline_leave_one_out,
    leave_one_out,
)
from irl.config import IRLConfig
from irl.problems import load_problem
from irl.unvisited import apply_unvisited_rule, visited_states


def method_loo(problem, method: str, config: IRLConfig, unvisited: str, seed: int = 0) -> np.ndarray:
    """``[n_trajectories]`` held-out log-likelihoods of ``method`` with the ``unvisited`` rule."""
    if method in ("qavg", "qsm"):  # model-free: the transition model is not used, do not re-estimate it per fold
        problem = replace(problem, transitions_estimated=False)

    def fold(train):
        start = time.perf_counter()
        sub = problem.subset(train)
        fit = fit_problem(sub, method, config, seed)
        q = apply_unvisited_rule(fit.q, visited_states(sub.demos), unvisited)
        policy = TabularPolicy(method, _log_softmax(q, config.beta))
        held = np.setdiff1d(np.arange(problem.demos.n_trajectories), train)
        ll = policy.trajectory_logliks(problem.demos.subset(held))[0]
        flags = ",".join(fit.flags) or "ok"
        print(f"    fold {int(held[0]):2d}: held-out LL {ll:9.1f}  {time.perf_counter() - start:6.1f} s  {flags}",
              flush=True)
        return policy

    return leave_one_out(problem.demos, fold)


def _log_softmax(q: np.ndarray, beta: float) -> np.ndarray:
    z = beta * q
    z = z - z.max(axis=1, keepdims=True)
    return z - np.log(np.exp(z).sum(axis=1, keepdims=True))


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("data")
    p.add_argument("--gamma", type=float, default=0.99)
    p.add_argument("--l2", type=float, default=0.01)
    p.add_argument("--methods", default="qavg,qsm,mlirl,reirl")
    p.add_argument("--features", default="paper,driver")
    p.add_argument("--unvisited", default="none,nearest")
    p.add_argument("--driver-methods", default="qavg,qsm",
                   help="methods run with the driver features (MLIRL and REIRL use the sparse [6250, 5, 6250] "
                        "model; MLIRL takes minutes per fold there: add them here to run them)")
    args = p.parse_args(argv)
    config = IRLConfig.paper(beta=1.0, gamma=args.gamma, l2=args.l2)
    rows: dict[str, dict[str, float]] = {}
    for fs in args.features.split(","):
        enc = "driver" if fs == "driver" else "paper"
        problem = load_problem("merge", args.data, encoding=enc, features=fs)
        for b in BASELINES:
            rows.setdefault(b, {})[fs] = baseline_leave_one_out(b, problem.demos).sum()
        methods = [m for m in args.methods.split(",") if fs != "driver" or m in args.driver_methods.split(",")]
        for m in methods:
            for rule in args.unvisited.split(","):
                t = time.perf_counter()
                try:
                    v = method_loo(problem, m, config, rule).sum()
                except Exception as e:  # a failing method is a row of the table, not the end of it
                    print(f"  {m} {fs} {rule}: failed ({type(e).__name__}: {e})", flush=True)
                    v = float("nan")
                rows.setdefault(f"{m} ({rule})", {})[fs] = v
                print(f"  {m:6s} {fs:7s} unvisited={rule:8s} {v:10.1f}  {time.perf_counter() - t:6.1f} s", flush=True)
    feats = args.features.split(",")
    marginal = rows["marginal"]
    print(f"\nLOO log-likelihood (nats, sum over 12 held-out trajectories), gamma {args.gamma}, beta 1, l2 {args.l2}")
    print(f"{'method':20s}" + "".join(f"{f:>12s} {'vs marg.':>10s}" for f in feats))
    for name, r in rows.items():
        print(f"{name:20s}" + "".join(f"{r[f]:12.1f} {r[f] - marginal[f]:+10.1f}" if f in r else f"{'not run':>23s}"
                                      for f in feats))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
