"""Study: the planning driver's held-out likelihood beside a history-free ceiling (the
likelihood scored fairly).

Per decision (nats; the paper's 5 action bins of 0.3 s decisions) on the held-out groups of a
split by group (seed ``--seed``, fraction ``--holdout``), it prints the log-likelihood of:

* each planning driver file (``--driver``, repeatable): ``PlanningDriver.heldout_ll_per_decision``;
* the **history-free ceiling**: scikit-learn's ``HistGradientBoostingClassifier`` on the
  observation the driver sees (``obs``: d_AC, v_AC, d_AB, v_AB, v_A, len_C, len_B, NaN where
  absent; and ``acc_C``, the lead car's acceleration as brake lights), no previous action; one
  of :data:`SETTINGS` chosen by ``GroupKFold`` (``--folds``) on the training groups only
  (pooled validation LL), refitted on all training decisions
  (:func:`studies.support.ceiling.fit_ceiling`);
* the **previous-bin Markov** model ``P(b | bin of prev_acc)`` (Laplace 1; unknown previous:
  the marginal). It sees history, so it is *not* a like-for-like comparison with the
  history-free models (the ceiling, and a driver without ``jerk`` or an actuation lag);
* the marginal (Laplace 1) and uniform (``log 1/5``).

Targets: "driver >= ceiling - 0.15 nats", one line per driver.

Data:

* ``--data pairs --pairs DIR``: real car-following pairs (``analysis.calibration.pairs``),
  split by follower with ``split_by_follower(pairs, holdout, seed)``: the split of
  ``merge-irl calibrate fit --holdout 0.3 --seed 0`` and ``merge-irl learn-driver --fit replay
  --holdout 0.3 --seed 0``;
* ``--data synthetic --encounters FILE [FILE ...]``: encounter tables (``merge-irl generate``'s
  ``encounters.parquet``), split by encounter run with ``split_groups(groups, holdout, seed)``.
  ``--write-train DIR`` writes each table's training rows to ``DIR/train-<i>.parquet``, for
  ``merge-irl learn-driver --demos DIR/train-1.parquet ...`` (a driver that never saw the test
  groups).

Run from the repository root (the ``studies`` extra: scikit-learn), e.g.::

    OMP_NUM_THREADS=1 python -m studies.likelihood_ceiling --data pairs \\
        --pairs ../shared/data/ngsim_i80_car_following --driver replay_driver.json --json ceiling-pairs.json
    OMP_NUM_THREADS=1 python -m studies.likelihood_ceiling --data synthetic \\
        --encounters synth/seed1/encounters.parquet synth/seed2/encounters.parquet --driver synthetic.json
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from analysis.calibration.pairs import load_pairs, split_by_follower
from analysis.experiments.learn_driver import pair_frames
from irl.domains.merge.bins import MergeBins
from irl.domains.merge.mdp import DEFAULT_DECISION_STEP_S, encounter_runs, read_encounters, resample_encounters
from irl.planning.decisions import PlanningDecisions, encounter_decisions, pair_decisions, split_groups
from irl.planning.driver import PlanningDriver
from studies.heldout_args import DEFAULT_PAIRS
from studies.support.ceiling import Marginal, PreviousBinMarkov, fit_ceiling

#: The gradient-boosting settings tried by grouped cross-validation (no early stopping: its
#: internal validation split is not by group).
SETTINGS: tuple[dict[str, Any], ...] = (
    {"learning_rate": 0.05, "max_iter": 50, "max_leaf_nodes": 4, "min_samples_leaf": 100},
    {"learning_rate": 0.05, "max_iter": 100, "max_leaf_nodes": 7, "min_samples_leaf": 100, "l2_regularization": 1.0},
    {"learning_rate": 0.05, "max_iter": 150, "max_leaf_nodes": 7, "min_samples_leaf": 100},
    {"learning_rate": 0.05, "max_iter": 300, "max_leaf_nodes": 7, "min_samples_leaf": 200, "l2_regularization": 1.0},
    {"learning_rate": 0.1, "max_iter": 100, "max_leaf_nodes": 15, "min_samples_leaf": 50},
    {"learning_rate": 0.05, "max_iter": 300, "max_leaf_nodes": 15, "min_samples_leaf": 50},
    {"learning_rate": 0.05, "max_iter": 300, "max_leaf_nodes": 31, "min_samples_leaf": 200, "l2_regularization": 1.0},
    {"learning_rate": 0.1, "max_iter": 300, "max_leaf_nodes": 31, "min_samples_leaf": 20},
)
#: How far below the ceiling a driver may be (nats per decision).
TARGET_GAP = 0.15


def log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def hist_gb(setting: dict[str, Any]) -> Any:
    from sklearn.ensemble import HistGradientBoostingClassifier

    return HistGradientBoostingClassifier(**setting, early_stopping=False, random_state=0)


def pairs_split(directory: Path, holdout: float, seed: int) -> tuple[PlanningDecisions, PlanningDecisions, str]:
    """(train, test) decisions of the pairs under ``directory``, split by follower."""
    pairs = load_pairs(directory)
    train, test = split_by_follower(pairs, holdout, seed)
    out = []
    for part in (train, test):
        frames, groups = pair_frames(part)
        out.append(pair_decisions(frames, DEFAULT_DECISION_STEP_S, groups=groups, where=str(directory)))
    n_f = (len({p.group for p in train}), len({p.group for p in test}))
    return out[0], out[1], (f"{directory}: {len(train)} training pairs of {n_f[0]} followers, {len(test)} held-out "
                            f"pairs of {n_f[1]} followers")


def decision_runs(df: pd.DataFrame) -> np.ndarray:
    """The encounter run (``encounter_runs(df).run``) of each of ``df``'s groups, in the order of
    ``encounter_decisions(df).groups`` (its codes: the sorted runs that hold a decision)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rows = resample_encounters(df, MergeBins.assumed_authors(), encoding="driver",
                                   decision_step_s=DEFAULT_DECISION_STEP_S).rows
    return np.unique(encounter_runs(df).run[rows])


