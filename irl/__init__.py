"""Maximum-likelihood inverse reinforcement learning on tabular demonstrations.

Pure numpy / scipy / cvxpy: never imports SUMO. Fit with ``irl.fit.fit(method, demos, config, rng)``.
"""

from irl.config import IRLConfig
from irl.demonstrations import Demonstrations
from irl.errors import ConfigError, ConvergenceError, DemonstrationError, IRLError, ModelFileError
from irl.result import FitResult, SavedModel
from irl.transitions import estimate_transitions

__all__ = [
    "ConfigError",
    "ConvergenceError",
    "DemonstrationError",
    "Demonstrations",
    "FitResult",
    "IRLConfig",
    "IRLError",
    "ModelFileError",
    "SavedModel",
    "estimate_transitions",
]
