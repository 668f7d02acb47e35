"""Driver classes: one population vector per class of the follower's initial time headway
(the classes and their key; fitted by :func:`analysis.calibration.class_fit.fit_classes`).

This is driver-type segmentation by an observable: the training pairs are cut into C equally
filled classes by the follower's time headway at the pair's first step, and the population fit
(:func:`~analysis.calibration.fit.fit_population`) is run on each class. A pair is then
simulated with the vector of its class. The class key uses only what the simulation of a pair is
given anyway (the recorded initial gap and speed), nothing of the driver's later behaviour, so it
applies to drivers never seen in the fit (``studies/driver_classes_heldout.py``;
docs/calibration.md, "Driver classes").
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from analysis.calibration.models import CFParams
from analysis.calibration.pairs import CarFollowingPair
from scenarios.errors import SpecError

#: Speed floor (m/s) of the class key, so a pair starting at a standstill has a finite headway.
MIN_SPEED_MPS = 0.5


def initial_time_headway(pair: CarFollowingPair) -> float:
    """The class key (s): the follower's time headway at the pair's first step,
    bumper gap / max(speed, :data:`MIN_SPEED_MPS`), from the recorded gap and speed."""
    return float(pair.spacing[0] / max(float(pair.v_follower[0]), MIN_SPEED_MPS))


@dataclass(frozen=True)
class DriverClasses:
    """C driver classes of the initial time headway and their car-following parameters.

    Attributes:
        edges_s: C-1 increasing class edges of :func:`initial_time_headway` (s, a tuple so the
            dataclass stays hashable; ``np.asarray`` gives float64[C-1]); class c holds the pairs
            with ``edges_s[c-1] <= key < edges_s[c]`` (the first and last classes open-ended).
        params: the C classes' parameters (SUMO vType attributes, SI units), class order.

    Raises:
        SpecError: not C-1 edges for C parameter sets, or edges not finite and increasing.
    """

    edges_s: tuple[float, ...]
    params: tuple[CFParams, ...]

    def __post_init__(self) -> None:
        if len(self.params) < 1 or len(self.edges_s) != len(self.params) - 1:
            raise SpecError(f"driver classes: {len(self.params)} parameter sets need {len(self.params) - 1} "
                            f"edges, got {len(self.edges_s)}")
        if any(not np.isfinite(e) for e in self.edges_s) or any(
                b <= a for a, b in zip(self.edges_s, self.edges_s[1:])):
            raise SpecError(f"driver classes: edges_s = {list(self.edges_s)}; expected increasing finite seconds")

    @property
    def n_classes(self) -> int:
        return len(self.params)

    def class_of(self, pair: CarFollowingPair) -> int:
        """The class index (0 .. C-1) of ``pair``."""
        return int(np.searchsorted(np.asarray(self.edges_s), initial_time_headway(pair), side="right"))

    def params_for(self, pairs: Sequence[CarFollowingPair]) -> list[CFParams]:
        """The parameters each of ``pairs`` is simulated with (its class's), in the order given."""
        return [self.params[self.class_of(p)] for p in pairs]