def synthetic_split(paths: list[Path], holdout: float, seed: int,
                    write_train: Path | None) -> tuple[PlanningDecisions, PlanningDecisions, str]:
    """(train, test) decisions of the encounter tables, split by encounter run; with
    ``write_train``, each table's training runs written there (checked to give the training
    decisions again)."""
    tables = [read_encounters(p) for p in paths]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        parts = [encounter_decisions(df, DEFAULT_DECISION_STEP_S, where=str(p)) for df, p in zip(tables, paths)]
    d = PlanningDecisions.concat(parts)
    tr, te = split_groups(d.groups, holdout, seed)
    train, test = d.take(tr), d.take(te)
    if write_train is not None:
        write_train.mkdir(parents=True, exist_ok=True)
        train_groups, off, written = set(np.unique(train.groups).tolist()), 0, []
        for i, (df, part) in enumerate(zip(tables, parts), start=1):
            runs = decision_runs(df)
            keep = [runs[g] for g in range(runs.size) if g + off in train_groups]
            off += int(part.groups.max()) + 1 if part.n else 0
            out = write_train / f"train-{i}.parquet"
            df[np.isin(encounter_runs(df).run, keep)].reset_index(drop=True).to_parquet(out)
            written.append(out)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            again = PlanningDecisions.concat([encounter_decisions(read_encounters(p)) for p in written])
        if again.n != train.n or not np.array_equal(np.bincount(again.actions, minlength=5),
                                                    np.bincount(train.actions, minlength=5)):
            raise RuntimeError(f"the training tables written to {write_train} give {again.n} decisions, not {train.n}")
        log(f"wrote the training groups' rows: {' '.join(map(str, written))}")
    n_g = (int(np.unique(train.groups).size), int(np.unique(test.groups).size))
    return train, test, f"{len(paths)} encounter tables: {n_g[0]} training encounter runs, {n_g[1]} held out"


def driver_sees(driver: PlanningDriver) -> str:
    cfg = driver.config
    hist = [x for x, on in (("jerk", cfg.jerk), (f"lag {cfg.lag:g}", cfg.lag < 1.0)) if on]
    return "obs + acc_C" + (f" + prev_acc ({', '.join(hist)}): history" if hist else "")


