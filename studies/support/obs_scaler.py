"""The observation scaler of the imitation learners (torch-free): the per-column mean and
standard deviation of the training policy observations, which ``studies/imitation_bench.py``'s
networks subtract and divide by in their first layer, so each trained network takes the policy
observation as the environment gives it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim.drivers.observe import policy_rows


@dataclass(frozen=True)
class ObsScaler:
    """Per-column mean and standard deviation of training policy observations
    (:func:`sim.drivers.observe.policy_rows`: filled and clipped, ft and ft/s), which the networks'
    first layer (``studies/imitation_nets.py``'s ``Standardize``) subtracts and divides by, so
    the trained policies take the policy observation itself, as the environment and
    :class:`~sim.drivers.callables.CallablePolicy` give it.

    Attributes:
        mean, std: ``[7]`` (a constant column's std is 1).
    """

    mean: tuple[float, ...]
    std: tuple[float, ...]

    @classmethod
    def fit(cls, obs: np.ndarray) -> ObsScaler:
        """The scaler of ``[N, 7]`` training observations (continuous rows, NaN allowed: made
        policy observations first)."""
        x = policy_rows(obs)
        sd = x.std(axis=0)
        return cls(tuple(float(v) for v in x.mean(axis=0)), tuple(float(v) if v > 0 else 1.0 for v in sd))

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        """``[N, 7]`` (or ``[7]``) observations -> ``[N, 7]`` float32, standardised (numpy; the
        networks do the same in torch)."""
        return ((policy_rows(obs) - np.asarray(self.mean)) / np.asarray(self.std)).astype(np.float32)
