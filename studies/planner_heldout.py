"""Held-out measurements of the planning driver (irl.planning) on synthetic merge
encounters or real NGSIM I-80 car-following pairs.

    OMP_NUM_THREADS=1 python -m studies.planner_heldout --data synthetic --out planner-synthetic.json
    OMP_NUM_THREADS=1 python -m studies.planner_heldout --data pairs --out planner-pairs.json

Split 70/30 by group (encounter run / follower), seed 0. The setting is selected by held-out LL
on an inner 70/30 split of the training groups (learn_planning_driver, seed 1), refitted on the
whole training set and scored on the test set beside uniform, marginal and the car-following
logit (l2 0.1). Bootstrap: 20 resamples of the training groups (seed 0), refitted from the full
fit: the signs of the safety weights. Pairs: held-out replay (most likely fine action every
decision) of the selected driver, of the best setting of each other grid (``--replay-grids``),
and of the cf-logit.
"""

from __future__ import annotations

import argparse
import glob
import json
import math
import sys
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np
import pandas as pd

from analysis.calibration.pairs import duplicate_files, pair_files, read_pair
from irl.domains.merge.actions import actions_of
from irl.domains.merge.car_following import CFDecisions
from irl.domains.merge.cf_logit import CarFollowingLogit
from irl.planning.decisions import PlanningDecisions, encounter_decisions, pair_decisions, split_groups
from irl.planning.driver import learn_planning_driver
from irl.planning.fit import fit_planner
from irl.planning.model import PlannerConfig, path_tensors
from irl.planning.replay import ReplayPair, replay
from merge_irl.units import FT_PER_M

PAIRS_DIR = "/work/shared/data/ngsim_i80_car_following/train"
GEN_DIR = "/work/scratch/gen"


