"""IRL problems: demonstrations plus everything a method needs beside them.

A :class:`Problem` bundles the expert demonstrations, the transition model that MLIRL and REIRL's
final log-likelihood use (the true model, or one estimated from the demonstrations), optional
REIRL baseline trajectories, and the merge bin edges. ``load_problem`` builds one from files for
each domain (``gridworld``, ``merge``, ``npz``).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from collections.abc import Callable

import numpy as np

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


def load_merge_demos(path: str | os.PathLike, bins: MergeBins | None) -> tuple[Demonstrations, MergeBins]:
    """Merge demonstrations from the authors' text files (state indices as they are; ``bins``
    default to ``MergeBins.assumed_authors()``) or from an encounter table (``.parquet``/
    ``.csv``; ``bins`` default to quantile bins fitted on it).

    Raises:
        DemonstrationError: ``path`` does not exist, or is not a valid encounter table or trajectory folder.
    """
    path = Path(path)
    if not path.exists():
        raise DemonstrationError(f"{path}: no such file or directory")
    if _is_text_format(path):
        return merge_mdp.load(path), bins or MergeBins.assumed_authors()
    table = merge_mdp.read_encounters(path)
    bins = bins or fit_quantile_bins(table, where=str(path))
    return merge_mdp.discretize(table, bins, where=str(path)), bins


def load_problem(
    domain: str,
    demos_path: str | os.PathLike,
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
        demos_path: file or directory of expert trajectories.
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
    label = name or str(demos_path)
    baseline = None
    if domain == "gridworld":
        demos = gridworld.load(demos_path)
        if baseline_path is not None:
            baseline = gridworld.load(baseline_path)
        return Problem(label, domain, demos, gridworld.transition_model(noise), False, baseline,
                       gridworld.FEATURE_NAMES, None, dt, noise)
    if domain == "merge":
        demos, bins = load_merge_demos(demos_path, bins)
        if baseline_path is not None:
            baseline, _ = load_merge_demos(baseline_path, bins)
        return Problem(label, domain, demos, merge_mdp.estimated_transitions(demos, bins, dt), True, baseline,
                       FEATURE_NAMES, bins, dt, 0.0)
    demos = load_npz(demos_path)
    if baseline_path is not None:
        baseline = load_npz(baseline_path)
    names = load_feature_names(demos_path) or tuple(f"f{k}" for k in range(demos.n_features))
    return Problem(label, domain, demos, estimate_model(demos, domain, None, dt), True, baseline, names,
                   None, dt, 0.0)
