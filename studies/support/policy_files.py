"""Saved Stable-Baselines3 policies read back under torch >= 2.6 (the imitation study's BC and
GAIL actors; torch and Stable-Baselines3 are imported inside the functions: the ``rl`` or
``imitation-bench`` extra).

Why this module: a policy is saved the documented way, Stable-Baselines3's ``policy.save(path)``
(a dict of the ``state_dict`` and the constructor's arguments) or imitation's
``imitation.util.util.save_policy(policy, path)`` (the whole pickled policy). The documented loads,
``PolicyClass.load(path)`` in Stable-Baselines3 2.2 (what imitation 1.0.1 pins) and imitation
1.0.1's ``bc.reconstruct_policy(path)``, call ``torch.load`` with torch's default, which torch 2.6
changed to ``weights_only=True``; the constructor's arguments (gymnasium spaces, the activation and
feature-extractor classes) are pickled Python objects, so both raise ``UnpicklingError: Weights
only load failed``. :func:`load_policy` reads either file with ``weights_only=False``, as
Stable-Baselines3 2.9.2's own load does. That unpickles, which can run code: load only files
you (or this project) wrote.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any


class PolicyFileError(ValueError):
    """A policy file that is missing or holds no policy (the message names the file)."""


def save_policy(policy: Any, path: str | os.PathLike) -> Path:
    """Write ``policy`` (a Stable-Baselines3 ``BasePolicy``, e.g. ``bc.BC(...).policy``) the
    documented way, ``policy.save(path)``: its ``state_dict`` and its constructor's arguments.

    Raises:
        OSError: the file cannot be written.
    """
    path = Path(path)
    policy.save(str(path))
    return path


def load_policy(path: str | os.PathLike, policy_class: Any = None, *, device: str = "cpu") -> Any:
    """The policy in ``path``, written by :func:`save_policy` (Stable-Baselines3's ``policy.save``;
    rebuilt as ``policy_class(**arguments)`` with its ``state_dict``) or by imitation's
    ``util.save_policy`` (the pickled policy itself; ``policy_class`` unused). On ``device``, in
    evaluation mode.

    ``policy_class``: the class to rebuild a ``policy.save`` file as; Stable-Baselines3's
    ``ActorCriticPolicy`` by default, which rebuilds imitation's BC policy
    (``imitation.policies.base.FeedForward32Policy``, an ``ActorCriticPolicy`` whose
    ``net_arch=[32, 32]`` the file holds) as the same network: ``FeedForward32Policy(**arguments)``
    itself raises ``TypeError`` (``net_arch`` given twice), as its own ``load`` does.

    Raises:
        PolicyFileError: no such file, or a file that holds neither kind.
        pickle.UnpicklingError, RuntimeError: torch cannot read the file.
    """
    import torch
    from stable_baselines3.common.policies import ActorCriticPolicy, BasePolicy

    path = Path(path)
    if not path.is_file():
        raise PolicyFileError(f"{path}: no such policy file")
    # weights_only=False: the file holds pickled spaces and classes (see the module docstring)
    saved = torch.load(path, map_location=device, weights_only=False)  # noqa: S614  (our own file)
    if isinstance(saved, BasePolicy):
        policy = saved
    elif isinstance(saved, dict) and {"state_dict", "data"} <= saved.keys():
        policy = (policy_class or ActorCriticPolicy)(**saved["data"])
        policy.load_state_dict(saved["state_dict"])
    else:
        raise PolicyFileError(f"{path}: holds {type(saved).__name__}, not a Stable-Baselines3 policy")
    policy.to(device)
    policy.set_training_mode(False)
    return policy
