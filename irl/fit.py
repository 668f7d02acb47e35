"""One entry point for every IRL method, ``fit(method, demos, config, rng, ...)``, and the
method registry it dispatches on."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any
from collections.abc import Callable

import numpy as np

from irl.config import IRLConfig
from irl.demonstrations import Demonstrations
from irl.errors import ConfigError
from irl.methods.mlirl import fit_mlirl
from irl.methods.qavg import fit_qavg
from irl.methods.qsm import fit_qsm
from irl.methods.reirl import fit_reirl
from irl.result import FitResult
from irl.transitions import TransitionModel


@dataclass(frozen=True)
class Method:
    """One IRL method of the registry.

    Attributes:
        name: the key (``"qavg"``, ...), as saved in ``model.json``.
        label: the paper's name (``"Q-Avg"``, ...).
        fitter: ``fitter(demos, config, rng, *, theta0, progress, [transitions], **options)``.
        uses_transitions: whether the method takes an ``[S, A, S]`` model (MLIRL needs one;
            REIRL uses it for its baseline and final log-likelihood; Q-Avg and Q-SM are
            model-free).
        options: the further keyword arguments the method accepts.
    """

    name: str
    label: str
    fitter: Callable[..., FitResult]
    uses_transitions: bool = False
    options: tuple[str, ...] = ()


#: The methods, in the order of the paper's tables' columns (Q-Avg, Q-SM, MLIRL, REIRL).
REGISTRY: dict[str, Method] = {
    m.name: m for m in (
        Method("qavg", "Q-Avg", fit_qavg, options=("fallback_next",)),
        Method("qsm", "Q-SM", fit_qsm, options=("fallback_next",)),
        Method("mlirl", "MLIRL", fit_mlirl, uses_transitions=True),
        Method("reirl", "REIRL", fit_reirl, uses_transitions=True,
               options=("baseline", "epsilon", "delta", "n_baseline", "pad_step", "theta_cap")),
    )
}
METHODS: tuple[str, ...] = tuple(REGISTRY)


def fit(method: str, demos: Demonstrations, config: IRLConfig, rng: np.random.Generator, *,
        transitions: TransitionModel | None = None, theta0: np.ndarray | None = None, progress: bool = False,
        **options: Any) -> FitResult:
    """Learn reward weights with ``method`` (a key of :data:`REGISTRY`).

    Args:
        method: ``"qavg"``, ``"qsm"``, ``"mlirl"`` or ``"reirl"``.
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
    spec = REGISTRY.get(method)
    if spec is None:
        raise ConfigError(f"unknown IRL method {method!r}; expected one of {METHODS}")
    unknown = sorted(set(options) - set(spec.options))
    if unknown:
        takes = ", ".join(spec.options) or "none"
        raise ConfigError(f"{method} takes no option {', '.join(unknown)} (its options: {takes})")
    if spec.uses_transitions:
        options["transitions"] = transitions
    return spec.fitter(demos, config, rng, theta0=theta0, progress=progress, **options)
