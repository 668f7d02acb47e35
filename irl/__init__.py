"""Maximum-likelihood inverse reinforcement learning on tabular demonstrations.

Pure numpy / scipy / cvxpy: never imports SUMO. Fit with ``irl.fit.fit(method, demos, config, rng)``.

The names below are loaded on first use (PEP 562), so that importing a leaf module such as
:mod:`merge_irl.units` or :mod:`merge_irl.atomic` (which :mod:`scenarios` does) loads nothing else of ``irl``.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from merge_irl.moved import install as _install_moved_paths

_install_moved_paths()  # old import paths (irl.merge_mdp, ...) fail naming their new home

if TYPE_CHECKING:
    from irl.config import IRLConfig
    from irl.demonstrations import Demonstrations
    from irl.errors import ConfigError, ConvergenceError, DemonstrationError, IRLError, ModelFileError
    from irl.result import FitResult, SavedModel
    from irl.transitions import estimate_transitions

#: Public name -> the module that defines it.
_EXPORTS = {
    "ConfigError": "irl.errors",
    "ConvergenceError": "irl.errors",
    "DemonstrationError": "irl.errors",
    "Demonstrations": "irl.demonstrations",
    "FitResult": "irl.result",
    "IRLConfig": "irl.config",
    "IRLError": "irl.errors",
    "ModelFileError": "irl.errors",
    "SavedModel": "irl.result",
    "estimate_transitions": "irl.transitions",
}

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
assert sorted(__all__) == sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'irl' has no attribute {name!r}")
    return getattr(importlib.import_module(module), name)