def _f(x: float, nd: int = 3) -> str:
    return f"{x:+.{nd}f}" if math.isfinite(x) else str(x)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", choices=("pairs", "synthetic"), required=True)
    ap.add_argument("--pairs", type=Path, default=DEFAULT_PAIRS, metavar="DIR",
                    help=f"--data pairs: folder of pair CSVs (default {DEFAULT_PAIRS})")
    ap.add_argument("--encounters", type=Path, nargs="+", default=[], metavar="FILE",
                    help="--data synthetic: encounter tables (merge-irl generate's encounters.parquet)")
    ap.add_argument("--driver", type=Path, action="append", default=[], metavar="DRIVER.json",
                    help="a planning driver file to score (repeatable)")
    ap.add_argument("--holdout", type=float, default=0.3, metavar="FRACTION", help="share of groups held out (0.3)")
    ap.add_argument("--seed", type=int, default=0, help="seed of the split by group (0)")
    ap.add_argument("--folds", type=int, default=5, help="GroupKFold folds of the training groups (5)")
    ap.add_argument("--write-train", type=Path, default=None, metavar="DIR",
                    help="--data synthetic: write each table's training rows to DIR/train-<i>.parquet")
    ap.add_argument("--json", type=Path, default=None, metavar="OUT", help="also write the figures as JSON")
    args = ap.parse_args(argv)
    from sklearn.model_selection import GroupKFold

    t0 = time.perf_counter()
    if args.data == "pairs":
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the folder's byte-identical copies: kept, as calibrate fit keeps them
            train, test, what = pairs_split(args.pairs, args.holdout, args.seed)
    else:
        if not args.encounters:
            ap.error("--data synthetic needs --encounters FILE [FILE ...]")
        train, test, what = synthetic_split(args.encounters, args.holdout, args.seed, args.write_train)
    t_data = time.perf_counter() - t0
    log(f"{what}; {train.n} training decisions, {test.n} held out ({t_data:.1f} s)")

    t1 = time.perf_counter()
    folds = list(GroupKFold(n_splits=args.folds).split(train.obs, train.actions, train.groups))
    ceiling = fit_ceiling(hist_gb, SETTINGS, train, folds, log=log)
    c_ll = ceiling.ll_per_decision(test)
    t_ceiling = time.perf_counter() - t1

    rows: list[dict[str, Any]] = []
    t2 = time.perf_counter()
    for path in args.driver:
        drv = PlanningDriver.load(path)
        if not math.isclose(drv.decision_step_s, test.decision_step_s):
            raise SystemExit(f"{path}: decisions of {drv.decision_step_s} s, the data's are {test.decision_step_s} s")
        rows.append({"model": f"driver {path}", "sees": driver_sees(drv), "ll": drv.heldout_ll_per_decision(test),
                     "driver": str(path)})
    t_drivers = time.perf_counter() - t2
    rows.append({"model": "ceiling: HistGradientBoosting", "sees": "obs + acc_C (no history)", "ll": c_ll})
    rows.append({"model": "previous-bin Markov (Laplace 1)", "sees": "previous action's bin: history, not like-for-like",
                 "ll": PreviousBinMarkov.fit(train).ll_per_decision(test)})
    rows.append({"model": "marginal (Laplace 1)", "sees": "nothing", "ll": Marginal.fit(train.actions).ll_per_decision(test)})
    rows.append({"model": "uniform", "sees": "nothing", "ll": -math.log(5)})
    for r in rows:
        r["vs_ceiling"] = r["ll"] - c_ll

    print(f"\n{args.data}: {what}")
    print(f"{train.n} training / {test.n} held-out decisions of {test.decision_step_s:g} s; split by group, "
          f"seed {args.seed}, held out {args.holdout:g}")
    print(f"\nceiling settings ({args.folds}-fold GroupKFold on the training groups; pooled validation LL):")
    for setting, v in ceiling.cv:
        print(f"  {'*' if setting is ceiling.setting else ' '} {_f(v, 4)}  {setting}")
    print("\n| model | sees | held-out LL per decision | vs ceiling (nats) |")
    print("|---|---|---|---|")
    for r in rows:
        print(f"| {r['model']} | {r['sees']} | {_f(r['ll'])} | {_f(r['vs_ceiling'])} |")
    print()
    targets = []
    for r in rows:
        if "driver" in r:
            ok = r["ll"] >= c_ll - TARGET_GAP
            targets.append({"driver": r["driver"], "met": bool(ok)})
            print(f"driver >= ceiling - {TARGET_GAP} nats: {'met' if ok else 'not met'} ({r['driver']}: "
                  f"{_f(r['ll'])} vs {_f(c_ll - TARGET_GAP)})")
    seconds = {"data": t_data, "ceiling_cv_and_fit": t_ceiling, "drivers": t_drivers, "total": time.perf_counter() - t0}
    print("seconds: " + ", ".join(f"{k} {v:.1f}" for k, v in seconds.items()))
    if args.json is not None:
        out = {"data": args.data, "source": what, "holdout": args.holdout, "seed": args.seed, "folds": args.folds,
               "n_train": train.n, "n_test": test.n, "ceiling_setting": ceiling.setting,
               "ceiling_cv": [{"setting": s, "val_ll": v} for s, v in ceiling.cv], "rows": rows,
               "target_gap": TARGET_GAP, "targets": targets, "seconds": seconds}
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(out, indent=1))
        log(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
