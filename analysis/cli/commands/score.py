"""``merge-irl score``: the log-likelihood of any demonstrations under a saved model (several
``--demos`` are scored as one set: the sums over them)."""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any

from analysis.cli.options import demos_option
from irl.baselines import TabularPolicy
from irl.domains.merge.bins import MergeBins
from irl.errors import DemonstrationError, ModelFileError
from irl.problems import DOMAINS, load_problem
from irl.result import SavedModel
from merge_irl.json_file import read_json_object
from sim.drivers.formats import check_role_of


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "score", parents=[demos_option(
            "trajectories in a format of --domain: the authors' text files (gridworld, merge), an encounter "
            "table .parquet/.csv (merge) or a .npz (npz); several are scored as one set", required=True)],
        description="Score demonstrations under a saved model's policy softmax(beta Q): print the total "
                    "log-likelihood sum_t log pi(a_t|s_t) (paper Eq. 5 without log Pr(s_1)) and the number "
                    "of steps. Merge encounter tables are discretized with the model's bin edges.")
    p.add_argument("--model", required=True, metavar="MODEL.json", help="a model saved by 'merge-irl learn'")
    p.add_argument("--domain", choices=DOMAINS, default=None,
                   help="how to read --demos (default: the model's domain)")
    p.add_argument("--json", action="store_true",
                   help="print one JSON object (keys loglik, n_steps, n_trajectories, loglik_per_step, ...)")
    p.set_defaults(func=run)


def score(model, demos_path: str, domain: str | None = None) -> dict:
    """Score ``demos_path`` under ``model``.

    Args:
        model: a :class:`irl.result.SavedModel`.
        domain: one of ``DOMAINS``; default ``model.domain``.

    Returns:
        ``{"loglik", "n_steps", "n_trajectories", "loglik_per_step", "trajectory_logliks",
        "method", "converged", "unbounded"}`` (log-likelihoods in nats).

    Raises:
        DemonstrationError: no domain known, or the demonstrations' state/action counts differ
            from the model's Q table.
    """
    domain = domain or model.domain
    if domain not in DOMAINS:
        raise DemonstrationError(f"{demos_path}: the model names no domain ({model.domain!r}); "
                                 f"pass --domain, one of {DOMAINS}")
    bins = MergeBins.from_dict(model.bin_edges, where="model bin_edges") if domain == "merge" and model.bin_edges \
        else None
    # merge: the model's decision step and state encoding (features only shape the demonstrations, not the score)
    kw: dict[str, Any] = {"bins": bins, "decision_step_s": model.decision_step_s, "encoding": model.state_encoding,
                          "features": model.feature_set if model.feature_set in ("paper", "driver") else None
                          } if domain == "merge" else {}
    if domain == "gridworld":
        kw["noise"] = _info_number(model, "noise", 0.0)
    demos = load_problem(domain, demos_path, **kw).demos
    per_traj = TabularPolicy(model.method, model.log_policy()).trajectory_logliks(demos)
    total = float(per_traj.sum())
    return {"loglik": total, "n_steps": demos.n_steps, "n_trajectories": demos.n_trajectories,
            "loglik_per_step": total / demos.n_steps, "trajectory_logliks": [float(x) for x in per_traj],
            "method": model.method, "converged": bool(model.converged), "unbounded": bool(model.unbounded)}


def merged(results: list[dict]) -> dict:
    """One :func:`score` result for several demonstration sets scored under the same model (the
    sums of their log-likelihoods, steps and trajectories; the trajectories in order): the score
    of their union, since the model fixes the state bins. ``results``: at least one."""
    if len(results) == 1:
        return results[0]
    first = results[0]
    loglik = float(sum(r["loglik"] for r in results))
    n_steps = sum(r["n_steps"] for r in results)
    return {**first, "loglik": loglik, "n_steps": n_steps,
            "n_trajectories": sum(r["n_trajectories"] for r in results), "loglik_per_step": loglik / n_steps,
            "trajectory_logliks": [x for r in results for x in r["trajectory_logliks"]]}


def _info_number(model, key: str, default: float) -> float:
    value = model.info.get(key, default)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ModelFileError(f"model field 'info.{key}' must be a finite number, got {value!r}")
    return float(value)


def run(args: argparse.Namespace) -> int:
    data = read_json_object(args.model, what="model file", error=ModelFileError)  # the one read of the file
    check_role_of(data, args.model, "model", option="--model")  # a driver's file: say which command takes it
    model = SavedModel.from_json_dict(data, Path(args.model))
    result = merged([score(model, path, args.domain) for path in args.demos])
    if args.json:
        print(json.dumps({k: (v if not isinstance(v, float) or math.isfinite(v) else None)
                          for k, v in result.items()}))
        return 0
    flags = [f for f, on in (("NOT converged", not result["converged"]),
                             ("unbounded", result["unbounded"])) if on]
    print(f"{Path(args.model).name} ({model.method}) on {', '.join(args.demos)}: loglik {result['loglik']:.4f} over "
          f"{result['n_steps']} steps in {result['n_trajectories']} trajectories "
          f"({result['loglik_per_step']:.4f} per step)" + (f"  [model {'; '.join(flags)}]" if flags else ""))
    return 0
