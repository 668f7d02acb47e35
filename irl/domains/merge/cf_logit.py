"""The car-following logit driver: a conditional logit on :mod:`irl.domains.merge.car_following`'s
features, and its JSON file (format ``merge-irl-cf-logit/2``; ``merge-irl dagger`` writes
``cf-logit.json`` and ``cf-dagger.json``).

``pi(a | x) = softmax_a(theta . phi(x, a))`` over the five merge actions, ``phi`` the
car-following features of the continuous observation ``x`` (A's speed, gaps and closing
speeds to C and B, their lengths, A's previous action); fitted by maximum likelihood
(:func:`irl.methods.conditional_logit.fit_conditional_logit`, i.e. maximum-likelihood IRL at discount 0).
Trained on demonstrations alone, or on demonstrations plus expert labels in the states the
learned driver reaches (DAgger; ``analysis.experiments.dagger``), which ``info`` records.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from irl.domains.merge.actions import N_ACTIONS
from irl.domains.merge.car_following import CF_FEATURES, CFDecisions, GapNeed, car_following_features
from irl.domains.merge.mdp import frames_per_step
from irl.errors import ConfigError, ModelFileError
from irl.methods.conditional_logit import conditional_log_policy, conditional_loglik, fit_conditional_logit
from merge_irl.atomic import write_json_atomic

#: The ``format`` field of a car-following logit file.
CF_FORMAT = "merge-irl-cf-logit/2"
#: Earlier formats, refused on load with the reason: their weights belong to other features.
#: ``/1`` (2026-12-01): the gap features took every leader for a car (no vehicle lengths).
OLD_CF_FORMATS: dict[str, str] = {
    "merge-irl-cf-logit/1": "its weights were fitted on features that took every leader for a car; since "
                            "format /2 the features subtract the leader's own length, so these weights would "
                            "drive another driver",
}


@dataclass(frozen=True)
class CarFollowingLogit:
    """A fitted car-following logit driver.

    Attributes:
        theta: ``[K]`` weights of :data:`~irl.domains.merge.car_following.CF_FEATURES`.
        action_acc_ft_s2: ``[5]`` acceleration applied per action (ft/s^2): the mean of each
            action's training decisions.
        decision_step_s: seconds per decision (the resampling of the demonstrations).
        gap_need: the nominal IDM parameters of the features.
        l2: the L2 penalty of the fit.
        loglik: training log-likelihood of the demonstrations (nats; expert labels excluded).
        converged: the fit's optimiser reported success (saved as ``converged``).
        info: provenance: ``n_demo_steps``, ``n_label_steps``, ``dagger_round`` (0: the
            demonstrations alone), ``labels_per_round``, ``critical_actions``, ``label_seed``,
            ``episodes_per_round``.
    """

    theta: np.ndarray
    action_acc_ft_s2: tuple[float, ...]
    decision_step_s: float
    gap_need: GapNeed = GapNeed()
    l2: float = 0.1
    loglik: float = float("nan")
    converged: bool = True
    info: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        theta = np.asarray(self.theta, dtype=np.float64)
        if theta.shape != (len(CF_FEATURES),) or not np.all(np.isfinite(theta)):
            raise ConfigError(f"theta must be {len(CF_FEATURES)} finite numbers (one per feature), got shape "
                              f"{theta.shape}{'' if theta.shape != (len(CF_FEATURES),) else ' with NaN or infinite values'}")
        object.__setattr__(self, "theta", theta)
        acc = tuple(float(x) for x in self.action_acc_ft_s2)
        if len(acc) != N_ACTIONS or not all(math.isfinite(x) for x in acc):
            raise ConfigError(f"action_acc_ft_s2 must be {N_ACTIONS} finite numbers, got {acc}")
        object.__setattr__(self, "action_acc_ft_s2", acc)
        if any(b <= a for a, b in zip(acc, acc[1:])):
            raise ConfigError(f"action_acc_ft_s2 must increase from High Brake to High Accel, got {acc}")
        frames_per_step(self.decision_step_s)

    @property
    def feature_names(self) -> tuple[str, ...]:
        """The ``K`` feature names of ``theta`` (:data:`~irl.domains.merge.car_following.CF_FEATURES`)."""
        return CF_FEATURES

    @classmethod
    def fit(cls, demos: CFDecisions, *, l2: float = 0.1, labels: CFDecisions | None = None,
            gap_need: GapNeed | None = None, info: dict[str, Any] | None = None) -> CarFollowingLogit:
        """Fit on the demonstrations' ``N`` decisions (plus the ``M`` expert ``labels``, each
        weighted as one demonstrated decision): features ``[N + M, 5, K]``, L-BFGS from 0.

        Args:
            demos: the demonstrations (their action accelerations and step are the model's).
            l2: L2 penalty; labels: expert decisions or None; gap_need: the features' IDM
                parameters (None: :class:`GapNeed`'s defaults); info: provenance merged into ``info``.

        Returns:
            the model, ``loglik`` on the demonstrations alone.

        Raises:
            ConfigError: a bad ``l2``; DemonstrationError: malformed decisions.
        """
        gap_need = gap_need or GapNeed()
        F = car_following_features(demos.obs, demos.prev, demos.action_acc_ft_s2, gap_need)
        actions = demos.actions
        if labels is not None and labels.n:
            F = np.concatenate([F, car_following_features(labels.obs, labels.prev, demos.action_acc_ft_s2, gap_need)])
            actions = np.concatenate([actions, labels.actions])
        res = fit_conditional_logit(F, actions, l2=l2)
        model = cls(res.theta, demos.action_acc_ft_s2, demos.decision_step_s, gap_need, float(l2),
                    converged=res.converged,
                    info={"n_demo_steps": demos.n, "n_label_steps": labels.n if labels is not None else 0} | (info or {}))
        return dataclasses.replace(model, loglik=model.loglik_of(demos))

    def log_policy(self, obs: np.ndarray, prev: np.ndarray) -> np.ndarray:
        """``[N, 5]`` ``log pi(a | x)`` for observations ``obs [N, 7]`` (``d_AC, v_AC, d_AB,
        v_AB, v_A, len_C, len_B``; ft, ft/s; a length NaN: unknown) and previous actions
        ``prev [N]`` (-1: unknown)."""
        return conditional_log_policy(car_following_features(obs, prev, self.action_acc_ft_s2, self.gap_need), self.theta)

    def loglik_of(self, decisions: CFDecisions) -> float:
        """Total log-likelihood (nats) of ``decisions``' actions under the driver."""
        F = car_following_features(decisions.obs, decisions.prev, self.action_acc_ft_s2, self.gap_need)
        return conditional_loglik(F, self.theta, decisions.actions)

    def to_json_dict(self) -> dict[str, Any]:
        """The file's JSON object (format :data:`CF_FORMAT`; a non-finite ``loglik`` as null)."""
        return {"format": CF_FORMAT, "feature_names": list(CF_FEATURES), "theta": self.theta.tolist(),
                "action_acc_ft_s2": list(self.action_acc_ft_s2), "decision_step_s": self.decision_step_s,
                "gap_need": dataclasses.asdict(self.gap_need), "l2": self.l2,
                "loglik": self.loglik if math.isfinite(self.loglik) else None, "converged": self.converged,
                "info": self.info}

    def save(self, path: str | os.PathLike) -> Path:
        """Write atomically (temporary file, then rename)."""
        return write_json_atomic(path, self.to_json_dict())

    @classmethod
    def load(cls, path: str | os.PathLike) -> CarFollowingLogit:
        """Read a car-following logit file (``cf-logit.json`` / ``cf-dagger.json`` of ``merge-irl dagger``).

        Raises:
            ModelFileError: missing, unreadable, another format (an earlier one of
                :data:`OLD_CF_FORMATS` with its reason), or a malformed field (named).
        """
        path = Path(path)
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
        except FileNotFoundError:
            raise ModelFileError(f"{path}: no such model file") from None
        except (OSError, ValueError, UnicodeDecodeError, RecursionError) as e:
            raise ModelFileError(f"{path}: not a readable JSON model file ({type(e).__name__}: {str(e)[:200]})") from None
        if isinstance(data, dict) and isinstance(data.get("format"), str) and data["format"] in OLD_CF_FORMATS:
            raise ModelFileError(f"{path}: format {data['format']!r}: {OLD_CF_FORMATS[data['format']]}; "
                                 f"train it again with 'merge-irl dagger' (writes {CF_FORMAT!r})")
        if not isinstance(data, dict) or data.get("format") != CF_FORMAT:
            got = data.get("format") if isinstance(data, dict) else type(data).__name__
            raise ModelFileError(f"{path}: expected format {CF_FORMAT!r} (a file of 'merge-irl dagger'), "
                                 f"got {got!r}")
        for key in ("feature_names", "theta", "action_acc_ft_s2", "decision_step_s", "gap_need"):
            if key not in data:
                raise ModelFileError(f"{path}: missing field {key!r}")
        if data["feature_names"] != list(CF_FEATURES):
            raise ModelFileError(f"{path}: field 'feature_names' must be {list(CF_FEATURES)}")
        theta = _numbers(path, "theta", data["theta"], len(CF_FEATURES))
        acc = _numbers(path, "action_acc_ft_s2", data["action_acc_ft_s2"], N_ACTIONS)
        step = _number(path, "decision_step_s", data["decision_step_s"])
        raw_gap = data["gap_need"]
        names = {f.name for f in dataclasses.fields(GapNeed)}
        if not isinstance(raw_gap, dict) or set(raw_gap) != names:
            raise ModelFileError(f"{path}: field 'gap_need' must be an object with the keys {sorted(names)}")
        gap_values = {k: _number(path, f"gap_need.{k}", v) for k, v in raw_gap.items()}
        l2 = _number(path, "l2", data.get("l2", 0.1))
        loglik = data.get("loglik")
        loglik = float("nan") if loglik is None else _number(path, "loglik", loglik)
        converged = data.get("converged", True)
        if not isinstance(converged, bool):
            raise ModelFileError(f"{path}: field 'converged' must be true or false, got {converged!r}")
        info = data.get("info") or {}
        if not isinstance(info, dict):
            raise ModelFileError(f"{path}: field 'info' must be an object")
        if l2 < 0 or loglik > 0:
            raise ModelFileError(f"{path}: field 'l2' must be >= 0 and 'loglik' <= 0, got {l2}, {loglik}")
        try:
            return cls(theta, tuple(acc), step, GapNeed(**gap_values), l2, loglik, converged, dict(info))
        except ConfigError as e:
            raise ModelFileError(f"{path}: {e}") from None


def _number(path: Path, name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ModelFileError(f"{path}: field {name!r} must be a finite number, got {str(value)[:40]!r}")
    return float(value)


def _numbers(path: Path, name: str, value: Any, n: int) -> np.ndarray:
    if not isinstance(value, list) or len(value) != n:
        raise ModelFileError(f"{path}: field {name!r} must be a list of {n} finite numbers")
    return np.array([_number(path, f"{name}[{i}]", v) for i, v in enumerate(value)], dtype=np.float64)
