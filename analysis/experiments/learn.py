"""One IRL fit from files to a saved ``model.json`` (the API behind ``merge-irl learn``).

Example::

    from irl.config import IRLConfig
    from analysis.experiments.learn import learn

    model = learn("qavg", "gridworld", "data/railusm/gridworld/noise_0.0_expert_trajs",
                  config=IRLConfig.paper(), seed=0, out="model.json")
    print(model.theta, model.loglik)
"""

from __future__ import annotations

import contextlib
import math
import os
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np

from irl.config import IRLConfig
from irl.domains.merge.bins import MergeBins
from irl.errors import ConvergenceError
from irl.fit import fit
from irl.methods.registry import get_method
from irl.methods.reirl import DEFAULT_EPSILON, DEFAULT_N_BASELINE
from irl.problems import DOMAINS, Problem, load_problem
from irl.result import FitResult, SavedModel
from irl.unvisited_states import apply_unvisited_rule, visited_states
from merge_irl.provenance import provenance as provenance_record
from merge_irl.provenance import write_timings
from merge_irl.run_folder import check_writable, locked
from merge_irl.tables import is_parquet_dataset


def merge_config(base: IRLConfig | None = None, *, beta: float | None = None, l2: float | None = None,
                 gamma: float | None = None, method: str | None = None, unobserved: str | None = None) -> IRLConfig:
    """The IRL settings of a merge fit on encounter tables: ``base`` (default the paper's) with
    the merge domain's beta and L2 (``irl.problems.DOMAINS["merge"].defaults``, their one home),
    unless ``beta`` / ``l2`` are given; ``gamma`` (None: ``base``'s) overrides the discount;
    ``unobserved`` (None: the domain's default when ``method`` is Q-Avg or Q-SM with the exact
    solver, else ``base``'s) the rule for pairs with no observed successor
    (:mod:`irl.unobserved_successors`). What ``merge-irl learn`` and ``merge-irl demo`` use.

    Raises:
        ConfigError: a value :class:`irl.config.IRLConfig` rejects.
    """
    base = base or IRLConfig.paper()
    d = DOMAINS["merge"].defaults
    cfg = replace(base, beta=base.beta if d.beta is None else d.beta, l2=base.l2 if d.l2 is None else d.l2)
    if beta is not None:
        cfg = replace(cfg, beta=float(beta))
    if l2 is not None:
        cfg = replace(cfg, l2=float(l2))
    if gamma is not None:
        cfg = replace(cfg, gamma=float(gamma))
    if unobserved is not None:
        return replace(cfg, unobserved=unobserved)
    if method in ("qavg", "qsm") and cfg.solver == "exact" and d.unobserved is not None:
        return replace(cfg, unobserved=d.unobserved)
    return cfg


def merge_features(demos_paths, features: str | None = None) -> str:
    """The merge feature set name: ``features`` if given, else ``"paper"`` for the authors' text
    trajectories (a folder or ``.txt``) and ``"driver"`` for encounter tables (the paper's three cannot tell persistence from safety)."""
    if features is not None:
        return features
    paths = [demos_paths] if isinstance(demos_paths, (str, os.PathLike)) else list(demos_paths)
    text = [d for d in paths if (Path(d).is_dir() and not is_parquet_dataset(d)) or Path(d).suffix == ".txt"]
    return "paper" if text else "driver"


def merge_encoding(features) -> str:
    """The state encoding that goes with a feature set: ``"driver"`` (A's previous action in the
    state) for the driver features, else the paper's."""
    return "driver" if features == "driver" else "paper"


def fit_problem(
    problem: Problem,
    method: str,
    config: IRLConfig,
    seed: int,
    *,
    progress: bool = False,
    epsilon: float | None = DEFAULT_EPSILON,
    n_baseline: int = DEFAULT_N_BASELINE,
) -> FitResult:
    """Fit ``method`` on ``problem`` with ``numpy.random.default_rng(seed)``.

    What the method gets from the problem besides the demonstrations is the registry's to say
    (:attr:`irl.methods.registry.Method.needs_transitions`, ``problem_options``): Q-Avg and Q-SM
    see only the demonstrations (and, with ``config.unobserved == "kinematic"``, the domain's
    kinematic successors at the problem's decision step); MLIRL gets ``problem.transitions``;
    REIRL gets the transitions (for its baseline and final log-likelihood), the baseline and the
    padding rule of the domain. A pure function of its arguments.

    Raises:
        ConfigError: ``method`` is not a registered method (:data:`irl.fit.REGISTRY`).
        DemonstrationError, ConvergenceError: from the method (see :func:`irl.fit.fit`).
    """
    options = get_method(method).options_for(problem, config, epsilon=epsilon, n_baseline=n_baseline)
    return fit(method, problem.demos, config, np.random.default_rng(seed), transitions=problem.transitions,
               progress=progress, **options)


def _json_scalar(v):
    """A JSON-safe scalar: finite numbers as float, anything else as text."""
    try:
        x = float(v)
    except (TypeError, ValueError):
        return str(v)
    return x if math.isfinite(x) else str(x)


