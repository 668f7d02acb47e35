"""The torch layer of ``studies/imitation_bench.py`` (imports torch and Stable-Baselines3: the
``imitation-bench`` extra; nothing else imports this module).

:class:`Standardize` is the first layer of the comparison's BC and PPO policies: it subtracts the
training mean and divides by the training standard deviation of each observation column, so the
trained policy takes the policy observation itself (ft, ft/s; :func:`sim.drivers.observe.policy_rows`)
and is a driver as it is (``CallablePolicy(policy)``). A module of its own so pickled policies
find the class by name in the evaluation's worker processes.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor


class Standardize(BaseFeaturesExtractor):
    """``[B, D]`` observations -> ``[B, D]`` ``(obs - mean) / std`` (fixed, not trained).

    Args:
        observation_space: a ``Box`` of shape ``(D,)``.
        mean, std: ``D`` numbers each (std > 0).
    """

    def __init__(self, observation_space, mean: Sequence[float], std: Sequence[float]):
        super().__init__(observation_space, features_dim=len(mean))
        self.register_buffer("mean", torch.as_tensor(list(mean), dtype=torch.float32))
        self.register_buffer("std", torch.as_tensor(list(std), dtype=torch.float32))

    def forward(self, observations: torch.Tensor) -> torch.Tensor:
        return (observations.float() - self.mean) / self.std
