"""Benchmark: the pair-trained driver's targets, printed side by side in one run (figures and
ratios, not a timed test).

    python -m benchmarks.driver_targets --driver pairs-replay.json \
        --pairs ../shared/data/ngsim_i80_car_following --params cal.toml \
        [--i80-seeds 1-30] [--synthetic-seeds 1-30,2000-2059] [--demos HELD-OUT.parquet] \
        [--train-demos TRAIN.parquet] [--skip i80,synthetic,pairs] [--duration S] [--workers N] \
        [--out-dir DIR] [--json OUT]

``--params`` is ``merge-irl calibrate fit --pairs PAIRS --classes 3 --holdout 0.3 --seed 0``'s
file; ``--holdout``/``--seed`` must match it (the same held-out followers). Three tables, each
skippable (``--skip``), with a PASS/MISS column per target:

1. **i80** (the evaluation API, ``--i80-seeds``; beside ``uniform``, ``sumo``, ``sumo-in-lane``):
   As controlled, A-into-C and A-into-B collisions (Wilson 95 %), emergency brakings near A per A
   (by A, B and A's follower, strictly beyond 4.5 m/s^2; exact Poisson 95 %; A's own count beside
   it) and its ratio to ``sumo``'s, the share of merges with B ahead of A beside ``sumo``'s,
   take-overs released by time-out. Targets: 0 / 0 collisions, EB <= 2x ``sumo``'s, B ahead
   within 10 points of ``sumo``'s, <= 1 % time-outs.
2. **Real pairs**, held-out split (:mod:`analysis.calibration.driver_eval`): median / mean spacing
   RMSE (95 % bootstrap) beside IDM with SUMO's defaults and the calibration, collisions over all
   pairs, the share closer than 2 m beside the recorded drivers'; then the correction figures
   (:mod:`analysis.calibration.corrections`) per driver beside the calibrated IDM and the
   recorded drivers. Targets: median and mean <= the calibration's, 0 collisions, share < 2 m <=
   recorded, sign changes <= 2x recorded.
3. **Synthetic closed loop** (``--synthetic-seeds``; beside ``sumo-in-lane``, ``uniform`` and,
   with ``--train-demos``, the fitted baselines): A collisions over As, EB near A vs
   ``sumo-in-lane``'s, B ahead vs the held-out demonstrations' (``--demos``; B ahead of A at the
   encounter's last frame with B seen). Targets: 0 collisions, EB <= 2x ``sumo-in-lane``'s, B ahead
   within 10 points of the demonstrations'.

Last, the cost line: ms per decision of ``PlanningDriver.act`` on one observation (median of repeats).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from analysis.calibration.corrections import (
    bin_match,
    gap_error_response,
    idm_acc_ft_s2,
    idm_act,
    idm_desired_gap_ft,
    median_gap_ft,
    planner_desired_gap_ft,
    recorded_commands,
    replay_commands,
    sign_changes,
    w1_acc_jerk,
)
from analysis.calibration.driver_eval import evaluate_driver, replay_pairs
from analysis.calibration.models import SUMO_DEFAULTS
from analysis.calibration.pairs import load_split
from analysis.calibration.params_file import load_result
from analysis.evaluation.evaluate import evaluate
from analysis.evaluation.intervals import poisson_rate_ci95, rate_ci95
from analysis.experiments.learn_driver import CLOSE_GAP_M, pair_frames
from irl.planning.decisions import pair_decisions
from irl.planning.driver import PlanningDriver
from sim.drivers.formats import replay_act

STEP_S = 0.3


def log(msg: str) -> None:
    print(f"[{time.strftime('%H:%M:%S')}] {msg}", file=sys.stderr, flush=True)


def seed_ranges(text: str) -> list[tuple[int, int]]:
    """``"1-30,2000-2059"`` -> ``[(1, 30), (2000, 60)]``: (first seed, episodes) of each range."""
    out = []
    for part in filter(None, (p.strip() for p in text.split(","))):
        a, _, b = part.partition("-")
        lo, hi = int(a), int(b or a)
        if hi < lo:
            raise SystemExit(f"driver_targets: bad seed range {part!r}")
        out.append((lo, hi - lo + 1))
    return out


def verdict(ok: bool | None) -> str:
    return "-" if ok is None else ("PASS" if ok else "MISS")


def ci(t, pct: bool = False, nd: int = 2) -> str:
    """``value [low, high]`` of ``t = (value, low, high)``, in percent with ``pct``."""
    v, lo, hi = t
    s = 100.0 if pct else 1.0
    unit = " %" if pct else ""
    return f"{v * s:.{nd}f} [{lo * s:.{nd}f}, {hi * s:.{nd}f}]{unit}"


# ---------------------------------------------------------------- closed loop (i80, synthetic)

@dataclass(frozen=True)
class Closed:
    """One policy's closed-loop counts, summed over seed ranges."""

    n_controls: int
    a_into_c: int
    a_into_b: int
    a_collisions: int
    eb_near_a: int
    eb_A: int
    n_merges: int
    b_ahead: float
    timeouts: int


