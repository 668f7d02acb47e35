"""``merge-irl evaluate``: closed-loop evaluation of learned models against SUMO and random."""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

from analysis.cli.commands._arg_types import DeprecatedAlias, Once, add_allow_implausible
from analysis.cli.options import (
    DASK,
    EPISODES,
    EXECUTOR,
    PROGRESS,
    WORKERS,
    apply_dask_options,
    executor_from_args,
    seed_option,
)
from analysis.errors import AnalysisError
from analysis.evaluation.config import EvaluationConfig
from analysis.evaluation.outcome import write_report
from analysis.evaluation.plan import plan_evaluation
from analysis.evaluation.report import flag_lines, human_table, report_table
from analysis.evaluation.run import run_plan
from analysis.evaluation.thresholds import gate, parse_thresholds
from merge_irl.run_folder import locked
from sim.closed_loop.config import HIGH_BRAKE_RULES, ControllerConfig
from sim.drivers.baselines import check_baselines, left_out_baselines, training_action_acc
from sim.drivers.callables import CallablePolicy
from sim.drivers.callables.limits import DEFAULT_DECISION_LIMIT_S, check_limit


class DeprecatedDriverAlias(argparse._AppendAction):
    """``--model``/``--cf-model``: append to ``--driver``'s list, saying once on stderr (and as a
    :class:`DeprecationWarning`) that the option is an alias of ``--driver``."""

    use = "--driver"

    def __call__(self, parser, namespace, values, option_string=None):
        said: set[str] = getattr(namespace, "_deprecated_said", set())
        if option_string not in said:
            note = (f"{parser.prog}: warning: {option_string} is deprecated and goes in the next release: use "
                    "--driver (the same meaning)")
            print(note, file=sys.stderr)
            warnings.warn(note, DeprecationWarning, stacklevel=2)
            namespace._deprecated_said = said | {option_string}
        super().__call__(parser, namespace, values, option_string)


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "evaluate", parents=[EPISODES, seed_option("first seed; episode i uses seed + i"), WORKERS, EXECUTOR,
                             PROGRESS, DASK],
        description="Re-inject learned drivers (--driver: files or baseline names; callables of your own, --policy) as the lag car A of every "
                    "merge, run N episodes per policy beside the baselines (SUMO's own driver, uniform, marginal, "
                    "markov, bc; on request idm and sumo-in-lane), and write report.md, metrics.json, PNG plots and "
                    "rerun recordings.")
    p.add_argument("--driver", action="append", default=[], metavar="SPEC",
                   help="a driver (repeatable, in order): a learned file of any registered format (a tabular IRL "
                        "model of 'merge-irl learn', a car-following logit of 'merge-irl dagger', a planning driver "
                        "of 'merge-irl learn-driver'; named after the file's stem, a model after its method) or a "
                        "baseline name (added to --baselines); none: only the baselines")
    for alias in ("--model", "--cf-model"):  # older spellings of --driver: hidden, one stderr line each
        p.add_argument(alias, action=DeprecatedDriverAlias, dest="driver", metavar="FILE", help=argparse.SUPPRESS)
    p.add_argument("--policy", action="append", default=[], metavar="MODULE:CALLABLE[:NAME]",
                   help="a callable obs -> action of your own (repeatable): MODULE a dotted module name or a path to "
                        "a .py file; obs the [7] continuous observation (d_AC, v_AC, d_AB, v_AB, v_A, len_C, len_B; "
                        "ft, ft/s); action an index 0..4 (High Brake .. High Accel) or A's acceleration in m/s^2; "
                        "an object with predict(obs, deterministic=True) (Stable-Baselines3) works too. NAME: its "
                        "row in the report (default: the callable's name)")
    p.add_argument("--policy-vecnormalize", default=None, metavar="FILE",
                   help="a Stable-Baselines3 VecNormalize.save file: its observation statistics normalise what "
                        "every --policy sees. A --policy exposing its action distribution (SB3's get_distribution, "
                        "a probs(obs) method) gets a held-out log-likelihood")
    p.add_argument("--policy-weights", action="append", default=[], metavar="FILE",
                   help="a file the --policy callables load (their weights, e.g. the Stable-Baselines3 .zip; "
                        "repeatable): its SHA-256 is recorded in the provenance of every --policy, with the "
                        "--policy-vecnormalize file's")
    p.add_argument("--policy-timeout", type=float, default=None, metavar="SECONDS",
                   help="seconds one decision of a --policy callable may take before the evaluation stops with an "
                        "error naming it (default 60: no honest policy needs that long)")
    p.add_argument("--scenario", default="synthetic", help="preset name or scenario TOML (default synthetic)")
    p.add_argument("--duration", type=float, default=None, help="simulated seconds per episode (default: the scenario's)")
    add_allow_implausible(p)
    p.add_argument("--demos", nargs="+", action="extend", default=None, metavar="PATH",
                   help="held-out encounter tables (.parquet/.csv) for the action divergence and held-out LL, read as "
                        "one set (repeat or list several: --demos a b and --demos a --demos b read both)")
    p.add_argument("--train-demos", default=None, action=Once, what="one training encounter table",
                   help="training encounter table (.parquet/.csv) of the marginal, markov and bc baselines")
    p.add_argument("--pairs", default=None, metavar="DIR", action=Once, what="one folder of pairs",
                   help="folder of recorded car-following pair CSVs (or with a train/ subfolder; e.g. NGSIM I-80): "
                        "adds the 'recorded drivers' row to the human-likeness table and every driver's W1 of "
                        "acceleration, jerk, gap and time headway to it")
    p.add_argument("--baselines", default="sumo,uniform,marginal,markov,bc",
                   help="comma-separated baselines among sumo, uniform, marginal, markov, bc, idm, sumo-in-lane "
                        "('' for none; marginal, markov and bc need --train-demos; idm: the Intelligent Driver Model "
                        "with the scenario's car parameters, driven through the controller; sumo-in-lane: SUMO's "
                        "driver with A's lane changes off, as for every commanded driver)")
    p.add_argument("--decision-step-s", dest="decision_step_s", type=float, default=None,
                   help="seconds between two decisions of A (default: the first tabular model's decision step, else the "
                        "first other driver's that has one, else 0.3; a model driven at another step than its own is warned about)")
    # the older spelling of --decision-step-s: one release more, with a note
    p.add_argument("--decision-step", dest="decision_step_s", type=float, action=DeprecatedAlias, use="--decision-step-s")
    p.add_argument("--high-brake", choices=HIGH_BRAKE_RULES, default=HIGH_BRAKE_RULES[0],
                   help="actuation: mean (default, physical) = every action at the driver's own acceleration (the "
                        "model file's per-action mean), capped at A's emergency deceleration; need = High Brake harder "
                        "when the simulator's ground truth says A would not stay behind its lane-6 leader (a named "
                        "variant, counted in the report; no learned driver can rely on it)")
    p.add_argument("--safety-ttc", type=float, default=None, metavar="S",
                   help="safety-filter variant: replace an action that would bring A's TTC to its leader "
                        "below S seconds (default: raw, no filter); interventions are reported")
    p.add_argument("--mode", action="store_true", help="take the most likely action instead of sampling")
    p.add_argument("--no-rrd", action="store_true", help="do not write rerun recordings")
    p.add_argument("--out", default=None, help="output folder (default ./runs/evaluate-<scenario>-<seed>/)")
    p.add_argument("--fail-if", action="append", default=[], metavar="EXPR",
                   help="exit 1 if a metric threshold holds, e.g. 'collisions>0' or "
                        "'qavg.min_ttc_s<1.5' (repeat, or separate with commas); checked on metrics.json")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    thresholds = parse_thresholds(args.fail_if) if args.fail_if else ()  # syntax errors before any work
    config = evaluation_config(args)
    with locked(config.out_dir):  # a second evaluate into the same folder fails at once (one line)
        plan = plan_evaluation(config)  # malformed files and specs before any work
        report = write_report(plan, run_plan(plan))
    return _print_report(report, plan.baselines, args.train_demos, thresholds)


