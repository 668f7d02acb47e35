"""``merge-irl learn``: one IRL fit from the command line, saved as ``model.json``."""

from __future__ import annotations

import argparse
from dataclasses import replace

from analysis.cli.commands._arg_types import DeprecatedAlias
from analysis.cli.options import PROGRESS, demos_option, seed_option
from analysis.experiments.learn import learn, merge_config, merge_encoding, merge_features
from irl.config import SOLVERS, UNOBSERVED_RULES, IRLConfig
from irl.methods.registry import method_names  # names only: irl.fit loads scipy.optimize
from irl.methods.reirl import DEFAULT_EPSILON
from irl.problems import DOMAINS


def add_config_arguments(p: argparse.ArgumentParser) -> None:
    """The IRL settings shared by ``learn`` and ``reproduce``."""
    p.add_argument("--settings", choices=("paper", "reference"), default="paper",
                   help="base settings: the paper's (gamma .99, alpha .01) or the authors' code's "
                        "(gamma .9, alpha .1); the options below override them")
    p.add_argument("--gamma", type=float, help="discount factor")
    p.add_argument("--beta", type=float, help="Boltzmann inverse temperature")
    p.add_argument("--alpha", type=float, help="learning rate of the faithful Q sweep")
    p.add_argument("--solver", choices=SOLVERS, help="exact (default) or faithful (paper-literal)")
    p.add_argument("--l2", type=float, help="L2 penalty l2/2 ||theta||^2 (0 = none)")
    p.add_argument("--max-outer", type=int, help="cap on outer (gradient) iterations")
    p.add_argument("--unobserved", choices=UNOBSERVED_RULES,
                   help="Q-Avg/Q-SM: what a pair with no observed successor bootstraps from (irl.unobserved_successors): "
                        "terminal (Q = R, the paper's), self (its own state) or kinematic (the merge domain's "
                        "kinematic next state); default terminal, kinematic for learn on merge data (analysis.experiments.learn.merge_config)")


def config_from_args(args: argparse.Namespace) -> IRLConfig:
    base = IRLConfig.reference() if args.settings == "reference" else IRLConfig.paper()
    overrides = {name: getattr(args, name) for name in ("gamma", "beta", "alpha", "solver", "l2", "max_outer",
                                                        "unobserved")
                 if getattr(args, name, None) is not None}
    return replace(base, **overrides)


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "learn", parents=[demos_option(
            "trajectories (merge encounter tables: several files or runs, kept apart): a directory/file in the "
            "authors' text format (gridworld, merge), an encounter table .parquet/.csv (merge), or a .npz (npz)",
            required=True), seed_option("seed of the fit's random numbers (initial weights, generated baselines)"), PROGRESS],
        description="Fit one IRL method on tabular demonstrations and save the result as model.json "
                    "(theta, loglik, q, settings, merge bin edges).")
    p.add_argument("--method", choices=method_names(), required=True)
    p.add_argument("--domain", choices=DOMAINS, required=True)
    p.add_argument("--noise", type=float, default=0.0, help="gridworld slip probability of the true model")
    p.add_argument("--baseline", help="REIRL baseline trajectories (same format as --demos); "
                                      "default: uniform-random ones generated under the model")
    p.add_argument("--bins", help="merge: JSON file of bin edges (default: assumed edges for text files, "
                                  "quantile bins fitted on an encounter table)")
    p.add_argument("--decision-step-s", dest="decision_step_s", type=float, default=None,
                   help="merge: decision step (s) the encounters are resampled at and the kinematic fallback uses "
                        "(default: the merge domain's, 0.3 for encounter tables; the authors' text files are at "
                        "their 0.1 s frame)")
    # the older spelling of --decision-step-s: one release more, with a note
    p.add_argument("--dt", dest="decision_step_s", type=float, action=DeprecatedAlias, use="--decision-step-s")
    p.add_argument("--features", choices=("paper", "driver"), default=None,
                   help="merge feature set (default: driver for encounter tables, paper for the authors' files); "
                        "driver also puts A's previous action in the state")
    p.add_argument("--unvisited", choices=("none", "nearest"), default="none",
                   help="merge: policy in states never seen in training (irl.unvisited_states)")
    p.add_argument("--epsilon", type=float, default=None, help="REIRL L1 weight of the dual (default: per feature, the "
                                                           "Hoeffding bound of the experts' feature-count estimate)")
    add_config_arguments(p)
    p.add_argument("--out", required=True, help="model.json to write")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    config = config_from_args(args)
    features = args.features
    if args.domain == "merge":  # the merge defaults: irl.problems.DOMAINS['merge'].defaults
        config = merge_config(config, beta=args.beta, l2=args.l2, method=args.method, unobserved=args.unobserved)
        features = merge_features(args.demos, features)
    model = learn(
        args.method, args.domain, args.demos, config=config, seed=args.seed,
        noise=args.noise, baseline_path=args.baseline, bins=args.bins or None, decision_step_s=args.decision_step_s,
        epsilon=DEFAULT_EPSILON if args.epsilon is None else args.epsilon,
        out=args.out, progress=not args.no_progress,
        encoding=merge_encoding(features), features=features, unvisited=args.unvisited,
    )
    theta = ", ".join(f"{n or k}={t:.4g}" for k, (n, t) in enumerate(
        zip(model.feature_names or [""] * len(model.theta), model.theta)))
    flags = []
    if not model.converged:
        flags.append("NOT converged")
    if model.unbounded:
        hint = "raise --epsilon" if model.method == "reirl" else "try --l2"
        flags.append(f"unbounded (weights grow without limit; {hint})")
    print(f"{model.method}: loglik {model.loglik:.4f}  theta [{theta}]"
          f"{'  (' + '; '.join(flags) + ')' if flags else ''}")
    print(f"  {model.info.get('message', '')}")
    print(f"  wrote {args.out}")
    return 0
