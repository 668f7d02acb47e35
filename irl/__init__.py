"""Maximum-likelihood inverse reinforcement learning on tabular demonstrations.

Pure numpy / scipy / cvxpy: never imports SUMO.
"""

from irl.config import IRLConfig
from irl.demonstrations import Demonstrations
from irl.errors import ConfigError, DemonstrationError, IRLError, ModelFileError
from irl.result import FitResult, SavedModel

__all__ = [
    "ConfigError",
    "DemonstrationError",
    "Demonstrations",
    "FitResult",
    "IRLConfig",
    "IRLError",
    "ModelFileError",
    "SavedModel",
]
