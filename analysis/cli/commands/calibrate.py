"""``merge-irl calibrate``: fit SUMO car-following parameters to real leader-follower pairs.

* ``calibrate fit --pairs DIR --out params.toml [--cf-model-name idm|krauss|eidm] [--classes C]``
* ``calibrate evaluate --params FILE --pairs DIR [--json]``
* ``calibrate check --params FILE --pairs DIR [--out report.md] [--json]``
* ``calibrate preset --params FILE --out my_i80.toml [--scenario i80]``: a scenario preset with
  the calibrated drivers (``generate --scenario my_i80.toml``)

Thin layer over :mod:`analysis.calibration`, :mod:`analysis.calibration.sweep` (per-pair fits
on every core through the sweep runner) and :mod:`analysis.calibration.check`. ``evaluate``
prints 95 % bootstrap intervals (pairs weighted equally) of the median, mean, win share and the
calibrated / default ratios. EIDM (no numpy replica) is fitted and scored through real SUMO
runs (:mod:`analysis.calibration.sumo_fit`): population fit only, ``--max-evals`` SUMO runs.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

from analysis.calibration import evaluate, load_pairs, load_result, save_result, split_by_follower
from analysis.calibration.check import run_calibration_check
from analysis.calibration.class_fit import class_edges, fit_classes
from analysis.calibration.driver_eval import evaluate_driver
from analysis.calibration.fit import bounds_warning
from analysis.calibration.models import CALIBRATION_MODELS, MODELS
from analysis.calibration.objective import DEFAULT_OBJECTIVE
from analysis.calibration.pairs import pair_files
from analysis.calibration.preset import default_header, preset_with_drivers
from analysis.calibration.sumo_fit import DEFAULT_MAX_EVALS, MIN_MAX_EVALS
from analysis.calibration.sweep import calibrate_parallel
from analysis.calibration.vtypes import scenario_car_model
from analysis.cli.commands._arg_types import DeprecatedAlias, Once, add_allow_implausible, positive_int
from analysis.cli.options import PROGRESS, WORKERS, seed_option
from merge_irl.atomic import write_text_atomic
from merge_irl.progress import progress_bar
from merge_irl.run_folder import check_writable
from scenarios.errors import SpecError
from scenarios.loader import load_scenario
from scenarios.spec.parse import spec_from_toml

#: the car-following models ``calibrate fit --cf-model-name`` fits.
CF_MODEL_NAMES = ("idm", "krauss", "eidm")


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "calibrate",
        description="Calibrate SUMO car-following models (IDM, Krauss, EIDM) on real leader-follower pairs: "
                    "the leader is replayed, the follower simulated, the spacing error minimised.",
    )
    sub = p.add_subparsers(dest="calibrate_command", metavar="ACTION")
    sub.required = True

    f = sub.add_parser("fit", help="population + per-pair fits, written as TOML",
                       parents=[seed_option("seed of the held-out split"), WORKERS, PROGRESS])
    f.add_argument("--pairs", required=True, metavar="DIR", action=Once, what="one folder of pairs", help="folder of pair CSVs (or with a train/ subfolder)")
    f.add_argument("--out", required=True, metavar="FILE", help="output params TOML")
    f.add_argument("--cf-model-name", choices=CF_MODEL_NAMES, default="idm",
                   help="the car-following model fitted: ""idm / krauss: numpy replica of SUMO, population + per-pair fits; eidm: real SUMO "
                        "runs, population fit only (Nelder-Mead, see --max-evals)")
    f.add_argument("--max-evals", type=int, default=None, metavar="N",
                   help="eidm only: SUMO runs over the training pairs the population fit may use (default 60, "
                        "at least 7: 2 starts + 5 simplex vertices); refused for idm and krauss")
    f.add_argument("--no-per-pair", action="store_true", help="population fit only (faster, no spread)")
    f.add_argument("--objective", choices=("log", "rmse", "ratio"), default=None,
                   help="population objective over the per-pair spacing RMSEs: log (geometric mean, "
                        "the default), rmse (Cauchy loss, 1 m), ratio (each pair's RMSE over its RMSE under "
                        "SUMO's defaults); see docs/calibration.md")
    f.add_argument("--classes", type=positive_int, default=1, metavar="C",
                   help="idm / krauss: also fit one population vector per class of the initial time headway "
                        "(C equally filled classes of the training pairs; default 1: one vector for all); "
                        "'evaluate' then simulates each pair with its class's vector")
    f.add_argument("--holdout", type=float, default=0.0, metavar="FRACTION",
                   help="leave this share of followers out of the fit (split by follower; see --seed)")
    # the spelling before --cf-model-name (--model is a model file elsewhere): one release more, with a note
    f.add_argument("--model", dest="cf_model_name", choices=CF_MODEL_NAMES, action=DeprecatedAlias,
                   use="--cf-model-name")
    f.add_argument("--limit", type=positive_int, default=None, metavar="N", help="use only the first N pair files")
    f.set_defaults(func=run_fit)

    e = sub.add_parser("evaluate", help="per-pair and median spacing RMSE vs SUMO's defaults",
                       parents=[seed_option("seed of the held-out split, as given to 'fit'"), WORKERS],
                       description="Replay each pair's recorded leader and score the follower's spacing RMSE: a "
                                   "calibration (--params) beside SUMO's defaults, or a learned driver (--driver, "
                                   "its most likely action each decision) beside SUMO's IDM defaults and, with "
                                   "--params, that calibration.")
    e.add_argument("--params", default=None, metavar="FILE",
                   help="params TOML from 'calibrate fit' (required without --driver)")
    e.add_argument("--driver", default=None, metavar="DRIVER.json",
                   help="a driver file of 'merge-irl learn-driver' (or a car-following logit) to replay")
    e.add_argument("--pairs", required=True, metavar="DIR", action=Once, what="one folder of pairs",
                   help="folder of pair CSVs (or with a train/ subfolder) to score; any folder")
    e.add_argument("--holdout", type=float, default=0.0, metavar="FRACTION",
                   help="evaluate only the held-out followers of 'fit --holdout FRACTION --seed S' (give the "
                        "fit's --holdout, --seed and --limit; refused if a scored follower was in the fit)")
    e.add_argument("--limit", type=positive_int, default=None, metavar="N",
                   help="use only the first N pair files, as 'fit --limit N'")
    e.add_argument("--json", action="store_true", help="print one JSON object")
    e.set_defaults(func=run_evaluate)

    c = sub.add_parser("check", help="compare the i80 scenario's simulated traffic with the real pairs",
                       parents=[seed_option("seed of the SUMO run and the driver sample")])
    c.add_argument("--params", required=True, metavar="FILE", help="params TOML from 'calibrate fit'")
    c.add_argument("--pairs", required=True, metavar="DIR", action=Once, what="one folder of pairs", help="folder of real pair CSVs to compare with")
    c.add_argument("--scenario", default="i80", metavar="NAME|FILE", help="scenario preset or TOML (default i80)")
    c.add_argument("--duration", type=float, default=None, metavar="S",
                   help="simulated seconds, warm-up included, longer than the scenario's warm-up "
                        "(default: the scenario's own; i80: 600 s with 240 s of warm-up)")
    add_allow_implausible(c)
    c.add_argument("--keep-drivers", action="store_true",
                   help="simulate the scenario's own drivers (default: the params file's driver distribution, as "
                        "'calibrate preset' writes it)")
    c.add_argument("--drivers", type=positive_int, default=None, metavar="N",
                   help="resample N driver types from the per-pair fits with --seed (default: one per per-pair fit)")
    c.add_argument("--heldout-only", action="store_true",
                   help="compare only with the pairs whose follower the fit did not see (the params file's "
                        "training followers left out; fit with --holdout F to keep some aside)")
    c.add_argument("--out", default=None, metavar="FILE", help="write the markdown report here")
    c.add_argument("--json", action="store_true", help="print the report as one JSON object")
    c.set_defaults(func=run_check)

    w = sub.add_parser("preset", help="write a scenario preset whose car drivers are the calibrated ones",
                       description="Write a scenario TOML: the scenario (default i80) with its car drivers replaced "
                                   "by the per-pair fits of --params (one equally likely type per fit, or --drivers N resampled), under the "
                                   "scenario's own car-following model when it takes the fitted parameters (i80: "
                                   "EIDM for IDM fits, SUMO's default driver noise), as the shipped i80 preset was "
                                   "made. Use it with 'merge-irl generate --scenario FILE' or 'calibrate check "
                                   "--scenario FILE --keep-drivers'.")
    w.add_argument("--params", required=True, metavar="FILE", help="params TOML from 'calibrate fit'")
    w.add_argument("--out", required=True, metavar="FILE.toml", help="scenario TOML to write")
    w.add_argument("--scenario", default="i80", metavar="NAME|FILE",
                   help="scenario preset or TOML whose road, demand and lane changing are kept (default i80)")
    w.add_argument("--drivers", type=positive_int, default=None, metavar="N",
                   help="resample N car driver types from the per-pair fits (default: one type per per-pair fit, "
                        "the fitted distribution itself; the shipped i80 preset: 32)")
    w.add_argument("--seed", type=int, default=None,
                   help="seed of a --drivers resample (default: the scenario's seed; i80: 80)")
    w.add_argument("--car-follow-model", default=None, metavar="MODEL",
                   help="SUMO carFollowModel of the written cars (default: the scenario's own when it takes the "
                        "fitted parameters, else the fitted model's; IDM fits: IDM, IIDM or EIDM; Krauss: Krauss)")
    w.add_argument("--name", default=None, help="scenario name written in the file (default: the file's stem)")
    w.set_defaults(func=run_preset)


def _pairs(args: argparse.Namespace, *, held_out: bool):
    pairs = load_pairs(args.pairs, limit=getattr(args, "limit", None))
    if args.holdout:  # 0 = no held-out split; a negative or NaN fraction is refused, not ignored
        if not 0 < args.holdout < 1:
            raise SpecError(f"--holdout: expected a fraction in (0, 1), got {args.holdout}")
        try:
            train, test = split_by_follower(pairs, args.holdout, args.seed)
        except SpecError as e:
            raise SpecError(f"--holdout {args.holdout}: {e}") from None
        return test if held_out else train
    return pairs


def run_fit(args: argparse.Namespace) -> int:
    if args.max_evals is not None and args.cf_model_name in MODELS:
        raise SpecError(f"--max-evals: caps the SUMO runs of a model fitted through SUMO "
                        f"({', '.join(m for m in CALIBRATION_MODELS if m not in MODELS)}); "
                        f"{args.cf_model_name} is fitted by its numpy replica")
    if args.classes > 1 and args.cf_model_name not in MODELS:
        raise SpecError(f"--classes: driver classes need a model with a numpy replica ({', '.join(MODELS)}); "
                        f"{args.cf_model_name} is fitted through SUMO")
    if args.max_evals is not None and args.max_evals < MIN_MAX_EVALS:
        raise SpecError(f"--max-evals: expected at least {MIN_MAX_EVALS} SUMO runs, got {args.max_evals}")
    try:
        check_writable(args.out)  # an unwritable --out fails now, not after minutes of fitting
    except OSError as e:
        raise SpecError(f"--out {args.out}: cannot write a file there ({e.strerror or e})") from None
    pairs = _pairs(args, held_out=False)
    if args.classes > 1:  # fail before minutes of fitting: too few pairs, or classes the quantiles cannot fill
        try:
            class_edges(pairs, args.classes, model=args.cf_model_name)
        except SpecError as e:  # "classes: ..." -> "--classes: ...", the option's name
            raise SpecError(f"--{e}") from None
    file_of = {f.stem: f for f in pair_files(args.pairs, limit=args.limit)}
    print(f"fitting {args.cf_model_name} on {len(pairs)} pairs ...", file=sys.stderr)
    if args.cf_model_name not in MODELS:
        if not args.no_per_pair:
            print(f"{args.cf_model_name}: no numpy replica; population fit through SUMO only, no per-pair fits",
                  file=sys.stderr)
        bar = progress_bar(args.max_evals or DEFAULT_MAX_EVALS, desc=f"calibrate {args.cf_model_name} (SUMO runs)",
                           unit="run", enabled=not args.no_progress)
    else:  # the population fit's simulations (two starts, up to 40 each), then the per-pair fits' own bar
        bar = progress_bar(None, desc=f"population {args.cf_model_name}", unit="sim", leave=False,
                           enabled=not args.no_progress)
    try:
        result = calibrate_parallel(pairs, [file_of[p.name] for p in pairs], model=args.cf_model_name,
                                    per_pair=not args.no_per_pair, workers=args.workers,
                                    objective=args.objective or DEFAULT_OBJECTIVE,
                                    progress=not args.no_progress, max_evals_sumo=args.max_evals,
                                    tick=lambda: bar.update(1))
    finally:
        bar.close()
    if args.classes > 1:
        t0 = time.perf_counter()
        with progress_bar(None, desc=f"{args.classes} class fits", unit="sim", leave=False,
                          enabled=not args.no_progress) as class_bar:
            classes = fit_classes(pairs, args.classes, model=args.cf_model_name, objective=result.objective,
                                  tick=lambda: class_bar.update(1))
        result = replace(result, classes=classes)
        print(f"{classes.n_classes} driver classes of the initial time headway, edges "
              f"{', '.join(f'{e:.2f}' for e in classes.edges_s)} s ({time.perf_counter() - t0:.1f} s):",
              file=sys.stderr)
        for c, q in enumerate(classes.params):
            print(f"  class {c}: accel={q.accel:.3f} decel={q.decel:.3f} tau={q.tau:.3f} minGap={q.minGap:.3f} "
                  f"maxSpeed={q.maxSpeed:.2f}", file=sys.stderr)
    save_result(result, args.out)
    p = result.population
    print(f"population: accel={p.accel:.3f} decel={p.decel:.3f} tau={p.tau:.3f} minGap={p.minGap:.3f} "
          f"maxSpeed={p.maxSpeed:.2f}; median spacing RMSE {result.population_median_rmse_m:.3f} m "
          f"({result.seconds_population:.1f} s + per-pair {result.seconds_per_pair:.1f} s)", file=sys.stderr)
    if result.spread:
        print(f"spread of the {len(result.per_pair)} per-pair fits (10% / median / 90%):", file=sys.stderr)
        for name, sp in result.spread:
            print(f"  {name:<9} {sp.q10:7.3f} {sp.median:7.3f} {sp.q90:7.3f}", file=sys.stderr)

    if line := bounds_warning(result.per_pair, result.fitted):
        print(f"merge-irl calibrate fit: warning: {line}", file=sys.stderr)
    print(args.out)
    return 0


def run_evaluate(args: argparse.Namespace) -> int:
    if args.driver is not None:
        return run_evaluate_driver(args)
    if args.params is None:
        raise SpecError("calibrate evaluate: give --params FILE (a calibration) or --driver DRIVER.json")
    result = load_result(args.params)
    pairs = _pairs(args, held_out=True)
    trained = set(result.train_followers) or {f.group for f in result.per_pair}
    in_fit = [p for p in pairs if p.group in trained]
    if in_fit and args.holdout:
        raise SpecError(f"--holdout {args.holdout} --seed {args.seed}: {len(in_fit)} of the {len(pairs)} held-out pairs "
                        f"(e.g. {in_fit[0].name}) have a follower {args.params} was fitted on: give 'evaluate' the "
                        "fit's --holdout, --seed and --limit")
    if not trained:
        print(f"note: {args.params} does not record its training followers: held-out and in-sample pairs cannot "
              "be told apart", file=sys.stderr)
    elif in_fit:
        print(f"note: {len(in_fit)} of the {len(pairs)} pairs have a follower {args.params} was fitted on: an "
              "in-sample score for them ('fit --holdout F --seed S', then 'evaluate --holdout F --seed S', scores "
              "held-out drivers only)", file=sys.stderr)
    ev = evaluate(result.population, pairs, model=result.model, workers=args.workers, classes=result.classes)
    if args.json:
        print(json.dumps({**ev.to_json_dict(), "n_pairs_in_fit": len(in_fit) if trained else None}))
        return 0
    drivers = f" ({ev.n_classes} driver classes of the initial time headway)" if ev.n_classes > 1 else ""
    print(f"{result.model} parameters of {args.params}{drivers} beside SUMO's {result.model} defaults, "
          f"{len(ev.pairs)} pairs (spacing RMSE, m)")
    width = max(len(s.name) for s in ev.pairs)
    print(f"{'pair':<{width}}  {'rmse_m':>8}  {'default_rmse_m':>14}")
    for s in ev.pairs:
        print(f"{s.name:<{width}}  {s.rmse_m:8.3f}  {s.default_rmse_m:14.3f}")
    print(f"{'median':<{width}}  {ev.median_rmse_m:8.3f}  {ev.default_median_rmse_m:14.3f}")
    print(f"{'mean':<{width}}  {ev.mean_rmse_m:8.3f}  {ev.default_mean_rmse_m:14.3f}")
    print(f"calibrated better on {100 * ev.win_fraction:.0f}% of {len(ev.pairs)} pairs")
    if ev.intervals:
        print("95% bootstrap intervals over pairs (pairs weighted equally):")
        for name, iv in ev.intervals:
            print(f"  {name:<22} {iv.value:8.3f}  [{iv.low:.3f}, {iv.high:.3f}]")
    return 0


def run_evaluate_driver(args: argparse.Namespace) -> int:
    """``calibrate evaluate --driver``: the driver's replay beside SUMO's IDM defaults (and ``--params``)."""
    calibration = load_result(args.params) if args.params is not None else None
    pairs = _pairs(args, held_out=True)
    ev = evaluate_driver(args.driver, pairs, calibration=calibration, seed=args.seed)
    summary = ev.to_json_dict()
    if args.json:
        print(json.dumps(summary))
        return 0
    cal = ev.calibrated_rmse_m
    print(f"{args.driver} on {ev.n_pairs} pairs (spacing RMSE, m; most likely action each decision), beside IDM with "
          f"SUMO's defaults{' and ' + str(args.params) if cal is not None else ''}")
    width = max(len(n) for n in ev.names)
    print(f"{'pair':<{width}}  {'rmse_m':>8}  {'default_rmse_m':>14}" + ("  calibrated_rmse_m" if cal is not None else "")
          + "  collided")
    for i, name in enumerate(ev.names):
        extra = f"  {cal[i]:17.3f}" if cal is not None else ""
        print(f"{name:<{width}}  {ev.rmse_m[i]:8.3f}  {ev.default_rmse_m[i]:14.3f}{extra}  {'yes' if ev.collided[i] else ''}")
    print(f"collisions: {summary['collisions']} of {ev.n_pairs} pairs")
    print("95% bootstrap intervals over pairs (pairs weighted equally):")
    for name, iv in ev.intervals:
        print(f"  {name:<26} {iv.value:8.3f}  [{iv.low:.3f}, {iv.high:.3f}]")
    return 0


def run_check(args: argparse.Namespace) -> int:
    if args.out:
        try:
            check_writable(args.out)  # an unwritable --out fails now, not after the SUMO run
        except OSError as e:
            raise SpecError(f"--out {args.out}: cannot write a file there ({e.strerror or e})") from None
    report = run_calibration_check(
        params_path=args.params, pairs_dir=args.pairs, scenario=args.scenario,
        duration_s=args.duration, seed=args.seed, keep_drivers=args.keep_drivers, n_drivers=args.drivers,
        allow_implausible=args.allow_implausible, heldout_only=args.heldout_only,
    )
    if args.out:
        report.write_markdown(args.out)
    if args.json:
        print(json.dumps(report.to_json_dict()))
    else:
        print(report.to_markdown())
    return 0


def run_preset(args: argparse.Namespace) -> int:
    out = Path(args.out)
    if args.seed is not None and args.drivers is None:
        raise SpecError("--seed: seeds a --drivers N resample; without --drivers every per-pair fit is written, no draw")
    if out.suffix != ".toml":
        raise SpecError(f"--out {args.out}: a scenario file must end in .toml (generate --scenario reads it by that)")
    try:
        check_writable(out)
    except OSError as e:
        raise SpecError(f"--out {args.out}: cannot write a file there ({e.strerror or e})") from None
    spec = load_scenario(args.scenario)
    if not Path(args.params).is_file():
        raise SpecError(f"--params {args.params}: no such file (write one with 'merge-irl calibrate fit')")
    result = load_result(args.params)
    n = args.drivers
    seed = spec.simulation.seed if args.seed is None else args.seed
    model = args.car_follow_model or scenario_car_model(result.model, [c.car_follow_model for c in spec.drivers.car])
    header = default_header(args.scenario, args.params, n=n, seed=seed, car_follow_model=model)
    text = preset_with_drivers(args.scenario, args.params, n=n, seed=seed, header=header,
                               car_follow_model=args.car_follow_model, name=args.name or out.stem)
    spec_from_toml(text, source=str(out))  # what is written loads as a scenario
    write_text_atomic(out, text)
    cars = load_scenario(out).drivers.car
    kinds = len({c.id for c in cars})
    distinct = len({replace(c, id="", probability=1.0) for c in cars})  # the same parameters drawn again
    n_fits = len(result.per_pair)
    if distinct < kinds:
        said = (f"{kinds} car driver types drawn with replacement from {n_fits} per-pair fit(s): {distinct} distinct "
                f"driver(s), {kinds - distinct} repeat(s)")
    else:
        said = f"{kinds} calibrated car driver type(s)"
    print(f"{args.scenario} with {said} from {args.params} ({result.model} fits, driven by SUMO's {model}); "
          f"run it: merge-irl generate --scenario {out}", file=sys.stderr)
    if n is not None and n_fits and n > n_fits:
        print(f"merge-irl calibrate preset: warning: --drivers {n} asks for more driver types than {args.params} has "
              f"per-pair fits ({n_fits}): a resample repeats fits, it adds no driver the data does not have; "
              f"fit more pairs (at least {n} followers) or leave out --drivers (one type per fit)", file=sys.stderr)
    print(out)
    return 0
