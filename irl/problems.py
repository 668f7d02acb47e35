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

from irl import merge_mdp
from irl.demonstrations import Demonstrations
from irl.domains import gridworld
from irl.domains.merge import FEATURE_NAMES, MergeBins, fit_quantile_bins
from irl.errors import ConfigError, DemonstrationError
from irl.io import load_feature_names, load_npz
from irl.transitions import estimate_transitions

DOMAINS = ("gridworld", "merge", "npz")


@dataclass(frozen=True)
class Problem:
    """One IRL data set, ready for every method (picklable).

    Attributes:
        name: short label (``"gridworld 0%"``, a path, ...).
        domain: one of ``DOMAINS``.
        demos: the expert demonstrations.
        transitions: ``[S, A, S]`` model for MLIRL and for REIRL's final log-likelihood.
        transitions_estimated: whether ``transitions`` were estimated from ``demos`` (then a
            subset of the trajectories re-estimates them, so held-out data never leaks in).
        baseline: REIRL baseline trajectories, or None (REIRL then generates uniform-random ones
            under ``transitions``).
        feature_names: ``K`` names.
        bins: merge state bin edges (merge domain only).
        dt: merge decision step (s) of the kinematic fallback and REIRL's padding.
        noise: gridworld slip probability.
    """

    name: str
    domain: str
    demos: Demonstrations
    transitions: np.ndarray
    transitions_estimated: bool = False
    baseline: Demonstrations | None = None
    feature_names: tuple[str, ...] = ()
    bins: MergeBins | None = None
    dt: float = 0.1
    noise: float = 0.0

    def subset(self, indices) -> Problem:
        """The same problem on the trajectories at ``indices`` (model re-estimated if estimated)."""
        demos = self.demos.subset(indices)
        transitions = estimate_model(demos, self.domain, self.bins, self.dt) if self.transitions_estimated \
            else self.transitions
        return Problem(self.name, self.domain, demos, transitions, self.transitions_estimated, self.baseline,
                       self.feature_names, self.bins, self.dt, self.noise)

    def pad_step(self) -> Callable[[int], tuple[int, int]] | None:
        """REIRL's padding rule: constant velocity for merge, repeat the last pair otherwise."""
        if self.domain == "merge" and self.bins is not None:
            return merge_mdp.ConstantVelocityPad(self.bins, self.dt)
        return None


def estimate_model(demos: Demonstrations, domain: str, bins: MergeBins | None, dt: float) -> np.ndarray:
    """Relative-count model of ``demos``; unseen pairs: kinematic (merge) or self-loop."""
    if domain == "merge" and bins is not None:
        return merge_mdp.estimated_transitions(demos, bins, dt)
    return estimate_transitions(demos)


def _is_text_format(path: Path) -> bool:
    return path.is_dir() or path.suffix == ".txt"


def load_merge_demos(path: str | os.PathLike | Sequence[str | os.PathLike],
                     bins: MergeBins | None) -> tuple[Demonstrations, MergeBins]:
    """Merge demonstrations from the authors' text files (state indices as they are; ``bins``
    default to ``MergeBins.assumed_authors()``) or from encounter tables (``.parquet``/``.csv``;
    ``bins`` default to quantile bins fitted on all of them). Several tables (files or runs)
    keep their encounters apart even where encounter ids repeat: each file's trajectories are
    named ``<file>: encounter <id>``.

    Raises:
        DemonstrationError: a path is missing, or several paths include text-format ones.
    """
    paths = [Path(p) for p in ([path] if isinstance(path, (str, os.PathLike)) else path)]
    if not paths:
        raise DemonstrationError("no demonstrations given")
    for p in paths:
        if not p.exists():
            raise DemonstrationError(f"{p}: no such file or directory")
    if len(paths) == 1 and _is_text_format(paths[0]):
        return merge_mdp.load(paths[0]), bins or MergeBins.assumed_authors()
    text = [str(p) for p in paths if _is_text_format(p)]
    if text:
        raise DemonstrationError(f"{text[0]}: several demonstration sources must all be encounter tables "
                                 "(.parquet/.csv); the authors' text format is read alone")
    tables = [merge_mdp.read_encounters(p) for p in paths]
    for p, t in zip(paths, tables):
        _warn_raw_accelerations(t, p)
    where = ", ".join(str(p) for p in paths)
    bins = bins or fit_quantile_bins(pd.concat(tables, ignore_index=True) if len(tables) > 1 else tables[0],
                                     where=where)
    parts = [merge_mdp.discretize(t, bins, where=str(p)) for p, t in zip(paths, tables)]
    if len(parts) == 1:
        return parts[0], bins
    first = parts[0]
    return replace(
        first, states=tuple(s for d in parts for s in d.states), actions=tuple(a for d in parts for a in d.actions),
        source=where, names=tuple(f"{p}: {n}" for p, d in zip(paths, parts) for n in d.names),
    ), bins


