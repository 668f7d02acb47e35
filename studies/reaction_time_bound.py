"""Study: does a driver reaction time (SUMO's ``actionStepLength``) let one population vector
reach the 0.8 target on held-out drivers? An in-sample upper bound.

    python -m studies.reaction_time_bound [--pairs DIR] [--holdout 0.3] [--seed 0]
        [--model idm] [--steps 1 3 5 10 15] [--objective median both] [--maxiter 100] [--popsize 12]
        [--tables bound fit] [--fit-seeds 0 1 2]

For every action step k (decisions every k x 0.1 s, the acceleration held in between: SUMO's
vType ``actionStepLength``, which ``models.simulate_follower(..., action_steps=k)`` replicates
exactly, ``tests/test_calibration_replica.py``) and every objective, finds the vector of the five
fitted parameters (``fit.FITTED`` within ``fit.BOUNDS``) that minimises the objective *on the
held-out pairs themselves* (``scipy.optimize.differential_evolution``, seed 0, all ``--maxiter``
generations run, vectorised: one replica simulation scores a generation). No fit on other
drivers can beat it, so it bounds what a calibration with that action step could reach.
Objectives, over the held-out pairs' spacing RMSEs, each relative to SUMO's defaults (action step
0.1 s, the same replica): ``median`` (the median ratio), ``mean``, ``both`` (the larger of the
two ratios: the target needs both <= 0.8).

Prints one row per (objective, action step): the median and mean ratios of the optimum and its
parameters. Then (table ``fit``) what a calibration with that action step gives: the population
fit of the product (``fit.fit_population``, default ``log`` objective) on the *training*
followers of each split ``--fit-seeds`` with the action step, scored on that split's held-out
followers with the same action step, beside SUMO's defaults (0.1 s). Figures are printed, not asserted. Differential evolution finds a good optimum, not a
certified global one (40 instead of 100 generations changed the ratios by up to 0.01). Cost: 101
simulations of 60 candidates x the 93 held-out pairs per row (0.5-1 min per row on 2 cores).
"""

from __future__ import annotations

import argparse
import os
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from scipy.optimize import differential_evolution

from analysis.calibration import BOUNDS, FITTED, CarFollowingPair, PairBatch, load_pairs, split_by_follower
from analysis.calibration.fit import fit_population
from analysis.calibration.models import DT, SUMO_DEFAULTS
from analysis.calibration.objective import spacing_rmse

TARGET_RATIO = 0.8


def bound(batch: PairBatch, model: str, action_steps: int, objective: str, *, maxiter: int, popsize: int,
          default_rmse: np.ndarray) -> tuple[np.ndarray, float, float]:
    """(optimal parameters float64[K] in ``FITTED`` order, its median ratio, its mean ratio).

    ``default_rmse``: float64[P] per-pair RMSE (m) under SUMO's defaults, batch order.
    """
    d_med, d_mean = float(np.median(default_rmse)), float(np.mean(default_rmse))
    base = SUMO_DEFAULTS.as_dict()

    def ratios(z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """z float64[K, S] candidate vectors -> (median ratio float64[S], mean ratio float64[S])."""
        r = spacing_rmse(model, batch, {**base, **{f: z[k] for k, f in enumerate(FITTED)}},
                         candidates=True, action_steps=action_steps)  # [P, S]
        return np.median(r, axis=0) / d_med, np.mean(r, axis=0) / d_mean

    def cost(z: np.ndarray) -> np.ndarray:
        med, mean = ratios(z)
        return {"median": med, "mean": mean, "both": np.maximum(med, mean)}[objective]

    sol = differential_evolution(cost, [BOUNDS[f] for f in FITTED], vectorized=True, seed=0, maxiter=maxiter,
                                 popsize=popsize, tol=0.0, polish=False, updating="deferred")  # all generations
    med, mean = ratios(sol.x[:, None])
    return sol.x, float(med[0]), float(mean[0])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--pairs", default=str(Path(os.environ.get("MERGE_IRL_SHARED", "/work/shared"))
                                          / "data" / "ngsim_i80_car_following"))
    ap.add_argument("--holdout", type=float, default=0.3)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--model", choices=["idm", "krauss"], default="idm")
    ap.add_argument("--steps", type=int, nargs="+", default=[1, 3, 5, 10, 15],
                    help="action steps in 0.1 s steps (1 = SUMO's default, a decision every step)")
    ap.add_argument("--objective", nargs="+", choices=["median", "mean", "both"], default=["median", "both"])
    ap.add_argument("--maxiter", type=int, default=100, help="differential evolution generations")
    ap.add_argument("--popsize", type=int, default=12, help="differential evolution population per parameter")
    ap.add_argument("--tables", nargs="+", choices=["bound", "fit"], default=["bound", "fit"])
    ap.add_argument("--fit-seeds", type=int, nargs="+", default=[0, 1, 2], help="splits of the table 'fit'")
    a = ap.parse_args()
    pairs = load_pairs(a.pairs)
    if "bound" in a.tables:
        print_bound(pairs, a)
    if "fit" in a.tables:
        print_fit(pairs, a)


