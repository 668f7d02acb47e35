"""Independent IRL trials: each a pure function of (method, data, config, seed).

Two ways to run a batch:

- :func:`run_trial_spec` is the sweep task (``func(config, seed) -> dict``) that
  ``analysis.experiments.reproduce`` hands to :func:`analysis.sweep.run_sweep`: its config, a
  :class:`TrialSpec`, is small and picklable (table id, data directory, method, settings,
  trial seed, held-out fold); the worker process loads the table's data itself, once per
  process (:func:`cached_table_problem`), instead of receiving the 62 MB merge model per task.
- :func:`run_trials` runs in-memory :class:`TrialTask` objects with any order-preserving
  ``map_fn`` (serial ``map`` by default), for ad-hoc problems that are not one of the tables.
"""

from __future__ import annotations

import functools
import math
import os
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from analysis.experiments.learn import fit_problem
from irl.boltzmann import loglik_from_counts, step_counts
from irl.config import IRLConfig
from irl.errors import ConfigError, DemonstrationError
from irl.methods.reirl import DEFAULT_EPSILON
from irl.problems import Problem, load_problem


@dataclass(frozen=True)
class TrialTask:
    """One trial.

    Attributes:
        method: ``qavg | qsm | mlirl | reirl``.
        problem: the data set.
        config: IRL settings.
        seed: seed of the trial's ``numpy.random.Generator`` (theta's initialisation; REIRL's
            generated baseline).
        holdout: if set, the index of the trajectory left out: the fit uses the others and the
            outcome reports that trajectory's log-likelihood under the learned policy.
        epsilon: REIRL's L1 weight.
    """

    method: str
    problem: Problem
    config: IRLConfig
    seed: int
    holdout: int | None = None
    epsilon: float | None = DEFAULT_EPSILON


def _flags_of_message(d: dict) -> tuple[str, ...]:
    """The verdicts of an outcome stored before outcomes had ``flags``, from its converged and
    unbounded fields and the fit message (REIRL writes "INFEASIBLE" / "UNINFORMATIVE" into it)."""
    out = [] if d["converged"] else ["not_converged"]
    if d["unbounded"]:
        out.append("unbounded")
    out += [k for k in ("infeasible", "uninformative") if k.upper() in str(d["message"])]
    return tuple(out)


@dataclass(frozen=True)
class TrialOutcome:
    """What one trial produced (plain values: picklable and JSON-friendly)."""

    method: str
    seed: int
    holdout: int | None
    theta: tuple[float, ...]
    loglik: float
    heldout_loglik: float
    wall_time_s: float
    converged: bool
    unbounded: bool
    n_iterations: int
    message: str
    #: the fit's verdicts (:attr:`irl.result.FitResult.flags`: ``not_converged``, ``unbounded``,
    #: ``infeasible``, ``uninformative``)
    flags: tuple[str, ...] = ()

    def to_dict(self) -> dict:
        d = dict(self.__dict__)
        d["theta"] = list(self.theta)
        d["flags"] = list(self.flags)
        for key in ("loglik", "heldout_loglik"):
            if not math.isfinite(d[key]):
                d[key] = None
        return d

    @classmethod
    def from_dict(cls, d: dict) -> TrialOutcome:
        """Inverse of :meth:`to_dict` (None log-likelihoods back to NaN)."""
        def num(x) -> float:
            return float("nan") if x is None else float(x)

        return cls(
            method=str(d["method"]), seed=int(d["seed"]),
            holdout=None if d["holdout"] is None else int(d["holdout"]),
            theta=tuple(float(x) for x in d["theta"]), loglik=num(d["loglik"]),
            heldout_loglik=num(d["heldout_loglik"]), wall_time_s=float(d["wall_time_s"]),
            converged=bool(d["converged"]), unbounded=bool(d["unbounded"]),
            n_iterations=int(d["n_iterations"]), message=str(d["message"]),
            flags=tuple(str(f) for f in d["flags"]) if "flags" in d else _flags_of_message(d),
        )


@dataclass(frozen=True)
class TrialSpec:
    """A reproduction trial as a sweep task config (small, picklable, stable digest).

    Attributes:
        table: 1, 2 or 3 (the data set, see :func:`table_problem`).
        data_dir: the authors' data directory (absolute path string).
        method: ``qavg | qsm | mlirl | reirl``.
        config: IRL settings.
        trial: trial index ``j`` (0-based; for a held-out fold, the trial whose seed it uses).
        trial_seed: seed of the trial's generator (``trial_seeds(master, n)[j]``: the same for
            every method, so trials pair up across methods).
        holdout: index of the left-out trajectory, or None.
        epsilon: REIRL's L1 weight.
    """

    table: int
    data_dir: str
    method: str
    config: IRLConfig
    trial: int
    trial_seed: int
    holdout: int | None = None
    epsilon: float | None = DEFAULT_EPSILON

    @property
    def key(self) -> str:
        """Unique sweep key, e.g. ``table3/qsm/trial07`` or ``table1/qavg/holdout03``."""
        tail = f"trial{self.trial:02d}" if self.holdout is None else f"holdout{self.holdout:02d}"
        return f"table{self.table}/{self.method}/{tail}"


