"""The action distribution of a policy from the ecosystem, for its held-out log-likelihood, and
Stable-Baselines3's observation normalisation applied to it.

:func:`action_probs_fn` finds, on an object that :class:`sim.drivers.callables.CallablePolicy`
drives, a function ``obs [N, 7] -> probs [N, 5]`` over the five merge actions (High Brake ..
High Accel), in this order:

* ``action_probs(obs [N, 7]) -> [N, 5]`` (this module's :class:`ObsNormalized` has one);
* ``probs(obs [7]) -> [5]`` (any object of your own), called row by row;
* Stable-Baselines3 (``model.policy``, or the policy itself, as imitation's BC gives it):
  ``get_distribution`` of the observations; a categorical distribution over ``Discrete(5)``
  gives its probabilities, a Gaussian over the acceleration (m/s^2, the environment's
  continuous action) the mass of each action's acceleration bin
  (:func:`irl.domains.merge.actions.action_of`'s edges: -4.8, -0.6, 0.6, 4.8 ft/s^2).

The observation is the policy observation of :func:`sim.drivers.observe.policy_rows` (ft, ft/s).
A policy trained behind ``VecNormalize`` saw normalised observations: :func:`with_vecnormalize`
(``merge-irl evaluate --policy-vecnormalize FILE``) applies the saved statistics before every
call, ``clip((obs - mean) / sqrt(var + epsilon), -clip_obs, clip_obs)``, as ``VecNormalize`` does.
"""

from __future__ import annotations

import os
import pickle
from collections.abc import Callable
from typing import Any

import numpy as np
from scipy.special import ndtr

from irl.domains.merge.actions import N_ACTIONS
from merge_irl.units import M_PER_FT
from sim.drivers.callables.actions import act_of
from sim.drivers.policy import PolicyError

#: The acceleration edges between the five actions (ft/s^2), :func:`irl.domains.merge.actions.action_of`'s.
ACTION_EDGES_FT_S2 = (-4.8, -0.6, 0.6, 4.8)

__all__ = ["ACTION_EDGES_FT_S2", "ObsNormalized", "action_probs_fn", "check_vecnormalize", "gaussian_bin_probs",
           "with_vecnormalize"]


def gaussian_bin_probs(mean_mps2: np.ndarray, std_mps2: np.ndarray) -> np.ndarray:
    """``[N] , [N] -> [N, 5]``: the mass of a normal acceleration (m/s^2) in each action's bin."""
    edges = np.asarray(ACTION_EDGES_FT_S2) * M_PER_FT
    z = (edges[None, :] - np.asarray(mean_mps2, dtype=np.float64)[:, None]) / np.asarray(std_mps2, np.float64)[:, None]
    cdf = np.concatenate([np.zeros((len(z), 1)), ndtr(z), np.ones((len(z), 1))], axis=1)
    return np.diff(cdf, axis=1)


def _sb3_probs(policy: Any) -> Callable[[np.ndarray], np.ndarray]:
    def probs(obs: np.ndarray) -> np.ndarray:
        import torch

        with torch.no_grad():
            t, _ = policy.obs_to_tensor(np.asarray(obs, dtype=np.float32))
            dist = policy.get_distribution(t).distribution
            if hasattr(dist, "probs"):  # Categorical over Discrete(5)
                return dist.probs.cpu().numpy().astype(np.float64).reshape(len(obs), -1)
            mean = dist.mean.cpu().numpy().reshape(len(obs), -1)[:, 0]
            std = dist.stddev.cpu().numpy().reshape(len(obs), -1)[:, 0]
        return gaussian_bin_probs(mean, std)
    return probs


def action_probs_fn(fn: Any) -> Callable[[np.ndarray], np.ndarray] | None:
    """``obs [N, 7] -> probs [N, 5]`` of ``fn`` (module docstring), None when it exposes no
    action distribution (a rule that returns an action only)."""
    if isinstance(fn, ObsNormalized):
        return fn.action_probs if fn.has_distribution else None
    batched = getattr(fn, "action_probs", None)
    if callable(batched):
        return batched
    one = getattr(fn, "probs", None)
    if callable(one):
        return lambda obs: np.stack([np.asarray(one(row), dtype=np.float64).reshape(-1) for row in obs])
    for policy in (getattr(fn, "policy", None), fn):
        if callable(getattr(policy, "get_distribution", None)) and callable(getattr(policy, "obs_to_tensor", None)):
            return _sb3_probs(policy)
    return None


class ObsNormalized:
    """``fn`` behind ``VecNormalize``'s observation statistics: ``predict``, ``__call__`` and
    ``action_probs`` normalise the observation, then ask ``fn``.

    Args:
        fn: the policy (a callable, or an object with ``predict``; its distribution as
            :func:`action_probs_fn` finds it).
        mean, var: ``[7]`` the running mean and variance; clip_obs, epsilon: as ``VecNormalize``'s.
    """

    def __init__(self, fn: Any, mean: np.ndarray, var: np.ndarray, *, clip_obs: float = 10.0, epsilon: float = 1e-8):
        self.fn = fn
        self.mean = np.asarray(mean, dtype=np.float64)
        self.var = np.asarray(var, dtype=np.float64)
        self.clip_obs = float(clip_obs)
        self.epsilon = float(epsilon)
        self._act = act_of(fn)
        self._probs = action_probs_fn(fn)
        self.has_distribution = self._probs is not None

    def normalize(self, obs: np.ndarray) -> np.ndarray:
        """``VecNormalize.normalize_obs`` of ``obs`` (``[7]`` or ``[N, 7]``)."""
        z = (np.asarray(obs, dtype=np.float64) - self.mean) / np.sqrt(self.var + self.epsilon)
        return np.clip(z, -self.clip_obs, self.clip_obs)

    def __call__(self, obs: np.ndarray) -> Any:
        return self._act(self.normalize(obs))

    def predict(self, obs: np.ndarray, deterministic: bool = True) -> tuple[Any, None]:
        return self._act(self.normalize(obs)), None

    def action_probs(self, obs: np.ndarray) -> np.ndarray:
        assert self._probs is not None
        return self._probs(self.normalize(obs))