def evaluation_config(args: argparse.Namespace) -> EvaluationConfig:
    """The :class:`~analysis.evaluation.config.EvaluationConfig` of ``merge-irl evaluate``'s
    arguments: ``--driver`` (and its aliases) then ``--policy`` as one driver spec list.

    Raises:
        AnalysisError: --executor with --workers, a spec that does not parse, or nothing to
            evaluate.
        SimError: an unknown baseline.
        PolicyError: a bad --policy spec.
    """
    executor = executor_from_args(args)
    apply_dask_options(args)
    baselines = tuple(b.strip() for b in args.baselines.split(",") if b.strip())
    check_baselines(baselines, "--baselines")
    if not args.driver and not args.policy and not baselines:
        raise AnalysisError("nothing to evaluate: give --driver, --policy and/or --baselines")
    scen = Path(args.scenario).stem if args.scenario.endswith(".toml") else args.scenario
    out = Path(args.out) if args.out else Path("runs") / f"evaluate-{scen}-{args.seed}"
    controller = ControllerConfig(decision_step_s=args.decision_step_s, mode=args.mode, safety_ttc_s=args.safety_ttc,
                                  high_brake=args.high_brake)
    return EvaluationConfig(
        args.scenario, args.episodes, args.seed, out, drivers=(*args.driver, *_callable_policies(args)),
        baselines=baselines, duration_s=args.duration, demos=_demos(args.demos), train_demos=args.train_demos,
        controller=controller, executor=executor, rrd=not args.no_rrd, progress=not args.no_progress,
        allow_implausible=args.allow_implausible, pairs=args.pairs, policy_weights=_policy_weights(args))


