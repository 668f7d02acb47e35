"""Fitting driver classes (:class:`~analysis.calibration.classes.DriverClasses`): the training
pairs cut into equally filled classes of the initial time headway, one population fit each."""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from analysis.calibration.classes import DriverClasses, initial_time_headway
from analysis.calibration.fit import fit_population
from analysis.calibration.models import MODELS
from analysis.calibration.objective import DEFAULT_OBJECTIVE
from analysis.calibration.pairs import CarFollowingPair
from scenarios.errors import SpecError

#: A class needs at least this many training pairs for its population fit.
MIN_CLASS_PAIRS = 5


def class_edges(pairs: Sequence[CarFollowingPair], n_classes: int, *, model: str = "idm") -> tuple[float, ...]:
    """The C-1 class edges (s) :func:`fit_classes` cuts ``pairs`` at: the quantiles of
    :func:`initial_time_headway`, checked before any fitting.

    Raises:
        SpecError: ``n_classes`` < 1, a model without a replica, equal quantiles (edges not
            increasing) or a class with fewer than :data:`MIN_CLASS_PAIRS` pairs.
    """
    if isinstance(n_classes, bool) or not isinstance(n_classes, int) or n_classes < 1:
        raise SpecError(f"classes: expected a whole number >= 1, got {n_classes!r}")
    if model not in MODELS:
        raise SpecError(f"classes: need a model with a numpy replica ({', '.join(sorted(MODELS))}), got {model!r}")
    keys = np.array([initial_time_headway(p) for p in pairs], dtype=np.float64)
    if len(keys) < n_classes * MIN_CLASS_PAIRS:
        raise SpecError(f"classes: {n_classes} classes need at least {n_classes * MIN_CLASS_PAIRS} training pairs "
                        f"({MIN_CLASS_PAIRS} per class), got {len(keys)}")
    edges = tuple(float(e) for e in np.quantile(keys, np.linspace(0.0, 1.0, n_classes + 1)[1:-1]))
    counts = np.bincount(np.searchsorted(np.asarray(edges), keys, side="right"), minlength=n_classes)
    if len(set(edges)) < len(edges) or counts.min() < MIN_CLASS_PAIRS:
        raise SpecError(f"classes: {n_classes} classes of the initial time headway hold {counts.tolist()} pairs; "
                        f"each needs at least {MIN_CLASS_PAIRS} (use fewer classes)")
    return edges


def fit_classes(
    pairs: Sequence[CarFollowingPair], n_classes: int, *, model: str = "idm", objective: str = DEFAULT_OBJECTIVE,
    tick: Callable[[], None] | None = None,
) -> DriverClasses:
    """Cut ``pairs`` into ``n_classes`` equally filled classes of :func:`initial_time_headway`
    (edges: the keys' quantiles, :func:`class_edges`) and run
    :func:`~analysis.calibration.fit.fit_population` on each.

    Args:
        pairs: the P training pairs.
        n_classes: C >= 1; C = 1 is the plain population fit.
        model: a replica model (``idm`` or ``krauss``, :data:`~analysis.calibration.models.MODELS`).
        objective: the population fit's objective (:data:`~analysis.calibration.objective.OBJECTIVES`).
        tick: called once per simulation of the class fits (progress reporting).

    Returns:
        The classes: float64[C-1] edges (s) and C parameter sets.

    Raises:
        SpecError: as :func:`class_edges`.
    """
    edges = class_edges(pairs, n_classes, model=model)
    of = np.searchsorted(np.asarray(edges), [initial_time_headway(p) for p in pairs], side="right")
    params = tuple(fit_population([p for p, k in zip(pairs, of) if k == c], model=model, objective=objective,
                                  tick=tick)[0] for c in range(n_classes))
    return DriverClasses(edges_s=edges, params=params)