def log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def cf_decisions(d: PlanningDecisions, acc5: tuple[float, ...]) -> CFDecisions:
    prev = np.where(np.isfinite(d.prev_acc), actions_of(np.nan_to_num(d.prev_acc)), -1)
    return CFDecisions(d.obs, prev, d.actions, acc5, d.decision_step_s)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--data", choices=("synthetic", "pairs"), required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--bootstrap", type=int, default=20)
    ap.add_argument("--l2", type=float, default=0.1)
    ap.add_argument("--replay-grids", default="bins,g13,g24")
    args = ap.parse_args()
    t_start = time.perf_counter()
    out: dict = {"data": args.data}
    pairs: list[ReplayPair] = []
    if args.data == "synthetic":
        tables = sorted(glob.glob(f"{GEN_DIR}/*/encounters.parquet"))
        d = PlanningDecisions.concat([encounter_decisions(pd.read_parquet(p), where=p) for p in tables])
    else:
        files = pair_files(PAIRS_DIR)
        copies = {c for c, _ in duplicate_files(files)}
        cps = [read_pair(f) for f in files if f not in copies]  # SI; byte-identical copies dropped
        frames = [pd.DataFrame({"t": p.t, "x_follower": p.x_follower * FT_PER_M, "v_follower": p.v_follower * FT_PER_M,
                                "x_leader": p.x_leader * FT_PER_M, "v_leader": p.v_leader * FT_PER_M,
                                "leader_length": p.leader_length * FT_PER_M}) for p in cps]
        followers = sorted({p.group for p in cps})
        d = pair_decisions(frames, groups=[followers.index(p.group) for p in cps])
        pairs = [ReplayPair(p.name, f.x_follower.to_numpy(), f.v_follower.to_numpy(), f.x_leader.to_numpy(),
                            f.v_leader.to_numpy(), float(f.leader_length.iloc[0])) for p, f in zip(cps, frames)]
        pair_group = np.array([followers.index(p.group) for p in cps])
    tr_m, te_m = split_groups(d.groups, 0.3, seed=0)
    train, test = d.take(tr_m), d.take(te_m)
    out |= {"n_train": train.n, "n_test": test.n, "groups_train": int(np.unique(train.groups).size),
            "groups_test": int(np.unique(test.groups).size)}
    log(f"{args.data}: {train.n} training decisions, {test.n} test")
    acc5 = train.action_acc_ft_s2()
    freq = np.bincount(train.actions, minlength=5) / train.n
    cf = CarFollowingLogit.fit(cf_decisions(train, acc5), l2=args.l2)
    out["baselines"] = {"uniform": -math.log(5), "marginal": float(np.log(freq)[test.actions].mean()),
                        "cf_logit": cf.loglik_of(cf_decisions(test, acc5)) / test.n, "cf_logit_converged": cf.converged}
    log(f"baselines {out['baselines']}")

    drv = learn_planning_driver(train, seed=1, l2=args.l2, log=log)
    out["selected"] = asdict(drv.config)
    out["selection"] = drv.info["selection"]
    out["action_acc_ft_s2"] = list(drv.action_acc_ft_s2)
    out["shape"] = drv.shape.as_dict()
    out["planner"] = {"test_ll": drv.heldout_ll_per_decision(test), "train_ll": drv.loglik / train.n,
                      "converged": drv.converged, "grad_norm": drv.info["grad_norm"],
                      "theta": dict(zip(drv.feature_names, drv.theta.tolist()))}
    log(f"selected {drv.config}: {out['planner']}")
    drv.save(Path(args.out).with_suffix(".planner.json"))

    T = path_tensors(train.obs, train.prev_acc, train.acc_C, drv.action_acc_ft_s2, drv.shape, drv.config)  # every feature: refits
    rng = np.random.default_rng(0)
    groups = np.unique(train.groups)
    gpos = np.searchsorted(groups, train.groups)
    safety = ("gap_need_C", "inv_ttc_C", "headway_C")
    signs: dict[str, list[float]] = {k: [] for k in safety}
    for _ in range(args.bootstrap):
        w = np.bincount(rng.choice(groups.size, size=groups.size), minlength=groups.size)[gpos].astype(float)
        fb = fit_planner(T, train.actions, drv.config, l2=args.l2, weights=w, theta0=drv.theta)
        for k in safety:
            signs[k].append(float(fb.theta[drv.feature_names.index(k)]))
    del T
    out["bootstrap"] = {k: {"negative": sum(x < 0 for x in v), "of": len(v), "values": v} for k, v in signs.items()}
    log(f"bootstrap negatives: { {k: v['negative'] for k, v in out['bootstrap'].items()} }")

    if pairs:
        test_groups = set(np.unique(test.groups).tolist())
        held = [p for p, g in zip(pairs, pair_group) if g in test_groups]
        out["replay"] = {"selected": replay(held, drv.act).summary()}
        acc_tab = np.asarray(cf.action_acc_ft_s2)
        out["replay"]["cf_logit"] = replay(held, lambda o, pa, ac: acc_tab[np.argmax(cf.log_policy(
            o, np.where(np.isfinite(pa), actions_of(np.nan_to_num(pa)), -1)), axis=1)]).summary()
        for grid in args.replay_grids.split(","):
            cands = [t for t in drv.info["selection"] if t["grid"] == grid]
            if not cands:
                continue
            best = max(cands, key=lambda t: t["val_ll"])
            cfg = PlannerConfig(**{k: best[k] for k in asdict(drv.config)})
            alt = learn_planning_driver(train, selection=cfg, l2=args.l2)
            out["replay"][f"best_{grid}"] = replay(held, alt.act).summary() | {
                "config": asdict(cfg), "test_ll": alt.heldout_ll_per_decision(test)}
            log(f"replay best {grid}: {out['replay'][f'best_{grid}']}")
        log(f"replay: {out['replay']}")
    out["seconds"] = time.perf_counter() - t_start
    Path(args.out).write_text(json.dumps(out, indent=1))
    log(f"wrote {args.out} in {out['seconds']:.0f} s")


if __name__ == "__main__":
    main()
