"""One entry point for every IRL method, ``fit(method, demos, config, rng, ...)``, dispatching
on the method registry (:mod:`irl.methods.registry`, re-exported here: :data:`REGISTRY`,
:func:`register`)."""

from __future__ import annotations

from typing import Any

import numpy as np

from irl.config import IRLConfig
from irl.demonstrations import Demonstrations
from irl.errors import ConfigError
from irl.methods.registry import REGISTRY, Method, get_method, method_names, register
from irl.result import FitResult
from irl.transitions import TransitionModel

__all__ = ["REGISTRY", "Method", "fit", "method_names", "register"]


def fit(method: str, demos: Demonstrations, config: IRLConfig, rng: np.random.Generator, *,
        transitions: TransitionModel | None = None, theta0: np.ndarray | None = None, progress: bool = False,
        **options: Any) -> FitResult:
    """Learn reward weights with ``method`` (a key of :data:`REGISTRY`).

    Args:
        method: a key of :data:`REGISTRY` (``"mlirl"``, ``"qavg"``, ``"qsm"``, ``"reirl"`` or one
            you registered).
        demos: the expert demonstrations (with features ``[S, A, K]``).
        config: settings; ``config.solver`` picks ``"exact"`` or ``"faithful"``.
        rng: the only source of randomness (theta initialisation, REIRL's baseline sampling).
        transitions: ``[S, A, S]`` row-stochastic model (dense, sparse ``[S*A, S]`` or a
            :class:`~irl.transitions.SuccessorModel`); required by MLIRL, used by REIRL for
            its baseline and final log-likelihood; ignored by Q-Avg and Q-SM (model-free).
        theta0: ``[K]`` start; default ``rng.uniform(config.init_low, config.init_high, K)``
            (REIRL ignores it: its dual is convex).
        progress: show a progress bar on stderr (only when it is a terminal).
        **options: the method's own options (``Method.options``); Q-Avg's and Q-SM's:
            ``fallback_next`` (``[S, A]`` int next states for ``config.unobserved ==
            "kinematic"``, :mod:`irl.unobserved_successors`); REIRL's: ``baseline``
            (sampling trajectories, default generated), ``epsilon`` (L1 weight; None: the
            Hoeffding bound at confidence ``1 - delta``), ``delta``, ``n_baseline``,
            ``pad_step`` (how trajectories are prolonged), ``theta_cap``
            (see :func:`irl.methods.reirl.fit_reirl`).

    Returns:
        The fit (theta ``[K]``, log-likelihood, Q ``[S, A]``, traces).

    Raises:
        ConfigError: unknown method, or an option the method does not take.
        DemonstrationError, ConvergenceError: from the method.
    """
    spec = get_method(method)
    unknown = sorted(set(options) - set(spec.options))
    if unknown:
        takes = ", ".join(spec.options) or "none"
        raise ConfigError(f"{method} takes no option {', '.join(unknown)} (its options: {takes})")
    if spec.needs_transitions:
        options["transitions"] = transitions
    return spec.fit_function()(demos, config, rng, theta0=theta0, progress=progress, **options)