def eb_near_a(agg: Any) -> int:
    """Emergency brakings near A: by A, B and A's follower while A is controlled
    (``emergency_brakings``, strictly beyond the metric's threshold), what the target counts."""
    return int(agg.emergency_brakings)


def eb_by_a(agg: Any) -> int:
    """A's own emergency brakings (``emergency_brakings_A``; the total where the evaluation has no
    count by role)."""
    return int(getattr(agg, "emergency_brakings_A", agg.emergency_brakings))


def closed_of(aggs: list[Any]) -> Closed:
    merges = sum(a.n_merges for a in aggs)
    ahead = sum(a.b_ahead_rate[0] * a.n_merges for a in aggs if a.n_merges)
    return Closed(sum(a.n_controls for a in aggs), sum(a.a_into_c for a in aggs), sum(a.a_into_b for a in aggs),
                  sum(a.a_collisions for a in aggs), sum(eb_near_a(a) for a in aggs),
                  sum(eb_by_a(a) for a in aggs), merges,
                  ahead / merges if merges else float("nan"),
                  sum(int(a.release_reasons.get("timeout", 0)) for a in aggs))


def run_closed(args, scenario: str, ranges, baselines, out_root: Path, **kw) -> dict[str, Closed]:
    """Every driver and baseline on every seed range; policy name -> summed counts."""
    by: dict[str, list[Any]] = {}
    for first, n in ranges:
        out = out_root / f"{scenario}-{first}-{first + n - 1}"
        log(f"{scenario}: seeds {first}-{first + n - 1}, {len(args.driver)} driver(s) + {list(baselines)} -> {out}")
        rep = evaluate(args.driver, scenario, n, first, out, baselines=baselines, workers=args.workers, rrd=False,
                       duration_s=args.duration, progress=True, **kw)
        for name, agg in rep.aggregates.items():
            by.setdefault(name, []).append(agg)
    return {name: closed_of(aggs) for name, aggs in by.items()}


def drivers_first(res: dict[str, Closed], baselines) -> list[tuple[str, Closed]]:
    """The learned drivers, then the baselines, each in the evaluation's order."""
    return sorted(res.items(), key=lambda kv: kv[0] in baselines)