#: NGSIM's acceleration cap (ft/s^2) and the share of rows at it that marks raw accelerations.
_NGSIM_ACC_CAP = 11.2
RAW_ACC_CAP_SHARE = 0.01


class RawAccelerationWarning(UserWarning):
    """Encounters whose acc_A looks like the difference of raw, unsmoothed NGSIM speeds."""


def _warn_raw_accelerations(table: pd.DataFrame, path: Path) -> None:
    """Warn when more than :data:`RAW_ACC_CAP_SHARE` of ``acc_A`` sits at or beyond NGSIM's +-11.2 cap.

    ``acc_A`` is the forward difference of A's speed, so the noise of raw NGSIM speeds shows as
    accelerations at or beyond the cap that the recording's own smoothing would never produce.
    """
    if "acc_A" not in table.columns or len(table) == 0:
        return
    acc = pd.to_numeric(table["acc_A"], errors="coerce").to_numpy(dtype=np.float64)
    share = float(np.mean(np.abs(acc) >= _NGSIM_ACC_CAP - 0.005))
    if share > RAW_ACC_CAP_SHARE:
        warnings.warn(
            f"{path}: column acc_A: {share:.0%} of rows at or beyond NGSIM's +-11.2 ft/s^2 cap: raw, unsmoothed "
            "accelerations, whose noise becomes the action labels (hard brake / hard accel); extract the "
            "encounters with `merge-irl encounters --smooth`", RawAccelerationWarning, stacklevel=3)


def load_problem(
    domain: str,
    demos_path: str | os.PathLike | Sequence[str | os.PathLike],
    *,
    noise: float = 0.0,
    baseline_path: str | os.PathLike | None = None,
    bins: MergeBins | None = None,
    dt: float = 0.1,
    name: str = "",
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
        dt: merge decision step of the kinematic fallback, seconds.

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
    if domain == "gridworld":
        demos = gridworld.load(paths[0])
        if baseline_path is not None:
            baseline = gridworld.load(baseline_path)
        return Problem(label, domain, demos, gridworld.transition_model(noise), False, baseline,
                       gridworld.FEATURE_NAMES, None, dt, noise)
    if domain == "merge":
        demos, bins = load_merge_demos(paths, bins)
        if baseline_path is not None:
            baseline, _ = load_merge_demos(baseline_path, bins)
        return Problem(label, domain, demos, merge_mdp.estimated_transitions(demos, bins, dt), True, baseline,
                       FEATURE_NAMES, bins, dt, 0.0)
    demos = load_npz(paths[0])
    if baseline_path is not None:
        baseline = load_npz(baseline_path)
    names = load_feature_names(paths[0]) or tuple(f"f{k}" for k in range(demos.n_features))
    return Problem(label, domain, demos, estimate_model(demos, domain, None, dt), True, baseline, names,
                   None, dt, 0.0)