def print_fit(pairs: Sequence[CarFollowingPair], a: argparse.Namespace) -> None:
    """Population fit on the training followers with each action step, scored on the held-out ones."""
    print(f"\n{a.model}: population fit on the training followers, held-out ratios to SUMO's defaults")
    print("| split seed | actionStepLength | median ratio | mean ratio | " + " | ".join(FITTED) + " | seconds |")
    print("|---:|---:|---:|---:|" + "---:|" * len(FITTED) + "---:|")
    for seed in a.fit_seeds:
        train, test = split_by_follower(pairs, a.holdout, seed=seed)
        batch = PairBatch.from_pairs(test)
        d = spacing_rmse(a.model, batch, SUMO_DEFAULTS.as_dict())
        for k in a.steps:
            t0 = time.perf_counter()
            pop, _ = fit_population(train, model=a.model, action_steps=k)
            r = spacing_rmse(a.model, batch, pop.as_dict(), action_steps=k)
            print(f"| {seed} | {k * DT:.1f} s | {np.median(r) / np.median(d):.3f} | {np.mean(r) / np.mean(d):.3f} | "
                  + " | ".join(f"{getattr(pop, f):.2f}" for f in FITTED) + f" | {time.perf_counter() - t0:.0f} |",
                  flush=True)


def print_bound(pairs: Sequence[CarFollowingPair], a: argparse.Namespace) -> None:
    """The in-sample bound on the held-out pairs of split ``a.seed``, per objective and action step."""
    _, test = split_by_follower(pairs, a.holdout, seed=a.seed)
    batch = PairBatch.from_pairs(test)
    default_rmse = spacing_rmse(a.model, batch, SUMO_DEFAULTS.as_dict())
    print(f"{a.model}, {len(test)} held-out pairs (holdout {a.holdout}, seed {a.seed}); SUMO defaults: median "
          f"{np.median(default_rmse):.2f} m, mean {np.mean(default_rmse):.2f} m; target both ratios <= {TARGET_RATIO}")
    print(f"| objective | actionStepLength | median ratio | mean ratio | {' | '.join(FITTED)} | seconds |")
    print("|---|---:|---:|---:|" + "---:|" * len(FITTED) + "---:|")
    for objective in a.objective:
        for k in a.steps:
            t0 = time.perf_counter()
            x, med, mean = bound(batch, a.model, k, objective, maxiter=a.maxiter, popsize=a.popsize,
                                 default_rmse=default_rmse)
            print(f"| {objective} | {k * DT:.1f} s | {med:.3f} | {mean:.3f} | "
                  + " | ".join(f"{v:.2f}" for v in x) + f" | {time.perf_counter() - t0:.0f} |", flush=True)


if __name__ == "__main__":
    main()
