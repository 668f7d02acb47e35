"""IRL problems: demonstrations plus everything a method needs beside them.

A :class:`Problem` bundles the expert demonstrations, the transition model that MLIRL and REIRL's
final log-likelihood use (the true model, or one estimated from the demonstrations), optional
REIRL baseline trajectories, and the merge bin edges. ``load_problem`` builds one from files for
each domain of :data:`DOMAINS` (``gridworld``, ``merge``, ``npz``): a :class:`Domain` carries its
loader, its model estimation, its padding and fallback rules, and its default settings
(:class:`DomainDefaults`, the domain's one default decision step among them).
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pandas as pd

from irl.demonstrations import Demonstrations
from irl.domains import gridworld
from irl.domains.merge import mdp as merge_mdp
from irl.domains.merge.actions import ACTION_ACC_FT_S2
from irl.domains.merge.bins import MergeBins, fit_quantile_bins
from irl.domains.merge.features import FeatureSet, feature_set
from irl.errors import ConfigError, DemonstrationError
from irl.io import load_feature_names, load_npz
from irl.transitions import SuccessorModel, TransitionModel, estimate_transitions, model_successors
from merge_irl.registry import Registry, RegistryError
from merge_irl.tables import is_parquet_dataset
from merge_irl.units import FRAME_S


@dataclass(frozen=True)
class Problem:
    """One IRL data set, ready for every method (picklable).

    Attributes:
        name: short label (``"gridworld 0%"``, a path, ...).
        domain: a key of :data:`DOMAINS`.
        demos: the expert demonstrations.
        transitions: ``[S, A, S]`` model for MLIRL and for REIRL's final log-likelihood;
            :func:`load_problem` stores it sparse (:class:`~irl.transitions.SuccessorModel`,
            ``.to_dense()`` gives the array); a dense array works too.
        transitions_estimated: whether ``transitions`` were estimated from ``demos`` (then a
            subset of the trajectories re-estimates them, so held-out data never leaks in).
        baseline: REIRL baseline trajectories, or None (REIRL then generates uniform-random ones
            under ``transitions``).
        feature_names: ``K`` names.
        bins: merge state bin edges (merge domain only).
        decision_step_s: seconds per decision (merge: the resampling of the encounters, the step
            of the kinematic fallback and of REIRL's padding).
        noise: gridworld slip probability.
        state_encoding: merge state encoding (``"paper"`` or ``"driver"``).
        feature_set: merge feature set name (``"paper"``, ``"driver"``, ``"custom"``).
        action_acc_ft_s2: ``[5]`` per-action mean acceleration of the training data (merge
            encounter tables), else the bin midpoints.
    """

    name: str
    domain: str
    demos: Demonstrations
    transitions: TransitionModel
    transitions_estimated: bool = False
    baseline: Demonstrations | None = None
    feature_names: tuple[str, ...] = ()
    bins: MergeBins | None = None
    decision_step_s: float = FRAME_S
    noise: float = 0.0
    state_encoding: str = "paper"
    feature_set: str = "paper"
    action_acc_ft_s2: tuple[float, ...] = tuple(ACTION_ACC_FT_S2)

    @property
    def domain_spec(self) -> Domain:
        """The :class:`Domain` of this problem."""
        return DOMAINS[self.domain]

    def subset(self, indices) -> Problem:
        """The same problem on the trajectories at ``indices`` (model re-estimated if estimated)."""
        demos = self.demos.subset(indices)
        transitions = self.domain_spec.estimate_model(demos, self) if self.transitions_estimated else self.transitions
        return replace(self, demos=demos, transitions=transitions)

    def pad_step(self) -> Callable[[int], tuple[int, int]] | None:
        """REIRL's padding rule, the domain's (constant velocity for merge; None: repeat the last pair)."""
        return self.domain_spec.pad_step(self)


@dataclass(frozen=True)
class DomainDefaults:
    """A domain's default settings.

    Attributes:
        decision_step_s: the one default decision step of the domain (s): merge encounter tables
            are resampled at it and a driver without its own step decides at it.
        beta, l2: the IRL settings of fits on the domain (None: the base configuration's).
        unobserved: Q-Avg's and Q-SM's rule for pairs with no observed successor with the exact
            solver (None: the base configuration's; :mod:`irl.unobserved_successors`).
    """

    decision_step_s: float = FRAME_S
    beta: float | None = None
    l2: float | None = None
    unobserved: str | None = None


def _no_rule(problem: Problem) -> None:
    return None


@dataclass(frozen=True)
class Domain:
    """One IRL domain: how its problems are loaded and what the methods get from them.

    Attributes:
        name: the key in :data:`DOMAINS` (``--domain`` on the command line).
        load: ``load(paths [list], *, noise, baseline_path, bins, decision_step_s, name, encoding,
            features) -> Problem``.
        estimate_model: ``(demos, problem) -> SuccessorModel``, the relative-count model of
            ``demos`` with the domain's rule for pairs never seen.
        pad_step: ``problem -> PadStep | None``, REIRL's padding (None: repeat the last pair).
        fallback_next: ``problem -> [S, A] int | None``, the next states Q-Avg and Q-SM bootstrap
            from at pairs with no observed successor under ``unobserved = "kinematic"``.
        defaults: the domain's default settings.
    """

    name: str
    load: Callable[..., Problem]
    estimate_model: Callable[[Demonstrations, Problem], SuccessorModel]
    pad_step: Callable[[Problem], Callable[[int], tuple[int, int]] | None] = _no_rule
    fallback_next: Callable[[Problem], np.ndarray | None] = _no_rule
    defaults: DomainDefaults = DomainDefaults()


def model_free_options(problem: Problem, config, **settings) -> dict:
    """Q-Avg's and Q-SM's options from ``problem``: the domain's kinematic successors as
    ``fallback_next`` when ``config.unobserved == "kinematic"`` and the domain has them (the
    method registry's ``problem_options`` of both)."""
    if config.unobserved != "kinematic":
        return {}
    nxt = problem.domain_spec.fallback_next(problem)
    return {} if nxt is None else {"fallback_next": nxt}


def _is_text_format(path: Path) -> bool:
    """The authors' text format: a ``.txt`` file or a folder of them (a folder of Parquet part
    files is an encounter table)."""
    return (path.is_dir() and not is_parquet_dataset(path)) or path.suffix == ".txt"


def load_merge_demos(path: str | os.PathLike | Sequence[str | os.PathLike], bins: MergeBins | None, *,
                     encoding: str = "paper", features=None, decision_step_s: float | None = None
                     ) -> tuple[Demonstrations, MergeBins, FeatureSet, tuple[float, ...], float]:
    """Merge demonstrations from the authors' text files (state indices as they are; ``bins``
    default to ``MergeBins.assumed_authors()``; their 0.1 s steps cannot be resampled, so
    ``decision_step_s`` must be None or 0.1; the driver encoding takes the previous action from
    the sequence) or from encounter tables (``.parquet``/``.csv``; ``bins`` default to quantile
    bins fitted on all of them; resampled at ``decision_step_s``, default 0.3 s). Several tables
    (files or runs) keep their encounters apart even where encounter ids repeat: each file's
    trajectories are named ``<file>: encounter <id>``.

    Args:
        features: a feature set name, a tuple of names or a :class:`FeatureSet`; None: the
            paper's three.

    Returns:
        ``(demos, bins, feature set, per-action acceleration [5] ft/s^2, decision step s)``; with
        several tables the per-action acceleration is over all of them.

    Raises:
        DemonstrationError: a path is missing or bad, or several paths include text-format ones.
        ConfigError: bad encoding/features/step.
    """
    paths = [Path(p) for p in ([path] if isinstance(path, (str, os.PathLike)) else path)]
    if not paths:
        raise DemonstrationError("no demonstrations given")
    for p in paths:
        if not p.exists():
            raise DemonstrationError(f"{p}: no such file or directory")
    if len(paths) == 1 and _is_text_format(paths[0]):
        if decision_step_s not in (None, FRAME_S):
            raise ConfigError(f"{paths[0]}: the authors' trajectories are 0.1 s steps and cannot be resampled "
                              f"at {decision_step_s} s")
        bins = bins or MergeBins.assumed_authors()
        fs = feature_set(features or "paper", bins, encoding, decision_step_s=FRAME_S)
        demos = merge_mdp.load(paths[0])
        if encoding == "driver":
            demos = merge_mdp.driver_encoded(demos, fs.array)
        else:
            demos = replace(demos, features=fs.array)
        return demos, bins, fs, tuple(ACTION_ACC_FT_S2), FRAME_S
    text = [str(p) for p in paths if _is_text_format(p)]
    if text:
        raise DemonstrationError(f"{text[0]}: several demonstration sources must all be encounter tables "
                                 "(.parquet/.csv); the authors' text format is read alone")
    step = merge_mdp.DEFAULT_DECISION_STEP_S if decision_step_s is None else decision_step_s
    tables = [merge_mdp.read_encounters(p) for p in paths]
    for p, t in zip(paths, tables):
        _warn_raw_accelerations(t, p)
    where = ", ".join(str(p) for p in paths)
    joined = pd.concat(tables, ignore_index=True) if len(tables) > 1 else tables[0]
    bins = bins or fit_quantile_bins(joined, where=where)
    fs = feature_set(features or "paper", bins, encoding, decision_step_s=step)
    if len(tables) == 1:
        r = merge_mdp.resample_encounters(tables[0], bins, where=where, encoding=encoding, decision_step_s=step,
                                          features=fs)
        return r.demos, bins, fs, r.action_acc_ft_s2, step
    parts = [merge_mdp.resample_encounters(t, bins, where=str(p), encoding=encoding, decision_step_s=step,
                                           features=fs) for p, t in zip(paths, tables)]
    demos = replace(
        parts[0].demos, states=tuple(s for r in parts for s in r.demos.states),
        actions=tuple(a for r in parts for a in r.demos.actions), source=where,
        names=tuple(f"{p}: {n}" for p, r in zip(paths, parts) for n in r.demos.names),
    )
    # the per-action mean acceleration over all tables, weighted by their decisions
    acc = merge_mdp.resample_encounters(joined, bins, where=where, encoding=encoding, decision_step_s=step,
                                        features=fs).action_acc_ft_s2
    return demos, bins, fs, acc, step


#: Accelerations beyond this (ft/s^2, 2x NGSIM's 11.2 cap, about 0.7 g) are not driving but noise,
#: and more than :data:`RAW_ACC_SHARE` of rows beyond it marks raw, unsmoothed speeds.
RAW_ACC_FT_S2 = 22.4
RAW_ACC_SHARE = 0.05


class RawAccelerationWarning(UserWarning):
    """Encounters whose acc_A looks like the difference of raw, unsmoothed NGSIM speeds."""


def _warn_raw_accelerations(table: pd.DataFrame, path: Path) -> None:
    """Warn when more than :data:`RAW_ACC_SHARE` of ``acc_A`` lies beyond :data:`RAW_ACC_FT_S2`.

    ``acc_A`` is the forward difference of A's speed over one 0.1 s frame, so the noise of raw
    NGSIM speeds shows as accelerations no driver produces (the noisy field case: 65 % of rows
    beyond 22.4 ft/s^2; smoothed, or simulated by SUMO: none or a few emergency stops).
    """
    if "acc_A" not in table.columns or len(table) == 0:
        return
    acc = pd.to_numeric(table["acc_A"], errors="coerce").to_numpy(dtype=np.float64)
    share = float(np.mean(np.abs(acc) > RAW_ACC_FT_S2))
    if share > RAW_ACC_SHARE:
        warnings.warn(
            f"{path}: column acc_A: {share:.0%} of rows beyond +-{RAW_ACC_FT_S2} ft/s^2 (0.7 g): raw, unsmoothed "
            "speeds, whose noise becomes the action labels (hard brake / hard accel); extract the "
            "encounters with `merge-irl encounters --smooth`", RawAccelerationWarning, stacklevel=3)


def _load_gridworld(paths: list, *, noise: float, baseline_path, decision_step_s: float | None, name: str,
                    **_: object) -> Problem:
    demos = gridworld.load(paths[0])
    baseline = gridworld.load(baseline_path) if baseline_path is not None else None
    step = FRAME_S if decision_step_s is None else decision_step_s  # the step is not resampled
    return Problem(name, "gridworld", demos, model_successors(gridworld.transition_model(noise)), False, baseline,
                   gridworld.FEATURE_NAMES, None, step, noise)


def _load_merge(paths: list, *, baseline_path, bins: MergeBins | None, decision_step_s: float | None, name: str,
                encoding: str, features, **_: object) -> Problem:
    demos, bins, fs, acc, step = load_merge_demos(paths, bins, encoding=encoding, features=features,
                                                  decision_step_s=decision_step_s)
    baseline = None
    if baseline_path is not None:
        baseline = load_merge_demos(baseline_path, bins, encoding=encoding, features=fs,
                                    decision_step_s=decision_step_s)[0]
    return Problem(name, "merge", demos, merge_mdp.estimated_transitions(demos, bins, step), True, baseline,
                   fs.names, bins, step, 0.0, encoding, fs.name, acc)


def _load_npz(paths: list, *, baseline_path, decision_step_s: float | None, name: str, **_: object) -> Problem:
    demos = load_npz(paths[0])
    baseline = load_npz(baseline_path) if baseline_path is not None else None
    names = load_feature_names(paths[0]) or tuple(f"f{k}" for k in range(demos.n_features))
    step = FRAME_S if decision_step_s is None else decision_step_s  # the step is not resampled
    return Problem(name, "npz", demos, estimate_transitions(demos), True, baseline, names, None, step, 0.0)


def _counted_model(demos: Demonstrations, problem: Problem) -> SuccessorModel:
    return estimate_transitions(demos)


def _merge_model(demos: Demonstrations, problem: Problem) -> SuccessorModel:
    assert problem.bins is not None  # a merge problem always has its bins
    return merge_mdp.estimated_transitions(demos, problem.bins, problem.decision_step_s)


def _merge_pad(problem: Problem) -> Callable[[int], tuple[int, int]] | None:
    if problem.bins is None:
        return None
    return merge_mdp.ConstantVelocityPad(problem.bins, problem.decision_step_s, problem.state_encoding)


def _merge_fallback(problem: Problem) -> np.ndarray | None:
    if problem.bins is None:
        return None
    return merge_mdp.kinematic_successors(problem.bins, problem.decision_step_s, problem.state_encoding,
                                          problem.action_acc_ft_s2)


class DomainRegistryError(RegistryError, ConfigError):
    """An unknown IRL domain, or one registered twice (a :class:`ConfigError`)."""


#: The IRL domains, by name: the one home of what differs between them.
DOMAINS: Registry[Domain] = Registry("IRL domain", error=DomainRegistryError)
DOMAINS.register("gridworld", Domain("gridworld", _load_gridworld, _counted_model))
# merge fits: beta 1 (the policy depends on beta * theta only), L2 0 (with the driver
# features the Q-Avg likelihood of simulated encounters is bounded; the fit's unbounded test
# flags it otherwise), and the kinematic rule for unobserved pairs, chosen by
# leave-one-trajectory-out likelihood on the authors' NGSIM data (docs/irl.md,
# studies/driver_loo.py)
DOMAINS.register("merge", Domain("merge", _load_merge, _merge_model, _merge_pad, _merge_fallback,
                                 DomainDefaults(merge_mdp.DEFAULT_DECISION_STEP_S, beta=1.0, l2=0.0,
                                                unobserved="kinematic")))
DOMAINS.register("npz", Domain("npz", _load_npz, _counted_model))


def load_problem(
    domain: str,
    demos_path: str | os.PathLike | Sequence[str | os.PathLike],
    *,
    noise: float = 0.0,
    baseline_path: str | os.PathLike | None = None,
    bins: MergeBins | None = None,
    decision_step_s: float | None = None,
    name: str = "",
    encoding: str = "paper",
    features=None,
) -> Problem:
    """Build a :class:`Problem` from files with the loader of ``DOMAINS[domain]``.

    Args:
        domain: ``gridworld`` (authors' text format; true model with slip ``noise``),
            ``merge`` (text files or an encounter table; estimated model with kinematic
            fallback) or ``npz`` (generic format; estimated model, self-loops where unseen).
        demos_path: file or directory of expert trajectories; for ``merge``, also several
            encounter tables (kept apart, see :func:`load_merge_demos`).
        baseline_path: REIRL baseline trajectories in the same format (merge encounter tables
            are discretized with the experts' bins).
        bins: merge bin edges (default: assumed for text files, quantile-fitted for tables).
        decision_step_s: seconds per decision: merge encounter tables are resampled at it and the
            kinematic fallback uses it (None: the domain's default,
            ``DOMAINS[domain].defaults.decision_step_s``, 0.3 s for merge encounter tables; the
            authors' text files and the other domains are at their 0.1 s frame).
        encoding: merge state encoding, ``"paper"`` or ``"driver"``.
        features: merge features: a set name (``"paper"``, ``"driver"``), a tuple of names, or
            your own :class:`irl.domains.merge.features.FeatureSet` (``FeatureSet.custom(names,
            array [S, A, K])``); None: the paper's three.

    Raises:
        ConfigError: ``domain`` is not a key of :data:`DOMAINS`.
        DemonstrationError: the demonstrations are missing or malformed.
    """
    spec = DOMAINS.get(domain)
    if spec is None:
        raise ConfigError(f"domain must be one of {tuple(DOMAINS)}, got {domain!r}")
    paths = [demos_path] if isinstance(demos_path, (str, os.PathLike)) else list(demos_path)
    if len(paths) != 1 and domain != "merge":
        raise ConfigError(f"domain {domain}: one demonstrations source expected, got {len(paths)}; "
                          "several are read for the merge domain's encounter tables only")
    return spec.load(paths, noise=noise, baseline_path=baseline_path, bins=bins, decision_step_s=decision_step_s,
                     name=name or ", ".join(str(p) for p in paths), encoding=encoding, features=features)
