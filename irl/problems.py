"""IRL problems: demonstrations plus everything a method needs beside them.

A :class:`Problem` bundles the expert demonstrations, the transition model that MLIRL and REIRL's
final log-likelihood use (the true model, or one estimated from the demonstrations), optional
REIRL baseline trajectories, and the merge bin edges. ``load_problem`` builds one from files for
each domain (``gridworld``, ``merge``, ``npz``).
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from collections.abc import Callable

import numpy as np
import pandas as pd

from irl.domains.merge import mdp as merge_mdp
from irl.demonstrations import Demonstrations
from irl.domains import gridworld
from irl.domains.merge.actions import ACTION_ACC_FT_S2
from irl.domains.merge.bins import MergeBins, fit_quantile_bins
from irl.domains.merge.features import FeatureSet, feature_set
from irl.errors import ConfigError, DemonstrationError
from irl.io import load_feature_names, load_npz
from irl.transitions import SuccessorModel, TransitionModel, estimate_transitions, model_successors

DOMAINS = ("gridworld", "merge", "npz")


@dataclass(frozen=True)
class Problem:
    """One IRL data set, ready for every method (picklable).

    Attributes:
        name: short label (``"gridworld 0%"``, a path, ...).
        domain: one of ``DOMAINS``.
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
        dt: merge decision step (s) of the kinematic fallback and REIRL's padding.
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
    dt: float = 0.1
    noise: float = 0.0
    state_encoding: str = "paper"
    feature_set: str = "paper"
    action_acc_ft_s2: tuple[float, ...] = tuple(ACTION_ACC_FT_S2)

    def subset(self, indices) -> Problem:
        """The same problem on the trajectories at ``indices`` (model re-estimated if estimated)."""
        demos = self.demos.subset(indices)
        transitions = estimate_model(demos, self.domain, self.bins, self.dt) if self.transitions_estimated \
            else self.transitions
        return replace(self, demos=demos, transitions=transitions)

    def pad_step(self) -> Callable[[int], tuple[int, int]] | None:
        """REIRL's padding rule: constant velocity for merge, repeat the last pair otherwise."""
        if self.domain == "merge" and self.bins is not None:
            return merge_mdp.ConstantVelocityPad(self.bins, self.dt, self.state_encoding)
        return None


def estimate_model(demos: Demonstrations, domain: str, bins: MergeBins | None, dt: float) -> SuccessorModel:
    """Relative-count model of ``demos`` (sparse); unseen pairs: kinematic (merge) or self-loop."""
    if domain == "merge" and bins is not None:
        return merge_mdp.estimated_transitions(demos, bins, dt)
    return estimate_transitions(demos)


def _is_text_format(path: Path) -> bool:
    return path.is_dir() or path.suffix == ".txt"


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
        if decision_step_s not in (None, 0.1):
            raise ConfigError(f"{paths[0]}: the authors' trajectories are 0.1 s steps and cannot be resampled "
                              f"at {decision_step_s} s")
        bins = bins or MergeBins.assumed_authors()
        fs = feature_set(features or "paper", bins, encoding, dt=0.1)
        demos = merge_mdp.load(paths[0])
        if encoding == "driver":
            demos = merge_mdp.driver_encoded(demos, fs.array)
        else:
            demos = replace(demos, features=fs.array)
        return demos, bins, fs, tuple(ACTION_ACC_FT_S2), 0.1
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
    fs = feature_set(features or "paper", bins, encoding, dt=step)
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


def load_problem(
    domain: str,
    demos_path: str | os.PathLike | Sequence[str | os.PathLike],
    *,
    noise: float = 0.0,
    baseline_path: str | os.PathLike | None = None,
    bins: MergeBins | None = None,
    dt: float | None = None,
    name: str = "",
    encoding: str = "paper",
    features=None,
) -> Problem:
    """Build a :class:`Problem` from files.

    Args:
        domain: ``gridworld`` (authors' text format; true model with slip ``noise``),
            ``merge`` (text files or an encounter table; estimated model with kinematic
            fallback) or ``npz`` (generic format; estimated model, self-loops where unseen).
        demos_path: file or directory of expert trajectories; for ``merge``, also several
            encounter tables (kept apart, see :func:`load_merge_demos`).
        baseline_path: REIRL baseline trajectories in the same format (merge encounter tables
            are discretized with the experts' bins).
        bins: merge bin edges (default: assumed for text files, quantile-fitted for tables).
        dt: merge decision step (s): encounter tables are resampled at it and the kinematic
            fallback uses it (default 0.3 s for tables, 0.1 s for text files and other domains).
        encoding: merge state encoding, ``"paper"`` or ``"driver"``.
        features: merge features: a set name (``"paper"``, ``"driver"``), a tuple of names, or
            your own :class:`irl.domains.merge.features.FeatureSet` (``FeatureSet.custom(names,
            array [S, A, K])``); None: the paper's three.

    Raises:
        ConfigError: ``domain`` is not one of :data:`DOMAINS`.
        DemonstrationError: the demonstrations are missing or malformed.
    """
    if domain not in DOMAINS:
        raise ConfigError(f"domain must be one of {DOMAINS}, got {domain!r}")
    paths = [demos_path] if isinstance(demos_path, (str, os.PathLike)) else list(demos_path)
    several = len(paths) != 1
    if several and domain != "merge":
        raise ConfigError(f"domain {domain}: one demonstrations source expected, got {len(paths)}; "
                          "several are read for the merge domain's encounter tables only")
    label = name or ", ".join(str(p) for p in paths)
    baseline = None
    step_other = 0.1 if dt is None else dt  # gridworld and npz: the step is not resampled
    if domain == "gridworld":
        demos = gridworld.load(paths[0])
        if baseline_path is not None:
            baseline = gridworld.load(baseline_path)
        return Problem(label, domain, demos, model_successors(gridworld.transition_model(noise)), False, baseline,
                       gridworld.FEATURE_NAMES, None, step_other, noise)
    if domain == "merge":
        demos, bins, fs, acc, step = load_merge_demos(paths, bins, encoding=encoding, features=features,
                                                      decision_step_s=dt)
        if baseline_path is not None:
            baseline = load_merge_demos(baseline_path, bins, encoding=encoding, features=fs, decision_step_s=dt)[0]
        return Problem(label, domain, demos, merge_mdp.estimated_transitions(demos, bins, step), True, baseline,
                       fs.names, bins, step, 0.0, encoding, fs.name, acc)
    demos = load_npz(paths[0])
    if baseline_path is not None:
        baseline = load_npz(baseline_path)
    names = load_feature_names(paths[0]) or tuple(f"f{k}" for k in range(demos.n_features))
    return Problem(label, domain, demos, estimate_model(demos, domain, None, step_other), True, baseline, names,
                   None, step_other, 0.0)