def saved_model(fit: FitResult, problem: Problem, *, seed: int, source: str = "",
                provenance: dict | None = None, unvisited: str = "none") -> SavedModel:
    """The ``model.json`` record of ``fit`` on ``problem``.

    It holds no wall-clock time (``fit.wall_time_s`` goes to a timings file, see
    :func:`merge_irl.provenance.write_timings`), so identical fits give identical files;
    ``provenance`` (:func:`merge_irl.provenance.provenance`) goes to ``info["provenance"]``.
    """
    info = {
        "demos": source or problem.name,
        "seed": int(seed),
        "n_trajectories": problem.demos.n_trajectories,
        "n_steps": problem.demos.n_steps,
        "n_states": problem.demos.n_states,
        "n_actions": problem.demos.n_actions,
        "message": fit.message,
        "n_iterations": fit.n_iterations,
        "extra": {str(k): _json_scalar(v) for k, v in fit.extra.items()},
        "loglik_note": "Eq. 5 sum of log pi(a_t|s_t) without log Pr(s_1)",
    }
    if problem.domain == "gridworld":
        info["noise"] = problem.noise
    if problem.domain == "merge":
        info["dt"] = problem.decision_step_s  # kept for readers of older files; the field is decision_step_s
    if provenance is not None:
        info["provenance"] = provenance
    merge = problem.domain == "merge"
    q = fit.q
    if merge and unvisited != "none":
        q = apply_unvisited_rule(fit.q, visited_states(problem.demos), unvisited)
    return SavedModel(
        method=fit.method, theta=np.asarray(fit.theta), loglik=fit.loglik, q=np.asarray(q), config=fit.config,
        converged=fit.converged, unbounded=fit.unbounded,
        state_encoding=problem.state_encoding if merge else "paper",
        decision_step_s=float(problem.decision_step_s),
        action_acc_ft_s2=tuple(problem.action_acc_ft_s2),
        feature_set=problem.feature_set if merge else "",
        unvisited_rule=unvisited if merge else "none",
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
    bins: MergeBins | str | os.PathLike | None = None,
    decision_step_s: float | None = None,
    epsilon: float | None = DEFAULT_EPSILON,
    out: str | os.PathLike | None = None,
    progress: bool = False,
    encoding: str = "paper",
    features=None,
    unvisited: str = "none",
) -> SavedModel:
    """Load ``demos_path`` as ``domain``, fit ``method``, and (if ``out``) save ``model.json``.

    See :func:`irl.problems.load_problem` for the domains and :func:`fit_problem` for what
    each method sees. ``bins``: merge bin edges, or the JSON file holding them. Returns the
    saved record (theta, loglik, q, settings, merge bin edges, provenance: versions and the
    SHA-256 of every input file). With ``out``, the fit's wall time goes to
    ``<out stem>.timings.json`` beside it, not into ``model.json``: identical runs write
    identical model files.

    Merge options: ``decision_step_s`` the decision step (s) the encounters are resampled at (default 0.3
    s; 0.1 for the authors' text files), ``encoding`` ``"paper"`` or ``"driver"`` (A's previous
    action in the state), ``features`` a set name (``"paper"``, ``"driver"``), a tuple of names
    or your own :class:`irl.domains.merge.features.FeatureSet`, ``unvisited`` the rule for
    states never seen in training (:mod:`irl.unvisited_states`). Each is recorded in ``model.json``
    (``decision_step_s``, ``state_encoding``, ``feature_set`` + ``feature_names``,
    ``unvisited_rule``), with ``action_acc_ft_s2``, the training data's mean acceleration per
    action.

    Raises:
        ConfigError: unknown ``domain`` or ``method``.
        DemonstrationError: ``demos_path`` is missing or not a valid trajectory/encounter file.
        ConvergenceError: the fit failed; no model is written.
        OSError: ``out`` cannot be written (checked before loading and fitting).
        OutputLockedError: another run is writing ``out`` (it holds ``.NAME.lock`` beside it,
            :func:`merge_irl.run_folder.locked`, for the whole load, fit and save); nothing is
            written.
    """
    if out is not None:
        check_writable(out)  # an unwritable --out fails now, not after the fit
    # a second run into the same --out fails at once, as generate's does (nothing is lost)
    with locked(out, what="file") if out is not None else contextlib.nullcontext():
        config = config or IRLConfig.paper()
        bins_path = None
        if bins is not None and not isinstance(bins, MergeBins):
            bins_path, bins = bins, MergeBins.load(bins)
        problem = load_problem(domain, demos_path, noise=noise, baseline_path=baseline_path, bins=bins, decision_step_s=decision_step_s,
                               encoding=encoding, features=features)
        demos_list = [demos_path] if isinstance(demos_path, (str, os.PathLike)) else list(demos_path)
        inputs = {("demos" if len(demos_list) == 1 else f"demos{i}"): p for i, p in enumerate(demos_list, start=1)}
        prov = provenance_record({**inputs, "baseline": baseline_path, "bins": bins_path})
        result = fit_problem(problem, method, config, seed, progress=progress, epsilon=epsilon)
        if not math.isfinite(result.loglik):
            raise ConvergenceError(f"{method} on {problem.name}: the fit failed ({result.message}); no model written")
        model = saved_model(result, problem, seed=seed, source=problem.name, provenance=prov, unvisited=unvisited)
        if out is not None:
            model.save(out)
            write_timings(out, {"fit_wall_time_s": float(result.wall_time_s)})
        return model
