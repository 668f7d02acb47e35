"""Leave-one-trajectory-out log-likelihood of the baselines and the IRL methods, fold by fold.

One evaluation for all (:func:`irl.baselines.leave_one_out`): fold ``i`` fits on every
trajectory but ``i`` and scores trajectory ``i``. The per-fold values pair up across methods (the
same held-out trajectory), so :func:`irl.baselines.paired_test` can compare two of them.

Run as a script to print the table of a reproduction data set::

    python -m analysis.experiments.leave_one_out /path/to/railusm --table 3 [--gamma 0.99] [--methods ...]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from analysis.experiments.learn import fit_problem
from analysis.experiments.trials import table_problem
from irl.baselines import TABULAR_BASELINES, TabularPolicy, baseline_leave_one_out, leave_one_out, paired_test
from irl.config import IRLConfig
from irl.methods.reirl import DEFAULT_EPSILON
from irl.problems import Problem


def method_leave_one_out(problem: Problem, method: str, config: IRLConfig, seed: int = 0,
                         epsilon: float | None = DEFAULT_EPSILON) -> np.ndarray:
    """``[n_trajectories]`` held-out log-likelihood of each trajectory (nats) under ``method`` (a
    baseline of ``irl.baselines.TABULAR_BASELINES`` or an IRL method) fitted on the others; IRL fits use
    ``numpy.random.default_rng(seed)`` and ``problem.subset`` (its model re-estimated per fold)."""
    if method in TABULAR_BASELINES:
        return baseline_leave_one_out(method, problem.demos)

    def fit_fold(train: np.ndarray) -> TabularPolicy:
        fit = fit_problem(problem.subset(train), method, config, seed, epsilon=epsilon)
        return TabularPolicy(method, fit.log_policy())

    return leave_one_out(problem.demos, fit_fold)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m analysis.experiments.leave_one_out", description=__doc__.splitlines()[0])
    p.add_argument("data", help="the authors' data directory (railusm layout)")
    p.add_argument("--table", type=int, choices=(1, 2, 3), default=3)
    p.add_argument("--gamma", type=float, default=0.99)
    p.add_argument("--methods", default="uniform,marginal,markov,bc,mlirl,qavg,qsm,reirl")
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)
    problem = table_problem(args.table, args.data)
    config = IRLConfig.paper(gamma=args.gamma)
    folds = {}
    print(f"table {args.table}, {problem.demos.n_trajectories} trajectories, {problem.demos.n_steps} steps, "
          f"gamma {args.gamma}: leave-one-trajectory-out log-likelihood (sum over folds)")
    for m in args.methods.split(","):
        t = time.perf_counter()
        folds[m] = method_leave_one_out(problem, m, config, args.seed)
        p_vs = paired_test(folds[m], folds["marginal"]) if "marginal" in folds and m != "marginal" else float("nan")
        print(f"{m:10s} {folds[m].sum():10.1f}   per step {folds[m].sum() / problem.demos.n_steps:7.3f}   "
              f"p vs marginal (paired folds) {p_vs:.3g}   {time.perf_counter() - t:6.1f} s", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
