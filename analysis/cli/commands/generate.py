"""``merge-irl generate``: simulate a scenario; write trajectories, encounters and the spec used.

With ``--seeds`` and/or ``--demand-scale`` it runs a resumable sweep (``analysis.sweep.generate``).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from analysis.cli.commands._arg_types import add_allow_implausible
from analysis.cli.main import os_error_line
from analysis.cli.options import DASK, EXECUTOR, PROGRESS, WORKERS, apply_dask_options, executor_from_args
from analysis.sweep.generate import FAILURES, SUMMARY, generate_many, parse_scales, parse_seeds
from merge_irl.atomic import write_text_atomic
from scenarios.loader import load_scenario
from scenarios.spec.parse import with_overrides
from sim.merges.generate import generate
from sim.merges.rules import ENCOUNTER_RULES


def _seeds(text: str):
    try:
        return parse_seeds(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def _scales(text: str):
    try:
        return parse_scales(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "generate", parents=[WORKERS, EXECUTOR, PROGRESS, DASK],
        description="Simulate a scenario headless in SUMO; write trajectories.parquet, encounters.parquet, "
                    "merges.parquet and scenario.toml (and trajectories.csv with --csv) into --out. "
                    "With --seeds and/or --demand-scale, run one simulation per seed x demand scale "
                    "in parallel into --out/<scenario>-seed<N>[-demand<X>]/; a rerun skips finished runs.",
    )
    p.add_argument("--scenario", default="synthetic", metavar="NAME|FILE.toml",
                   help="preset name (synthetic, i80) or a scenario TOML file (default: synthetic)")
    p.add_argument("--duration", type=float, default=None, metavar="S", help="simulated seconds (default: the spec's)")
    p.add_argument("--seed", type=int, default=None, metavar="N", help="SUMO seed of a single run (default: the spec's)")
    p.add_argument("--seeds", type=_seeds, default=None, metavar="LIST",
                   help="sweep: SUMO seeds, e.g. 1,2,3 or 1-10 or 1-3,7")
    p.add_argument("--demand-scale", type=_scales, default=None, metavar="LIST",
                   help="sweep: factors on every demand flow, e.g. 0.5,1,2")
    p.add_argument("--encounter-rule", choices=ENCOUNTER_RULES, default=ENCOUNTER_RULES[0],
                   help="how the run becomes demonstrations: in-lane (default; SUMO's drivers observed as the "
                        "closed-loop controller observes them, A's lane held while observed), take-over (the "
                        "controller's cut, lanes free: other traffic, and each encounter ends where A leaves lane 6), "
                        "merge-frame (A = B's lag car at B's merge frame); run.toml records it; docs/encounters.md")
    p.add_argument("--csv", action="store_true", help="also write trajectories.csv in NGSIM's text format")
    add_allow_implausible(p)
    p.add_argument("--out", default=None, metavar="DIR",
                   help="output folder (default: ./runs/<scenario>-<seed>, or ./runs/<scenario>-sweep for a sweep)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    spec = load_scenario(args.scenario, allow_implausible=args.allow_implausible)
    if args.duration is not None:
        with_overrides(spec, duration_s=args.duration)  # an implausible --duration: one line, exit 2, now
    if args.seeds is not None or args.demand_scale is not None:
        return _run_sweep(args, spec)

    res = generate(spec, args.out, seed=args.seed, duration_s=args.duration, csv=args.csv,
                   progress=not args.no_progress, encounter_rule=args.encounter_rule)
    sim = res.simulation
    print(f"{sim.spec.name} seed {sim.seed}: {sim.n_vehicles} vehicles, {sim.n_vehicle_steps} rows, "
          f"{len(res.encounters.merges)} merges, {len(res.encounters.frames)} encounter frames "
          f"in {sim.wall_time_s:.1f} s", file=sys.stderr)
    for w in sim.events.warnings():
        print(f"warning: {w}", file=sys.stderr)
    for f in res.files:
        print(f)
    return 0


def _run_sweep(args: argparse.Namespace, spec) -> int:
    if args.seed is not None and args.seeds is not None:
        print("merge-irl generate: error: give --seed or --seeds, not both", file=sys.stderr)
        return 2
    executor = executor_from_args(args)  # a bad --executor: one line, exit 2, before any run
    apply_dask_options(args)
    seeds = args.seeds if args.seeds is not None else (
        (args.seed,) if args.seed is not None else (spec.simulation.seed,))
    out = Path(args.out) if args.out else Path("runs") / f"{spec.name}-sweep"
    report = generate_many(spec, seeds, args.demand_scale, out, duration_s=args.duration, csv=args.csv,
                           executor=executor, progress=not args.no_progress,
                           encounter_rule=args.encounter_rule)
    for r in report.results.values():
        print(f"{r['out_dir']}\t{r['n_vehicles']} vehicles\t{r['n_merges']} merges")
        for w in r.get("warnings", ()):
            print(f"warning: {r['run']}: {w}", file=sys.stderr)
    print(report.summary(), file=sys.stderr)
    print(f"summary: {out / SUMMARY}", file=sys.stderr)
    if report.failures:
        print(_write_tracebacks(report, out / FAILURES), file=sys.stderr)
    return 0 if report.ok else 1


def _write_tracebacks(report, path) -> str:
    """The failed runs' tracebacks to ``path`` (not the terminal: the summary's FAILED lines say
    what failed); returns the line that says where they are."""
    text = "".join(f"--- {f.key} ({f.attempts} attempt(s)): {f.error}\n{f.traceback}\n" for f in report.failures)
    try:
        write_text_atomic(path, text)
    except OSError as e:
        return f"tracebacks not written ({os_error_line(e)})"
    return f"tracebacks: {path}"