def closed_row(name: str, c: Closed, ref: Closed | None, ref_b_ahead: float, ref_name: str) -> dict[str, Any]:
    eb = poisson_rate_ci95(c.eb_near_a, c.n_controls)
    ref_eb = ref.eb_near_a / ref.n_controls if ref and ref.n_controls else float("nan")
    return {"policy": name, "As": c.n_controls, "a_into_c": c.a_into_c, "a_into_b": c.a_into_b,
            "a_collisions": c.a_collisions, "collision_rate_ci95": rate_ci95(c.a_collisions, c.n_controls),
            "eb_near_a_per_a_ci95": eb, "eb_by_A": c.eb_A, "eb_ratio": eb[0] / ref_eb if ref_eb > 0 else float("inf") if eb[0] else 1.0,
            "b_ahead": c.b_ahead, "b_ahead_ref": ref_b_ahead, "merges": c.n_merges,
            "timeout_rate_ci95": rate_ci95(c.timeouts, c.n_controls), "reference": ref_name}


def closed_targets(r: dict[str, Any], timeouts: bool) -> dict[str, bool]:
    t = {"0 into C": r["a_into_c"] == 0, "0 into B": r["a_into_b"] == 0,
         f"EB <= 2x {r['reference']}": r["eb_ratio"] <= 2.0,
         "B ahead within 10 points": bool(abs(r["b_ahead"] - r["b_ahead_ref"]) <= 0.10)}
    if timeouts:
        t["<= 1 % time-outs"] = r["timeout_rate_ci95"][0] <= 0.01
    return t