def _demos(paths: list[str] | None) -> str | tuple[str, ...] | None:
    """``--demos``: one path, or several read as one set."""
    return None if not paths else paths[0] if len(paths) == 1 else tuple(paths)


def _policy_weights(args: argparse.Namespace) -> tuple[str, ...]:
    """``--policy-weights``: files, each checked to exist (with ``--policy`` only)."""
    if args.policy_weights and not args.policy:
        raise AnalysisError("--policy-weights: give the --policy that loads them")
    for f in args.policy_weights:
        if not Path(f).is_file():
            raise AnalysisError(f"--policy-weights {f}: no such file")
    return tuple(args.policy_weights)


def _callable_policies(args: argparse.Namespace) -> list:
    """The ``--policy MODULE:CALLABLE[:NAME]`` drivers (``--policy-vecnormalize``, ``--policy-timeout``)."""
    if not args.policy:
        return []
    # discrete actions of a callable at the training frames' mean acceleration per bin, as the baselines'
    acc = training_action_acc(args.train_demos) if args.train_demos else CallablePolicy.action_acc_ft_s2
    limit = DEFAULT_DECISION_LIMIT_S if args.policy_timeout is None else check_limit(args.policy_timeout)
    return [CallablePolicy.from_spec(spec, action_acc_ft_s2=acc, obs_stats=args.policy_vecnormalize or "",
                                     timeout_s=limit) for spec in args.policy]


def _print_report(report, baselines: tuple[str, ...], train_demos, thresholds) -> int:
    print(report_table(report.aggregates))
    print("human likeness:")
    print(human_table(report.aggregates, report.demo_closeness, recorded=report.recorded))
    for line in flag_lines(report.aggregates):
        print(line, file=sys.stderr)
    left_out = left_out_baselines(baselines, train_demos)
    if left_out:
        print(f"note: {', '.join(left_out)} {'is' if len(left_out) == 1 else 'are'} left out without --train-demos",
              file=sys.stderr)
    print(f"report:  {report.report_md}")
    print(f"metrics: {report.metrics_json}")
    for name, path in report.rrd.items():
        print(f"rerun:   {path}  ({name}; open with: merge-irl view {path})")
    return gate(thresholds, report.metrics_json) if thresholds else 0