def resolve_data_dir(data_dir: str | os.PathLike) -> Path:
    """``data_dir`` itself if it holds ``gridworld/`` or ``merge_ngsim/``, else its ``railusm/``.

    Raises:
        DemonstrationError: the folder does not hold the authors' data layout (``gridworld/``,
            ``merge_ngsim/``).
    """
    d = Path(data_dir)
    if (d / "gridworld").is_dir() or (d / "merge_ngsim").is_dir():
        return d
    if (d / "railusm").is_dir():
        return d / "railusm"
    raise DemonstrationError(f"{d}: expected the authors' data layout (gridworld/, merge_ngsim/)")


def table_problem(table: int, data_dir: str | os.PathLike) -> Problem:
    """The data set of ``table`` (1, 2 or 3) under ``data_dir`` (the ``railusm`` layout).

    Raises:
        ConfigError: ``table`` is not 1, 2 or 3.
    """
    d = resolve_data_dir(data_dir)
    if table in (1, 2):
        noise = 0.0 if table == 1 else 0.1
        tag = f"noise_{noise:.1f}"
        return load_problem("gridworld", d / "gridworld" / f"{tag}_expert_trajs", noise=noise,
                            baseline_path=d / "gridworld" / f"{tag}_baseline_trajs",
                            name=f"gridworld {int(noise * 100)}% noise")
    if table == 3:
        return load_problem("merge", d / "merge_ngsim", name="NGSIM merge")
    raise ConfigError(f"table must be 1, 2 or 3, got {table}")


@functools.lru_cache(maxsize=4)
def cached_table_problem(table: int, data_dir: str) -> Problem:
    """:func:`table_problem`, loaded once per process (each sweep worker)."""
    return table_problem(table, data_dir)


def run_trial_spec(spec: TrialSpec, seed: int) -> dict:
    """Sweep task: run the trial ``spec`` describes and return ``TrialOutcome.to_dict()``.

    ``seed`` (the sweep's derived per-task seed) is not used: the trial's generator is seeded
    with ``spec.trial_seed``, shared by every method so the trials pair up (Wilcoxon test).
    """
    del seed
    problem = cached_table_problem(spec.table, spec.data_dir)
    task = TrialTask(spec.method, problem, spec.config, spec.trial_seed, holdout=spec.holdout,
                     epsilon=spec.epsilon)
    return run_trial(task).to_dict()


def run_trial(task: TrialTask) -> TrialOutcome:
    """Fit one trial (top-level function, so process pools can pickle it)."""
    problem = task.problem
    heldout = float("nan")
    if task.holdout is not None:
        keep = [i for i in range(problem.demos.n_trajectories) if i != task.holdout]
        train = problem.subset(keep)
    else:
        train = problem
    fit = fit_problem(train, task.method, task.config, task.seed, epsilon=task.epsilon)
    if task.holdout is not None:
        s = problem.demos.states[task.holdout]
        a = problem.demos.actions[task.holdout]
        counts = step_counts(s, a, problem.demos.n_states, problem.demos.n_actions)
        heldout = loglik_from_counts(fit.q, task.config.beta, counts)
    return TrialOutcome(
        method=task.method, seed=int(task.seed), holdout=task.holdout,
        theta=tuple(float(x) for x in np.asarray(fit.theta)), loglik=float(fit.loglik),
        heldout_loglik=float(heldout), wall_time_s=float(fit.wall_time_s), converged=bool(fit.converged),
        unbounded=bool(fit.unbounded), n_iterations=int(fit.n_iterations), message=fit.message,
        flags=tuple(fit.flags),
    )


def run_trials(
    tasks: Sequence[TrialTask],
    *,
    progress: bool = False,
    map_fn: Callable[[Callable, Iterable], Iterable] = map,
    description: str = "trials",
) -> list[TrialOutcome]:
    """Run ``tasks`` with ``map_fn(run_trial, tasks)`` (default: serial ``map``), in task order.

    Args:
        progress: show the progress on stderr (:func:`merge_irl.progress.progress_bar`: a bar on a
            terminal, lines elsewhere).
        map_fn: any order-preserving map, e.g. ``concurrent.futures.Executor.map``.
    """
    results = map_fn(run_trial, tasks)
    if progress:
        from merge_irl.progress import progress_bar

        results = progress_bar(len(tasks), desc=description, unit="trial", iterable=results)
    return list(results)


def trial_seeds(seed: int, n: int) -> list[int]:
    """``n`` independent trial seeds derived from one master ``seed`` (same for every method, so
    trials pair up across methods)."""
    children = np.random.SeedSequence(int(seed)).spawn(int(n))
    return [int(c.generate_state(1, dtype=np.uint64)[0] >> np.uint64(1)) for c in children]


def config_label(config: IRLConfig) -> str:
    return (f"gamma {config.gamma}, beta {config.beta}, alpha {config.alpha}, solver {config.solver}"
            + (f", l2 {config.l2}" if config.l2 else ""))