def print_closed(title: str, rows: list[dict[str, Any]], ref_label: str) -> None:
    print(f"\n### {title}\n")
    print(f"| policy | As | A into C | A into B | A collisions / A (Wilson 95 %) | EB near A / A (Poisson 95 %; A's own) "
          f"| EB ratio | B ahead (vs {ref_label}) | time-outs / A | targets |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        tg = r.get("targets", {})
        print(f"| {r['policy']} | {r['As']} | {r['a_into_c']} | {r['a_into_b']} | "
              f"{ci(r['collision_rate_ci95'], pct=True, nd=1)} | {ci(r['eb_near_a_per_a_ci95'], nd=3)} ({r['eb_by_A']}) | "
              f"{r['eb_ratio']:.2f} | {100 * r['b_ahead']:.0f} % ({100 * r['b_ahead_ref']:.0f} %) | "
              f"{ci(r['timeout_rate_ci95'], pct=True, nd=1)} | "
              f"{'; '.join(f'{k}: {verdict(v)}' for k, v in tg.items()) or '-'} |")


def i80_table(args, out_root: Path) -> list[dict[str, Any]]:
    res = run_closed(args, "i80", seed_ranges(args.i80_seeds), ("uniform", "sumo", "sumo-in-lane"), out_root)
    ref = res.get("sumo")
    rows = []
    for name, c in drivers_first(res, ("uniform", "sumo", "sumo-in-lane")):
        r = closed_row(name, c, ref, ref.b_ahead if ref else float("nan"), "sumo")
        if name not in ("uniform", "sumo", "sumo-in-lane"):
            r["targets"] = closed_targets(r, timeouts=True)
        rows.append(r)
    print_closed(f"i80, seeds {args.i80_seeds} (EB ratio and B ahead against sumo)", rows, "sumo")
    return rows


def demos_b_ahead(path: str | None) -> float:
    """The share of encounters whose B is ahead of A (``d_AB > 0``) at the last frame B is seen."""
    if not path:
        return float("nan")
    df = pd.read_parquet(path) if str(path).endswith(".parquet") else pd.read_csv(path)
    seen = df[np.isfinite(df["d_AB"].to_numpy(dtype=float))]
    return float((seen.groupby("encounter_id")["d_AB"].last() > 0).mean()) if len(seen) else float("nan")


def synthetic_table(args, out_root: Path) -> list[dict[str, Any]]:
    base = ("sumo-in-lane", "uniform") + (("marginal", "markov", "bc") if args.train_demos else ())
    res = run_closed(args, "synthetic", seed_ranges(args.synthetic_seeds), base, out_root, demos=args.demos,
                     train_demos=args.train_demos)
    ref, demo_ahead = res.get("sumo-in-lane"), demos_b_ahead(args.demos)
    rows = []
    for name, c in drivers_first(res, base):
        r = closed_row(name, c, ref, demo_ahead, "sumo-in-lane")
        if name not in base:
            r["targets"] = closed_targets(r, timeouts=False)
            if not args.demos:
                r["targets"]["B ahead within 10 points"] = None
        rows.append(r)
    print_closed(f"synthetic, seeds {args.synthetic_seeds} (EB ratio against sumo-in-lane)", rows,
                 "demonstrations" if args.demos else "no --demos")
    return rows


# ---------------------------------------------------------------- real pairs

def correction_row(name: str, dec, acc, desired, desired_how: str, series=None, rec_series=None) -> dict[str, Any]:
    """The correction figures of one driver's accelerations ``acc`` on the recorded decisions."""
    k, n = bin_match(dec, acc)
    g = gap_error_response(dec, acc, desired)
    row: dict[str, Any] = {"driver": name, "bin_match_ci95": rate_ci95(k, n), "desired_gap": desired_how,
                           "gap_off_share": g.share_off, "abs_acc_off_m_s2": g.driver_abs_acc_ft_s2 * 0.3048,
                           "recorded_abs_acc_off_m_s2": g.recorded_abs_acc_ft_s2 * 0.3048}
    if series is not None:
        flips, trans = sign_changes(series)
        row["sign_changes_per_100_ci95"] = rate_ci95(flips, trans)
        row["w1_acc_m_s2"], row["w1_jerk_m_s3"] = w1_acc_jerk(series, rec_series, STEP_S)
    return row


def pair_driver_rows(path: str, test, pairs, cal, seed: int, dec, rec_series, recorded_close) -> tuple[dict, dict]:
    """The RMSE row and the correction row of one driver file."""
    log(f"pairs: {path}")
    ev = evaluate_driver(path, test, calibration=cal, seed=seed)
    iv = dict(ev.intervals)
    act, step = replay_act(path)
    _, series = replay_commands(replay_pairs(test), act, step)
    every, _ = replay_commands(replay_pairs(pairs), act, step)
    close = int(np.sum(ev.min_gap_m < CLOSE_GAP_M))
    med, mean = iv["median_rmse_m"], iv["mean_rmse_m"]
    c_med = float(np.median(ev.calibrated_rmse_m)) if ev.calibrated_rmse_m is not None else float("nan")
    c_mean = float(np.mean(ev.calibrated_rmse_m)) if ev.calibrated_rmse_m is not None else float("nan")
    row = {"driver": Path(path).name, "median_rmse_m": [med.value, med.low, med.high],
           "mean_rmse_m": [mean.value, mean.low, mean.high],
           "idm_defaults": [float(np.median(ev.default_rmse_m)), float(np.mean(ev.default_rmse_m))],
           "calibrated": [c_med, c_mean], "collisions_all_pairs": int(every.collided.sum()), "n_all_pairs": len(pairs),
           "close_ci95": rate_ci95(close, len(test)), "recorded_close": recorded_close}
    try:
        drv = PlanningDriver.load(path)
        desired, how = planner_desired_gap_ft(dec, drv.shape), "its own s0 + v T"
    except Exception:  # another format: no steady-state gap of its own
        desired, how = median_gap_ft(dec), "recorded median gap"
    corr = correction_row(Path(path).name, dec, np.asarray(act(dec.obs, dec.prev_acc, dec.acc_C)), desired, how,
                          series, rec_series)
    flips = corr["sign_changes_per_100_ci95"][0]
    rec_flips, rec_n = sign_changes(rec_series)
    have_cal = cal is not None
    row["targets"] = {"median <= calibrated": med.value <= c_med if have_cal else None,
                      "mean <= calibrated": mean.value <= c_mean if have_cal else None,
                      "0 collisions": row["collisions_all_pairs"] == 0,
                      "< 2 m <= recorded": row["close_ci95"][0] <= recorded_close,
                      "sign changes <= 2x recorded": flips <= 2 * rec_flips / max(rec_n, 1)}
    return row, corr


def idm_series(rp, params) -> list[np.ndarray]:
    """The commands of IDM replaying the pairs ``rp``, pair ``i`` with ``params[i]``."""
    series: list[np.ndarray] = [np.empty(0)] * len(rp)
    for prm in dict.fromkeys(params):
        idx = [i for i, q in enumerate(params) if q == prm]
        _, part = replay_commands([rp[i] for i in idx], idm_act(prm), STEP_S)
        for i, sr in zip(idx, part):
            series[i] = sr
    return series


def reference_corrections(dec, test, cal, rec_series) -> list[dict[str, Any]]:
    rows = []
    calibrated = (cal.classes.params_for(test) if cal.classes else [cal.population] * len(test)) if cal else None
    for name, params in (("IDM calibrated", calibrated), ("IDM SUMO defaults", [SUMO_DEFAULTS] * len(test))):
        if params is None:
            continue
        per = [params[g] for g in dec.groups]
        rows.append(correction_row(name, dec, idm_acc_ft_s2(dec, per), idm_desired_gap_ft(dec, per),
                                   "IDM steady state", idm_series(replay_pairs(test), params), rec_series))
    rec = correction_row("recorded drivers", dec, dec.acc, median_gap_ft(dec), "recorded median gap",
                         rec_series, rec_series)
    rec["bin_match_ci95"] = (1.0, 1.0, 1.0)
    return rows + [rec]


def print_pairs(rows, corr, n_train, n_test, recorded_close) -> None:
    print(f"\n### Real pairs: {n_train} training, {n_test} held-out pairs (recorded drivers closer than "
          f"{CLOSE_GAP_M:g} m: {100 * recorded_close:.0f} % of held-out pairs)\n")
    print("| driver | median RMSE (m, 95 %) | mean RMSE (m, 95 %) | IDM defaults | calibrated | collisions, all "
          "pairs | closer than 2 m (Wilson 95 %) | targets |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['driver']} | {ci(r['median_rmse_m'])} | {ci(r['mean_rmse_m'])} | "
              f"{r['idm_defaults'][0]:.2f} / {r['idm_defaults'][1]:.2f} | {r['calibrated'][0]:.2f} / "
              f"{r['calibrated'][1]:.2f} | {r['collisions_all_pairs']}/{r['n_all_pairs']} | "
              f"{ci(r['close_ci95'], pct=True, nd=0)} | "
              f"{'; '.join(f'{k}: {verdict(v)}' for k, v in r['targets'].items())} |")
    print("\nCorrections on the held-out recorded states (0.3 s decisions). Desired gap: a driver's own "
          "steady-state gap at the recorded speed where it has one (planner: s0 + v T of its shape; IDM: "
          "(s0 + v T) / sqrt(1 - (v/v0)^delta)), else the recorded follower's median gap in the pair. "
          "Response: mean |acceleration| where the recorded gap is >= 20 % off it, beside the recorded "
          "drivers' on the same decisions. Sign changes and W1: the closed replay of the held-out pairs.\n")
    print("| driver | bin matches person's (Wilson 95 %) | desired gap | decisions >= 20 % off | response "
          "(m/s^2) | recorded there | sign changes / 100 decisions | W1 acc (m/s^2) | W1 jerk (m/s^3) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for c in corr:
        sc = c.get("sign_changes_per_100_ci95")
        print(f"| {c['driver']} | {ci(c['bin_match_ci95'], pct=True, nd=0)} | {c['desired_gap']} | "
              f"{100 * c['gap_off_share']:.0f} % | {c['abs_acc_off_m_s2']:.2f} | {c['recorded_abs_acc_off_m_s2']:.2f} | "
              f"{ci(sc, pct=True, nd=1)[:-2] if sc else '-'} | {c.get('w1_acc_m_s2', float('nan')):.3f} | "
              f"{c.get('w1_jerk_m_s3', float('nan')):.3f} |")


def pairs_table(args) -> dict[str, Any]:
    pairs, train, test = load_split(args.pairs, args.holdout, args.seed)  # the folder's copies: not warned of
    cal = load_result(args.params) if args.params else None
    recorded_close = float(np.mean([float(np.min(p.spacing)) < CLOSE_GAP_M for p in test]))
    frames, _ = pair_frames(test)
    dec = pair_decisions(frames, STEP_S)  # one group per held-out pair
    rec_series = recorded_commands(replay_pairs(test), STEP_S)
    rows, corr = [], []
    for path in args.driver:
        row, c = pair_driver_rows(path, test, pairs, cal, args.seed, dec, rec_series, recorded_close)
        rows.append(row)
        corr.append(c)
    corr += reference_corrections(dec, test, cal, rec_series)
    print_pairs(rows, corr, len(train), len(test), recorded_close)
    return {"rmse": rows, "corrections": corr, "cost_obs": dec.take(np.arange(1))}


# ---------------------------------------------------------------- cost

def cost_line(paths: list[str], one, repeats: int = 50) -> dict[str, float]:
    out = {}
    for path in paths:
        try:
            drv = PlanningDriver.load(path)
        except Exception:
            continue
        obs = one.obs if one is not None else np.array([[60.0, 0.0, np.nan, np.nan, 40.0, 15.0, np.nan]])
        prev = one.prev_acc if one is not None else np.zeros(1)
        acc_c = one.acc_C if one is not None else np.zeros(1)
        times = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            drv.act(obs, prev, acc_c)
            times.append(time.perf_counter() - t0)
        out[Path(path).name] = 1000.0 * float(np.median(times))
    print("\nCost: " + ("; ".join(f"{k} {v:.2f} ms per decision (PlanningDriver.act, one observation, median of "
                                  f"{repeats})" for k, v in out.items()) or "no planning driver"))
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--driver", action="append", required=True, metavar="DRIVER.json")
    ap.add_argument("--pairs", default=None, metavar="DIR")
    ap.add_argument("--params", default=None, metavar="CAL.toml")
    ap.add_argument("--holdout", type=float, default=0.3)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--i80-seeds", default="1-30")
    ap.add_argument("--synthetic-seeds", default="1-30,2000-2059")
    ap.add_argument("--demos", default=None, metavar="HELD-OUT.parquet")
    ap.add_argument("--train-demos", default=None, metavar="TRAIN.parquet")
    ap.add_argument("--skip", default="", help="comma-separated tables to skip: i80, synthetic, pairs")
    ap.add_argument("--duration", type=float, default=None, help="simulated s per episode (default: the scenario's)")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--out-dir", default=None, help="evaluation outputs (default: a temporary folder)")
    ap.add_argument("--json", default=None, metavar="FILE")
    args = ap.parse_args(argv)
    skip = {s.strip() for s in args.skip.split(",") if s.strip()}
    if skip - {"i80", "synthetic", "pairs"}:
        ap.error(f"--skip: unknown table(s) {sorted(skip - {'i80', 'synthetic', 'pairs'})}")
    if "pairs" not in skip and not args.pairs:
        ap.error("--pairs is needed for the pairs table (or --skip pairs)")
    result: dict[str, Any] = {}
    one = None
    if "pairs" not in skip:
        p = pairs_table(args)
        one = p.pop("cost_obs")
        result["pairs"] = p
    with tempfile.TemporaryDirectory() as tmp:
        out_root = Path(args.out_dir or tmp)
        if "i80" not in skip:
            result["i80"] = i80_table(args, out_root)
        if "synthetic" not in skip:
            result["synthetic"] = synthetic_table(args, out_root)
    result["cost_ms_per_decision"] = cost_line(args.driver, one)
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=1, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main())
