"""The ``"policy"`` observation (the environments' default): ``[7]`` float64, the continuous
observation as a policy sees it (:func:`sim.drivers.observe.policy_observation`: filled and
clipped), columns :data:`sim.drivers.observe.CONTINUOUS_NAMES` (``d_AC``, ``v_AC``, ``d_AB``,
``v_AB``, ``v_A``, ``len_C``, ``len_B``), in ft and ft/s, or m and m/s with ``units="si"``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces

from sim.drivers.observe import POLICY_OBS_HIGH, POLICY_OBS_LOW, MergeObservation, policy_observation
from sim.env.observations import register_observation


class PolicyObservation:
    """The 7 policy columns of a decision, in the config's units (module docstring)."""

    def __init__(self, config: Any):  # a sim.env.config.MergeEnvConfig (which imports this package)
        self.scale = config.obs_scale

    def space(self) -> spaces.Space[Any]:
        """``Box(POLICY_OBS_LOW, POLICY_OBS_HIGH, (7,), float64)`` times the unit's scale."""
        return spaces.Box(POLICY_OBS_LOW * self.scale, POLICY_OBS_HIGH * self.scale, dtype=np.float64)

    def observe(self, obs: MergeObservation) -> np.ndarray:
        """``[7]`` of ``obs`` (a new array)."""
        o = policy_observation(obs)
        return o * self.scale if self.scale != 1.0 else o


register_observation("policy", PolicyObservation)
