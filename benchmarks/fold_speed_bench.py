"""Per-fold time of a Boltzmann-backup fit (MLIRL or Q-SM) on the authors' NGSIM data, before
and after a code change, side by side in one run (the target: MLIRL and Q-SM fast
enough at the driver encoding's 6250 states). Prints figures and ratios; not a timed test.

    python benchmarks/fold_speed_bench.py /work/shared/data/railusm/merge_ngsim \\
        [--base main] [--method mlirl|qsm] [--gamma 0.9] [--folds 0,5] [--paper-check]

``--base`` is a git revision of this repository: its tree is exported (``git archive``) to a
temporary folder and each "before" fit runs in a fresh process with that folder first on
``PYTHONPATH``; each "after" fit runs in a fresh process on this checkout. A fold leaves out
one trajectory, fits on the other 11 with the driver features and encoding (beta 1, l2 0.01,
seed 0, Q-SM with the kinematic rule for unobserved pairs) and scores the held-out one (no
rule for unvisited states), as ``studies/driver_loo.py`` does. ``--paper-check`` adds the
paper features' fit on all 12 trajectories at gamma 0.99, whose optimum is well defined: both
versions must reach the same log-likelihood (the driver folds end where L-BFGS stops on a
likelihood with jumps between branches of fixed points, so their end points may differ with
round-off; the table shows by how much).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent


def worker(data: str, method: str, gamma: float, fold: int, encoding: str) -> dict:
    """One fit in this process (imports whichever code is first on ``sys.path``): fold ``fold``
    held out (``-1``: fit on every trajectory). Returns the figures as a dict."""
    from dataclasses import replace

    from analysis.experiments.learn import fit_problem
    from irl.config import IRLConfig
    from irl.problems import load_problem

    problem = load_problem("merge", data, encoding=encoding, features=encoding)
    if method == "qsm":
        problem = replace(problem, transitions_estimated=False)
    n = problem.demos.n_trajectories
    train = [i for i in range(n) if i != fold]
    sub = problem.subset(train)
    cfg = replace(IRLConfig.paper(beta=1.0, l2=0.01, unobserved="kinematic" if method == "qsm" else "terminal"),
                  gamma=gamma)
    start, cpu = time.perf_counter(), time.process_time()
    fit = fit_problem(sub, method, cfg, 0)
    seconds, cpu = time.perf_counter() - start, time.process_time() - cpu
    held = float("nan")
    if fold >= 0:
        z = cfg.beta * fit.q
        z = z - z.max(axis=1, keepdims=True)
        lp = z - np.log(np.exp(z).sum(axis=1, keepdims=True))
        held = float(lp[problem.demos.states[fold], problem.demos.actions[fold]].sum())
    return {"seconds": seconds, "cpu_seconds": cpu, "train_ll": float(fit.loglik), "heldout_ll": held,
            "evaluations": float(fit.extra.get("evaluations", float("nan"))),
            "branch_jumps": float(fit.extra.get("branch_jumps", float("nan"))),
            "flags": ",".join(fit.flags) or "ok", "theta": [float(x) for x in fit.theta]}


def _run(pythonpath: str, args: list[str]) -> dict:
    env = dict(os.environ, PYTHONPATH=pythonpath)
    out = subprocess.run([sys.executable, __file__, "--worker", *args], env=env, capture_output=True,
                         text=True, check=False)
    if out.returncode != 0:
        raise RuntimeError(f"worker failed ({out.returncode}): {out.stderr.strip().splitlines()[-1:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def _export(rev: str, into: str) -> None:
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", rev], capture_output=True, check=True).stdout
    tar_path = Path(into) / "base.tar"
    tar_path.write_bytes(archive)
    with tarfile.open(tar_path) as tar:
        tar.extractall(into, filter="data")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("data")
    p.add_argument("--base", default="main", help="git revision of the 'before' code")
    p.add_argument("--method", default="mlirl", choices=("mlirl", "qsm"))
    p.add_argument("--gamma", type=float, default=0.9)
    p.add_argument("--folds", default="0", help="held-out trajectories, comma-separated")
    p.add_argument("--paper-check", action="store_true",
                   help="also fit the paper features on all trajectories at gamma 0.99, before and after")
    p.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    p.add_argument("--fold", type=int, default=0, help=argparse.SUPPRESS)
    p.add_argument("--encoding", default="driver", help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.worker:
        print(json.dumps(worker(args.data, args.method, args.gamma, args.fold, args.encoding)))
        return 0
    base_rev = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", args.base], capture_output=True,
                              text=True, check=True).stdout.strip()
    head_rev = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True,
                              text=True, check=True).stdout.strip()
    cases = [(int(f), "driver", args.gamma) for f in args.folds.split(",") if f]
    if args.paper_check:
        cases.append((-1, "paper", 0.99))
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        _export(args.base, tmp)
        for fold, enc, gamma in cases:
            common = [args.data, "--method", args.method, "--gamma", str(gamma), "--fold", str(fold),
                      "--encoding", enc]
            before = _run(tmp, common)
            after = _run(str(ROOT), common)
            label = f"{enc} fold {fold}" if fold >= 0 else f"{enc} all 12"
            print(f"  {label} gamma {gamma:g}: before {before['seconds']:.1f} s ({before['cpu_seconds']:.1f} s CPU), "
                  f"after {after['seconds']:.1f} s ({after['cpu_seconds']:.1f} s CPU)", flush=True)
            rows.append((label, gamma, before, after))
    print(f"\n{args.method}: before = {args.base} ({base_rev}), after = HEAD ({head_rev}); beta 1, l2 0.01, seed 0")
    print("times: wall-clock seconds of the fit (CPU seconds of its process); ratio = before / after, of the CPU times")
    print(f"{'case':16s}{'gamma':>6s}{'before s':>16s}{'after s':>15s}{'ratio':>7s}"
          f"{'train LL before':>17s}{'after':>11s}{'held-out before':>17s}{'after':>10s}"
          f"{'evals':>12s}{'jumps':>10s}  flags before / after")
    for label, gamma, b, a in rows:
        print(f"{label:16s}{gamma:6g}{b['seconds']:8.1f} ({b['cpu_seconds']:5.1f}){a['seconds']:7.1f} ({a['cpu_seconds']:5.1f})"
              f"{b['cpu_seconds'] / a['cpu_seconds']:7.1f}"
              f"{b['train_ll']:17.3f}{a['train_ll']:11.3f}{b['heldout_ll']:17.2f}{a['heldout_ll']:10.2f}"
              f"{b['evaluations']:6.0f}/{a['evaluations']:<5.0f}{b['branch_jumps']:5.0f}/{a['branch_jumps']:<4.0f}"
              f"  {b['flags']} / {a['flags']}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