def with_vecnormalize(fn: Any, path: str | os.PathLike) -> ObsNormalized:
    """``fn`` behind the observation statistics of a ``VecNormalize.save`` file (a pickle;
    Stable-Baselines3 must be importable to read it), checked by :func:`check_vecnormalize`.

    Raises:
        FileNotFoundError: no such file.
        PolicyError: not a ``VecNormalize`` pickle with observation statistics of 7 columns, or
            statistics that would put NaN or a constant into what the policy sees (the file and
            the field named).
    """
    with open(path, "rb") as f:
        try:
            vn = pickle.load(f)  # noqa: S301  (the user's own statistics file, as SB3's VecNormalize.load reads it)
        except Exception as e:
            raise PolicyError(f"{path}: not a VecNormalize statistics file ({type(e).__name__}: {e})") from e
    rms = getattr(vn, "obs_rms", None)
    mean, var = getattr(rms, "mean", None), getattr(rms, "var", None)
    if mean is None or var is None or np.shape(mean) != (7,) or np.shape(var) != (7,):
        raise PolicyError(f"{path}: no observation statistics of 7 columns (VecNormalize.obs_rms) in it")
    clip_obs, epsilon = getattr(vn, "clip_obs", 10.0), getattr(vn, "epsilon", 1e-8)
    if not getattr(vn, "norm_obs", True):
        # VecNormalize without norm_obs passes observations through as they are: no scaling, no clip
        return ObsNormalized(fn, np.zeros(7), np.ones(7) - 1e-8, clip_obs=np.inf, epsilon=1e-8)
    check_vecnormalize(path, mean, var, getattr(rms, "count", 1.0), clip_obs, epsilon)
    return ObsNormalized(fn, mean, var, clip_obs=clip_obs, epsilon=epsilon)


def _real_array(value: Any) -> np.ndarray | None:
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        return None
    return arr


def check_vecnormalize(path: str | os.PathLike, mean: Any, var: Any, count: Any, clip_obs: Any, epsilon: Any) -> None:
    """Refuse ``VecNormalize`` observation statistics the policy could not have been trained with.

    ``mean``, ``var``: ``[7]`` (columns :data:`sim.drivers.observe.CONTINUOUS_NAMES`). A NaN mean or
    a negative variance would put NaN into every observation the policy gets, an infinite variance
    would turn that column into 0 at every decision.

    Raises:
        PolicyError: ``obs_rms.mean`` not finite; ``obs_rms.var`` not finite or negative;
            ``obs_rms.count`` not a positive finite number; ``clip_obs`` not positive;
            ``epsilon`` not a positive finite number (``path``, the field and the column named).
    """
    from sim.drivers.observe import CONTINUOUS_NAMES

    for field_name, value, ok, want in (
            ("obs_rms.mean", mean, np.isfinite, "finite numbers"),
            ("obs_rms.var", var, lambda a: np.isfinite(a) & (a >= 0), "finite numbers >= 0")):
        arr = _real_array(value)
        if arr is None or arr.shape != (len(CONTINUOUS_NAMES),):
            raise PolicyError(f"{path}: {field_name} must be {len(CONTINUOUS_NAMES)} numbers, got {value!r}")
        bad = np.flatnonzero(~ok(arr))
        if bad.size:
            cols = ", ".join(f"{CONTINUOUS_NAMES[i]} {float(arr[i])}" for i in bad)
            raise PolicyError(f"{path}: {field_name} must be {want}, got {cols}")
    for field_name, value, allow_inf in (("obs_rms.count", count, False), ("clip_obs", clip_obs, True),
                                         ("epsilon", epsilon, False)):
        arr = _real_array(value)
        if arr is None or arr.size != 1 or not (arr.item() > 0 and (allow_inf or np.isfinite(arr.item()))):
            raise PolicyError(f"{path}: {field_name} must be a positive{'' if allow_inf else ' finite'} number, "
                              f"got {value!r}")


def heldout_probs_loglik(probs_fn: Callable[[np.ndarray], np.ndarray], obs: np.ndarray,
                         actions: np.ndarray) -> tuple[float, float]:
    """``(total, per decision)`` log-likelihood of ``actions [N]`` (0..4) under ``probs_fn(obs [N, 7])``.

    Raises:
        PolicyError: probabilities not ``[N, 5]`` finite numbers.
    """
    if len(actions) == 0:
        return 0.0, float("nan")
    p = np.asarray(probs_fn(obs), dtype=np.float64)
    if p.shape != (len(actions), N_ACTIONS) or not np.all(np.isfinite(p)):
        raise PolicyError(f"the policy's action probabilities must be [{len(actions)}, {N_ACTIONS}] finite numbers, "
                          f"got shape {p.shape}")
    ll = np.log(np.clip(p[np.arange(len(actions)), actions], 1e-300, None))
    return float(ll.sum()), float(ll.mean())
