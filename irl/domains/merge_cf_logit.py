"""The car-following logit driver: a conditional logit on :mod:`irl.domains.merge_car_following`'s
features, and its file (``cf_model.json``, format ``merge-irl-cf-logit/1``).

``pi(a | x) = softmax_a(theta . phi(x, a))`` over the five merge actions, ``phi`` the
car-following features of the continuous observation ``x`` (A's speed, gaps and closing
speeds to C and B, A's previous action); fitted by maximum likelihood
(:func:`irl.conditional_logit.fit_conditional_logit`, i.e. maximum-likelihood IRL at discount 0).
Trained on demonstrations alone, or on demonstrations plus expert labels in the states the
learned driver reaches (DAgger; ``analysis.dagger``), which ``info`` records.
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

from irl.atomic import write_json_atomic
from irl.conditional_logit import conditional_log_policy, conditional_loglik, fit_conditional_logit
from irl.domains.merge_actions import N_ACTIONS
from irl.domains.merge_car_following import CF_FEATURES, CFDecisions, GapNeed, car_following_features
from irl.errors import ConfigError, ModelFileError

#: The ``format`` field of a car-following logit file.
CF_FORMAT = "merge-irl-cf-logit/1"


@dataclass(frozen=True)
class CarFollowingLogit:
    """A fitted car-following logit driver.

    Attributes:
        theta: ``[K]`` weights of :data:`~irl.domains.merge_car_following.CF_FEATURES`.
        action_acc_ft_s2: ``[5]`` acceleration applied per action (ft/s^2): the mean of each
            action's training decisions.
        decision_step_s: seconds per decision (the resampling of the demonstrations).
        gap_need: the nominal IDM parameters of the features.
        l2: the L2 penalty of the fit.
        loglik: training log-likelihood of the demonstrations (nats; expert labels excluded).
        converged: the optimiser's last fit reported success.
        info: provenance, e.g. ``n_demo_steps``, ``dagger_rounds``, ``labels_per_round``.
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
            raise ConfigError(f"theta must be {len(CF_FEATURES)} finite numbers ({CF_FEATURES}), got {theta}")
        object.__setattr__(self, "theta", theta)
        acc = tuple(float(x) for x in self.action_acc_ft_s2)
        if len(acc) != N_ACTIONS or not all(math.isfinite(x) for x in acc):
            raise ConfigError(f"action_acc_ft_s2 must be {N_ACTIONS} finite numbers, got {acc}")
        object.__setattr__(self, "action_acc_ft_s2", acc)
        if not (math.isfinite(self.decision_step_s) and self.decision_step_s > 0):
            raise ConfigError(f"decision_step_s must be positive, got {self.decision_step_s}")

    @property
    def feature_names(self) -> tuple[str, ...]:
        return CF_FEATURES

    @classmethod
    def fit(cls, demos: CFDecisions, *, l2: float = 0.1, labels: CFDecisions | None = None,
            info: dict[str, Any] | None = None) -> CarFollowingLogit:
        """Fit on the demonstrations' decisions (plus expert ``labels``, weighted as demonstrations).

        Raises:
            ConfigError: a bad ``l2``; DemonstrationError: malformed decisions.
        """
        gap_need = GapNeed()
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
        """``[N, 5]`` ``log pi(a | x)`` for observations ``obs [N, 5]`` (``d_AC, v_AC, d_AB,
        v_AB, v_A``; ft, ft/s) and previous actions ``prev [N]`` (-1: unknown)."""
        return conditional_log_policy(car_following_features(obs, prev, self.action_acc_ft_s2, self.gap_need), self.theta)

    def loglik_of(self, decisions: CFDecisions) -> float:
        """Total log-likelihood (nats) of ``decisions``' actions under the driver."""
        F = car_following_features(decisions.obs, decisions.prev, self.action_acc_ft_s2, self.gap_need)
        return conditional_loglik(F, self.theta, decisions.actions)

    def to_json_dict(self) -> dict[str, Any]:
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
        """Read a ``cf_model.json``.

        Raises:
            ModelFileError: missing, unreadable, another format, or a malformed field (named).
        """
        path = Path(path)
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
        except FileNotFoundError:
            raise ModelFileError(f"{path}: no such model file") from None
        except (OSError, ValueError, UnicodeDecodeError) as e:
            raise ModelFileError(f"{path}: not a readable JSON model file ({type(e).__name__}: {str(e)[:200]})") from None
        if not isinstance(data, dict) or data.get("format") != CF_FORMAT:
            got = data.get("format") if isinstance(data, dict) else type(data).__name__
            raise ModelFileError(f"{path}: expected format {CF_FORMAT!r}, got {got!r}")
        if data.get("feature_names") != list(CF_FEATURES):
            raise ModelFileError(f"{path}: field 'feature_names' must be {list(CF_FEATURES)}")
        try:
            gap = GapNeed(**data["gap_need"])
            loglik = data.get("loglik")
            return cls(np.asarray(data["theta"], dtype=np.float64), tuple(data["action_acc_ft_s2"]),
                       float(data["decision_step_s"]), gap, float(data.get("l2", 0.1)),
                       float("nan") if loglik is None else float(loglik), bool(data.get("converged", True)),
                       dict(data.get("info") or {}))
        except KeyError as e:
            raise ModelFileError(f"{path}: missing field {e.args[0]!r}") from None
        except (TypeError, ValueError, ConfigError) as e:
            raise ModelFileError(f"{path}: {e}") from None
