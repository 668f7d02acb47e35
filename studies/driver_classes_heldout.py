"""Study: one population vector per driver class, the class read from the pair's initial time
headway. Does it bring held-out drivers nearer the 0.8 target for unseen drivers than one vector for all?

    python -m studies.driver_classes_heldout [--pairs DIR] [--holdout 0.3] [--seeds 0 1 2]
        [--classes 1 3 5] [--model idm]

For each split (``split_by_follower(pairs, holdout, seed)``, never the same driver on both sides)
and each number of classes C, the training pairs are cut into C equally filled classes by the
follower's time headway at the pair's first step (recorded gap / recorded speed, s; the edges
are the training quantiles), the product's population fit (``fit.fit_population``, default
``log`` objective) is run on each class, and every held-out pair is simulated with the vector
of its own class. The class uses only what the evaluation already gives the simulation (the
pair's recorded initial gap and speed), nothing of the held-out driver's later behaviour.
C = 1 is today's calibration. Prints, per split and C, the held-out median and mean spacing RMSE
as ratios to SUMO's defaults (the same replica). Figures are printed, not asserted. Cost: C
population fits per row (about 20-40 s each on 2 cores).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from analysis.calibration import CarFollowingPair, PairBatch, load_pairs, split_by_follower
from analysis.calibration.fit import fit_population
from analysis.calibration.models import SUMO_DEFAULTS, CFParams
from analysis.calibration.objective import spacing_rmse
from studies.heldout_args import add_split_arguments


def initial_time_headway(pair: CarFollowingPair) -> float:
    """The follower's time headway (s) at the pair's first step: bumper gap / speed (speed >= 0.5 m/s)."""
    return float(pair.spacing[0] / max(float(pair.v_follower[0]), 0.5))


def rmse(pairs: list[CarFollowingPair], params: CFParams, model: str) -> np.ndarray:
    """float64[P]: per-pair spacing RMSE (m) of ``params``, in the order given."""
    batch = PairBatch.from_pairs(pairs)
    return batch.unsort(spacing_rmse(model, batch, params.as_dict()))


def class_ratios(train: list[CarFollowingPair], test: list[CarFollowingPair], n_classes: int,
                 model: str) -> tuple[float, float]:
    """(median ratio, mean ratio) of the held-out RMSEs to SUMO's defaults, one vector per class."""
    edges = np.quantile([initial_time_headway(p) for p in train], np.linspace(0, 1, n_classes + 1)[1:-1])
    of = [int(np.searchsorted(edges, initial_time_headway(p))) for p in test]
    r = np.empty(len(test))
    for c in range(n_classes):
        members = [i for i, k in enumerate(of) if k == c]
        if not members:
            continue
        params, _ = fit_population([p for p in train if int(np.searchsorted(edges, initial_time_headway(p))) == c],
                                   model=model)
        r[members] = rmse([test[i] for i in members], params, model)
    d = rmse(test, SUMO_DEFAULTS, model)
    return float(np.median(r) / np.median(d)), float(np.mean(r) / np.mean(d))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_split_arguments(ap)
    ap.add_argument("--classes", type=int, nargs="+", default=[1, 3, 5], help="numbers of classes, one row each")
    ap.add_argument("--model", default="idm", choices=("idm", "krauss"))
    args = ap.parse_args()
    pairs = load_pairs(args.pairs)
    print("| split | classes | held-out median ratio | mean ratio | seconds |")
    print("|---|---:|---:|---:|---:|")
    for seed in args.seeds:
        train, test = split_by_follower(pairs, args.holdout, seed=seed)
        for c in args.classes:
            t0 = time.perf_counter()
            med, mean = class_ratios(list(train), list(test), c, args.model)
            print(f"| {seed} | {c} | {med:.3f} | {mean:.3f} | {time.perf_counter() - t0:.0f} |", flush=True)


if __name__ == "__main__":
    main()
