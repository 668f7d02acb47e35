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
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any

import numpy as np
from pydantic import BaseModel, Field, field_validator

from irl.domains.merge.actions import N_ACTIONS
from irl.domains.merge.car_following import CF_FEATURES, CFDecisions, GapNeed, car_following_features
from irl.domains.merge.mdp import frames_per_step
from irl.errors import ConfigError, ModelFileError
from irl.methods.conditional_logit import conditional_log_policy, conditional_loglik, fit_conditional_logit
from merge_irl.atomic import write_json_atomic
from merge_irl.json_file import STRICT, dataclass_schema, read_json_object, to_dataclass, validate

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
                :data:`OLD_CF_FORMATS` with its reason), or a malformed field (one line naming the
                file and the field path).
        """
        return cls.from_json_dict(read_json_object(path, what="model file", error=ModelFileError), Path(path))

    @classmethod
    def from_json_dict(cls, data: Any, source: str | os.PathLike = "<dict>") -> CarFollowingLogit:
        """The driver of a parsed file object (:meth:`to_json_dict`'s layout), validated by
        :class:`CFLogitSchema`; ``source`` names it in messages.

        Raises:
            ModelFileError: as :meth:`load`.
        """
        m = validate(CFLogitSchema, data, source, error=ModelFileError)
        try:
            return cls(np.asarray(m.theta, dtype=np.float64), tuple(m.action_acc_ft_s2), m.decision_step_s,
                       to_dataclass(GapNeed, m.gap_need), m.l2, math.nan if m.loglik is None else m.loglik,
                       m.converged, dict(m.info or {}))
        except ConfigError as e:
            raise ModelFileError(f"{source}: {e}") from None


Finite = Annotated[float, Field(allow_inf_nan=False)]
#: ``gap_need``: every :class:`GapNeed` parameter, a number (their range is ``GapNeed``'s check).
GapNeedSchema = dataclass_schema(GapNeed, optional={})


class CFLogitSchema(BaseModel):
    """The schema of a car-following logit file (format :data:`CF_FORMAT`)."""

    model_config = STRICT

    format: Any = Field(default=None, validate_default=True)
    feature_names: list[str]
    theta: list[Finite] = Field(min_length=len(CF_FEATURES), max_length=len(CF_FEATURES))
    action_acc_ft_s2: list[Finite] = Field(min_length=N_ACTIONS, max_length=N_ACTIONS)
    decision_step_s: Finite
    gap_need: GapNeedSchema  # type: ignore[valid-type]  # built from the dataclass
    l2: Finite = Field(default=0.1, ge=0)
    loglik: Finite | None = Field(default=None, le=0)
    converged: bool = True
    info: dict[str, Any] | None = None

    @field_validator("format", mode="before")
    @classmethod
    def _this_format(cls, fmt: Any) -> Any:
        if isinstance(fmt, str) and fmt in OLD_CF_FORMATS:
            raise ValueError(f"{fmt!r}: {OLD_CF_FORMATS[fmt]}; train it again with 'merge-irl dagger' "
                             f"(writes {CF_FORMAT!r})")
        if fmt != CF_FORMAT:
            raise ValueError(f"expected format {CF_FORMAT!r} (a file of 'merge-irl dagger'), got {fmt!r}")
        return fmt

    @field_validator("feature_names")
    @classmethod
    def _cf_features(cls, names: list[str]) -> list[str]:
        if names != list(CF_FEATURES):
            raise ValueError(f"must be {list(CF_FEATURES)}, got {names!r}")
        return names
