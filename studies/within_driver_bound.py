"""Study: how well does a driver's *own* calibration predict the rest of its trajectory? The
scale against which the 0.8 target for unseen drivers can be read.

    python -m studies.within_driver_bound [--pairs DIR] [--holdout 0.3] [--seeds 0 1 2]
        [--fraction 0.5] [--classes 3] [--model idm]

For each split (``split_by_follower(pairs, holdout, seed)``) every held-out pair is cut in time
(``pairs.split_in_time(pair, fraction)``: the first part, and the rest starting from the recorded
state where the first part ends). Every row is scored on the same steps, the rest of the held-out
pairs, as median / mean spacing RMSE over pairs, each a ratio to SUMO's defaults on those steps
(the same replica):

* ``population``: the product's population fit on the *training* followers (``log`` objective),
  the calibration meant to generalise to unseen drivers;
* ``classes``: one population vector per class of the initial time headway (``--classes``),
  the class read at the start of the rest;
* ``own, 5 parameters``: each held-out driver's own fit (``fit.fit_per_pair``, the five
  ``fit.FITTED``) on its first part, started from the population: within-driver validation, the
  usual calibration/validation protocol of the car-following literature;
* ``own, tau + minGap``: the same with only ``tau`` and ``minGap`` fitted, the others the
  population's (fewer parameters over-fit the first part less);
* ``own fit on the rest``: each driver's own fit on the scored steps themselves, an in-sample
  figure, not a prediction (how far a perfect identification of the driver could go).

A calibration from other drivers cannot be expected to beat a driver's own calibration on that
driver's earlier data; where the own-fit rows sit near 0.8, the target is at the level the
data and model allow. Figures are printed, not asserted. Cost: about 40-50 s per split on 2 cores.
"""

from __future__ import annotations

import argparse
import time
import warnings
from collections.abc import Sequence

import numpy as np

from analysis.calibration import (
    SUMO_DEFAULTS,
    CarFollowingPair,
    CFParams,
    PairBatch,
    fit_classes,
    fit_per_pair,
    fit_population,
    load_pairs,
    split_by_follower,
    split_in_time,
)
from analysis.calibration.objective import spacing_rmse
from analysis.calibration.pairs import DuplicatePairWarning
from scenarios.errors import SpecError
from studies.heldout_args import add_split_arguments

ROWS = ("population", "classes", "own, 5 parameters", "own, tau + minGap", "own fit on the rest")


def rmse_each(pairs: Sequence[CarFollowingPair], params: Sequence[CFParams], model: str) -> np.ndarray:
    """float64[P]: spacing RMSE (m) of pair i simulated with ``params[i]``, in the order of ``pairs``."""
    batch = PairBatch.from_pairs(pairs)
    names = params[0].as_dict().keys()
    per_row = {n: np.array([params[int(i)].as_dict()[n] for i in batch.order]) for n in names}
    return batch.unsort(spacing_rmse(model, batch, per_row))


def split_ratios(train: Sequence[CarFollowingPair], test: Sequence[CarFollowingPair], fraction: float,
                 n_classes: int, model: str) -> dict[str, tuple[float, float]]:
    """Row name (:data:`ROWS`) -> (median ratio, mean ratio) to SUMO's defaults on the rest of the held-out pairs."""
    pop, _ = fit_population(train, model=model)
    classes = fit_classes(train, n_classes, model=model)
    parts = [split_in_time(p, fraction) for p in test]
    first = [a for a, _ in parts]
    rest = [b for _, b in parts]
    default = rmse_each(rest, [SUMO_DEFAULTS] * len(rest), model)
    chosen = {
        "population": [pop] * len(rest),
        "classes": classes.params_for(rest),
        "own, 5 parameters": [f.params for f in fit_per_pair(first, pop, model=model)],
        "own, tau + minGap": [f.params for f in fit_per_pair(first, pop, model=model, fitted=("tau", "minGap"))],
        "own fit on the rest": [f.params for f in fit_per_pair(rest, pop, model=model)],
    }
    out = {}
    for row, params in chosen.items():
        r = rmse_each(rest, params, model)
        out[row] = (float(np.median(r) / np.median(default)), float(np.mean(r) / np.mean(default)))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_split_arguments(ap)
    ap.add_argument("--fraction", type=float, default=0.5, help="share of each held-out pair used to fit it")
    ap.add_argument("--classes", type=int, default=3, help="driver classes of the classes row (default 3)")
    ap.add_argument("--model", default="idm", choices=("idm", "krauss"))
    args = ap.parse_args()
    if not 0.0 < args.fraction < 1.0 or not 0.0 < args.holdout < 1.0:
        ap.error(f"--fraction and --holdout must be in (0, 1), got {args.fraction} and {args.holdout}")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", DuplicatePairWarning)
        try:
            pairs = load_pairs(args.pairs)
        except (FileNotFoundError, SpecError) as e:
            ap.error(str(e))
    if caught:
        print(f"note: {caught[0].message}".split(" (")[0] + " (kept, as in docs/calibration.md)")
    print(f"{args.model}, held-out followers, scored on the last {1 - args.fraction:.0%} of each pair; "
          "median / mean spacing RMSE as ratios to SUMO's defaults on the same steps")
    print("| split | " + " | ".join(ROWS) + " | seconds |")
    print("|---|" + "---:|" * (len(ROWS) + 1))
    for seed in args.seeds:
        train, test = split_by_follower(pairs, args.holdout, seed=seed)
        t0 = time.perf_counter()
        try:
            ratios = split_ratios(train, test, args.fraction, args.classes, args.model)
        except SpecError as e:  # a pair too short to cut, too few pairs for the classes
            ap.error(f"split {seed}: {e}")
        cells = " | ".join(f"{ratios[r][0]:.3f} / {ratios[r][1]:.3f}" for r in ROWS)
        print(f"| {seed} | {cells} | {time.perf_counter() - t0:.0f} |", flush=True)


if __name__ == "__main__":
    main()
