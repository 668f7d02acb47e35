"""One IRL fit from files to a saved ``model.json`` (the API behind ``merge-irl learn``).

Example::

    from irl.config import IRLConfig
    from analysis.learn import learn

    model = learn("qavg", "gridworld", "data/railusm/gridworld/noise_0.0_expert_trajs",
                  config=IRLConfig.paper(), seed=0, out="model.json")
    print(model.theta, model.loglik)
"""

from __future__ import annotations

import math
from collections.abc import Sequence
import os
from pathlib import Path

import numpy as np

from analysis.problem import Problem, load_problem
from irl.config import IRLConfig
from irl.errors import ConfigError, ConvergenceError
from irl.merge_mdp import MergeBins
from irl.reirl import DEFAULT_EPSILON, DEFAULT_N_BASELINE, fit_reirl
from irl.result import METHODS, FitResult, SavedModel


def fit_problem(
    problem: Problem,
    method: str,
    config: IRLConfig,
    seed: int,
    *,
    progress: bool = False,
    epsilon: float = DEFAULT_EPSILON,
    n_baseline: int = DEFAULT_N_BASELINE,
) -> FitResult:
    """Fit ``method`` on ``problem`` with ``numpy.random.default_rng(seed)``.

    Q-Avg and Q-SM see only the demonstrations; MLIRL gets ``problem.transitions``; REIRL gets
    the transitions (for its baseline and final log-likelihood), the baseline and the padding
    rule of the domain. A pure function of its arguments.
    """
    if method not in METHODS:
        raise ConfigError(f"method must be one of {METHODS}, got {method!r}")
    rng = np.random.default_rng(seed)
    if method == "reirl":
        return fit_reirl(problem.demos, config, rng, baseline=problem.baseline, transitions=problem.transitions,
                         epsilon=epsilon, n_baseline=n_baseline, pad_step=problem.pad_step(), progress=progress)
    from irl.fit import fit

    transitions = problem.transitions if method == "mlirl" else None
    return fit(method, problem.demos, config, rng, transitions=transitions, progress=progress)


def _json_scalar(v):
    """A JSON-safe scalar: finite numbers as float, anything else as text."""
    try:
        x = float(v)
    except (TypeError, ValueError):
        return str(v)
    return x if math.isfinite(x) else str(x)


def saved_model(fit: FitResult, problem: Problem, *, seed: int, source: str = "") -> SavedModel:
    """The ``model.json`` record of ``fit`` on ``problem``."""
    info = {
        "demos": source or problem.name,
        "seed": int(seed),
        "n_trajectories": problem.demos.n_trajectories,
        "n_steps": problem.demos.n_steps,
        "n_states": problem.demos.n_states,
        "n_actions": problem.demos.n_actions,
        "message": fit.message,
        "wall_time_s": float(fit.wall_time_s),
        "n_iterations": fit.n_iterations,
        "extra": {str(k): _json_scalar(v) for k, v in fit.extra.items()},
        "loglik_note": "Eq. 5 sum of log pi(a_t|s_t) without log Pr(s_1)",
    }
    if problem.domain == "gridworld":
        info["noise"] = problem.noise
    if problem.domain == "merge":
        info["dt"] = problem.dt
    return SavedModel.from_fit(
        fit,
        domain=problem.domain,
        feature_names=tuple(problem.feature_names),
        bin_edges={k: tuple(v) for k, v in problem.bins.to_dict().items()} if problem.bins else {},
        info=info,
    )


def learn(
    method: str,
    domain: str,
    demos_path: str | os.PathLike | Sequence[str | os.PathLike],
    *,
    config: IRLConfig | None = None,
    seed: int = 0,
    noise: float = 0.0,
    baseline_path: str | os.PathLike | None = None,
    bins: MergeBins | None = None,
    dt: float = 0.1,
    epsilon: float = DEFAULT_EPSILON,
    out: str | os.PathLike | None = None,
    progress: bool = False,
) -> SavedModel:
    """Load ``demos_path`` as ``domain``, fit ``method``, and (if ``out``) save ``model.json``.

    See :func:`analysis.problem.load_problem` for the domains and :func:`fit_problem` for what
    each method sees. Returns the saved record (theta, loglik, q, settings, merge bin edges).
    """
    config = config or IRLConfig.paper()
    problem = load_problem(domain, demos_path, noise=noise, baseline_path=baseline_path, bins=bins, dt=dt)
    result = fit_problem(problem, method, config, seed, progress=progress, epsilon=epsilon)
    if not math.isfinite(result.loglik):
        raise ConvergenceError(f"{method} on {problem.name}: the fit failed ({result.message}); no model written")
    model = saved_model(result, problem, seed=seed, source=problem.name)
    if out is not None:
        model.save(out)
    return model
