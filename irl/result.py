"""The result of an IRL fit, and the saved-model contract (``model.json``)."""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any

import numpy as np
from pydantic import BaseModel, Field, ValidationInfo, field_validator

from irl.boltzmann import log_policy
from irl.config import IRLConfig
from irl.domains.merge.actions import ACTION_ACC_FT_S2
from irl.domains.merge.states import STATE_ENCODINGS
from irl.errors import ConfigError, ModelFileError
from irl.methods.registry import method_names
from merge_irl.atomic import write_json_atomic
from merge_irl.json_file import STRICT, dataclass_schema, read_json_object, to_dataclass, validate
from merge_irl.units import FRAME_S

#: ``action_acc_ft_s2`` of files written before the field existed: the bin midpoints.
#: The ``format`` field of a tabular model file (``model.json`` of ``merge-irl learn``).
MODEL_FORMAT = "merge-irl-model/1"

DEFAULT_ACTION_ACC: tuple[float, ...] = tuple(float(x) for x in ACTION_ACC_FT_S2)


@dataclass(frozen=True)
class FitResult:
    """What every IRL method returns.

    Attributes:
        method: a registered method (:data:`irl.methods.registry.REGISTRY`).
        theta: ``[K]`` learned reward weights.
        loglik: final log-likelihood ``L(theta)`` of the training demonstrations (Eq. 5 without
            ``log Pr(s_1)``), for the model-free methods under their own Q; for REIRL under the
            MDP solved for the learned theta.
        q: ``[S, A]`` Q values at ``theta``; the policy is ``softmax(beta q)``.
        config: the settings used.
        loglik_trace: ``[n_iterations]`` L after each outer iteration.
        theta_trace: ``[n_iterations, K]`` theta after each outer iteration.
        converged: whether the stopping rule was met (and for Q-SM/MLIRL, the inner fixed
            point converged) before any cap.
        message: human-readable status (why it stopped; unbounded weights; Q-SM divergence).
        wall_time_s: seconds spent in ``fit``.
        unbounded: the likelihood has no finite maximiser (weights grow without bound); the
            reported ``loglik`` is then the supremum approached.
        extra: method-specific scalars (e.g. inner iterations, solver status).
    """

    method: str
    theta: np.ndarray
    loglik: float
    q: np.ndarray
    config: IRLConfig
    loglik_trace: np.ndarray
    theta_trace: np.ndarray
    converged: bool
    message: str = ""
    wall_time_s: float = 0.0
    unbounded: bool = False
    extra: dict[str, float] = field(default_factory=dict)

    @property
    def n_iterations(self) -> int:
        return int(len(self.loglik_trace))

    @property
    def flags(self) -> tuple[str, ...]:
        """What downstream code must check before ranking or deploying the model (empty: none).

        ``"not_converged"``, ``"unbounded"`` (no finite maximiser; for REIRL the dual is
        unbounded below), ``"infeasible"`` (REIRL: the experts' counts are out of reach within
        eps), ``"uninformative"`` (REIRL: every weight is 0).
        """
        out = [] if self.converged else ["not_converged"]
        if self.unbounded:
            out.append("unbounded")
        out += [k for k in ("infeasible", "uninformative") if self.extra.get(k)]
        return tuple(out)

    def log_policy(self) -> np.ndarray:
        """``[S, A]`` log pi(a|s) of the learned policy."""
        return log_policy(self.q, self.config.beta)


@dataclass(frozen=True)
class SavedModel:
    """The ``model.json`` contract read by ``evaluate``, the closed loop and other scripts.

    Attributes:
        method, theta, loglik, config: as in ``FitResult``.
        q: ``[S, A]`` Q table defining the policy ``softmax(beta q)``.
        feature_names: ``K`` names, or empty.
        bin_edges: for the merge domain, the state bin edges by variable name
            (``{"d_AC": [...4 inner edges...], ...}``); empty otherwise.
        domain: ``"gridworld" | "merge" | "npz"``.
        info: free-form provenance (data path, seed, trials, versions).
        state_encoding: merge state encoding, ``"paper"`` (1250 states) or ``"driver"``
            (6250: times A's previous action); :data:`irl.domains.merge.states.STATE_ENCODINGS`.
        decision_step_s: seconds between decisions the demonstrations were resampled at (and
            the kinematic fallback used); files without it load as 0.1.
        action_acc_ft_s2: ``[5]`` acceleration (ft/s^2) the closed loop applies per action:
            each action's conditional mean in the training data; files without it load as
            the bin midpoints.
        feature_set: name of the feature set (``"paper"``, ``"driver"`` or ``"custom"``).
        unvisited_rule: how ``q`` is defined in states never seen in training
            (``"none"``: the method's own value; see :mod:`irl.unvisited_states`).
    """

    method: str
    theta: np.ndarray
    loglik: float
    q: np.ndarray
    config: IRLConfig
    domain: str = ""
    feature_names: tuple[str, ...] = ()
    bin_edges: dict[str, tuple[float, ...]] = field(default_factory=dict)
    converged: bool = True
    unbounded: bool = False
    info: dict[str, Any] = field(default_factory=dict)
    state_encoding: str = "paper"
    decision_step_s: float = FRAME_S  # files written before the field: the 0.1 s frame
    action_acc_ft_s2: tuple[float, ...] = DEFAULT_ACTION_ACC
    feature_set: str = ""
    unvisited_rule: str = "none"

    @classmethod
    def from_fit(cls, fit: FitResult, **kw: Any) -> SavedModel:
        return cls(
            method=fit.method, theta=np.asarray(fit.theta), loglik=fit.loglik, q=np.asarray(fit.q),
            config=fit.config, converged=fit.converged, unbounded=fit.unbounded, **kw,
        )

    def log_policy(self) -> np.ndarray:
        """``[S, A]`` log pi(a|s)."""
        return log_policy(self.q, self.config.beta)

    def to_json_dict(self) -> dict[str, Any]:
        return {
            "format": MODEL_FORMAT,
            "method": self.method,
            "theta": [float(x) for x in self.theta],
            "loglik": float(self.loglik),
            "settings": self.config.to_dict(),
            "domain": self.domain,
            "feature_names": list(self.feature_names),
            "bin_edges": {k: [float(x) for x in v] for k, v in self.bin_edges.items()},
            "converged": bool(self.converged),
            "unbounded": bool(self.unbounded),
            "q": np.asarray(self.q, dtype=float).tolist(),
            "info": self.info,
            "state_encoding": self.state_encoding,
            "decision_step_s": float(self.decision_step_s),
            "action_acc_ft_s2": [float(x) for x in self.action_acc_ft_s2],
            "feature_set": self.feature_set,
            "unvisited_rule": self.unvisited_rule,
        }

    def save(self, path: str | os.PathLike) -> Path:
        """Write atomically (temporary file, then rename)."""
        return write_json_atomic(path, self.to_json_dict())

    @classmethod
    def load(cls, path: str | os.PathLike) -> SavedModel:
        """Read a ``model.json``.

        Raises:
            ModelFileError: a missing, unreadable or malformed file (one line naming the file and
                the field path at fault, e.g. ``model.json: settings.gamma: ...``).
        """
        return cls.from_json_dict(read_json_object(path, what="model file", error=ModelFileError), Path(path))

    @classmethod
    def from_json_dict(cls, data: Any, source: str | os.PathLike = "<dict>") -> SavedModel:
        """The model of a parsed ``model.json`` object (:meth:`to_json_dict`'s layout), validated
        by its schema (:class:`ModelFileSchema`); ``source`` names it in messages.

        Raises:
            ModelFileError: a malformed field (``source: field.path: problem``).
        """
        m = validate(ModelFileSchema, data, source, error=ModelFileError)
        try:
            config = to_dataclass(IRLConfig, m.settings)
        except (ConfigError, TypeError, ValueError, OverflowError) as e:
            name, _, rest = str(e).partition(" ")  # IRLConfig's checks say "<field> must be ..."
            where = f"settings.{name}: {rest}" if name in SettingsSchema.model_fields else f"settings: {e}"
            raise ModelFileError(f"{source}: {where}") from None
        return cls(
            method=m.method, theta=np.asarray(m.theta, dtype=float), loglik=m.loglik,
            q=np.asarray(m.q, dtype=float), config=config, domain=m.domain,
            feature_names=tuple(m.feature_names or ()),
            bin_edges={k: tuple(v) for k, v in (m.bin_edges or {}).items()},
            converged=m.converged, unbounded=m.unbounded, info=dict(m.info or {}),
            state_encoding=m.state_encoding, decision_step_s=m.decision_step_s,
            action_acc_ft_s2=tuple(m.action_acc_ft_s2), feature_set=m.feature_set,
            unvisited_rule=m.unvisited_rule,
        )


Finite = Annotated[float, Field(allow_inf_nan=False)]
#: The ``settings`` object: :class:`IRLConfig`'s fields, each of its default's JSON type, no others
#: (the value checks are ``IRLConfig``'s own).
SettingsSchema = dataclass_schema(IRLConfig)


class ModelFileSchema(BaseModel):
    """The schema of a ``model.json`` (:class:`SavedModel`'s fields as JSON; files written before
    the later fields load with their defaults, null lists and objects as empty)."""

    model_config = STRICT

    format: Any = None
    method: str
    theta: list[Finite] = Field(min_length=1)
    loglik: float
    settings: SettingsSchema  # type: ignore[valid-type]
    q: list[Annotated[list[Finite], Field(min_length=1)]] = Field(min_length=1)
    domain: str = ""
    feature_names: list[str] | None = None
    bin_edges: dict[str, list[float]] | None = None
    converged: bool = True
    unbounded: bool = False
    info: dict[str, Any] | None = None
    state_encoding: str = "paper"
    decision_step_s: float = FRAME_S
    action_acc_ft_s2: list[Finite] = Field(default=list(DEFAULT_ACTION_ACC), min_length=len(DEFAULT_ACTION_ACC),
                                           max_length=len(DEFAULT_ACTION_ACC))
    feature_set: str = ""
    unvisited_rule: str = "none"

    @field_validator("format")
    @classmethod
    def _tabular(cls, fmt: Any) -> Any:
        if isinstance(fmt, str) and fmt.partition("/")[0] != MODEL_FORMAT.partition("/")[0]:
            raise ValueError(f"{fmt!r} is not a tabular IRL model's ({MODEL_FORMAT!r}, 'merge-irl learn')")
        return fmt

    @field_validator("method")
    @classmethod
    def _registered(cls, method: str) -> str:
        if method not in method_names():
            raise ValueError(f"must be one of {method_names()}, got {method!r}")
        return method

    @field_validator("loglik", "bin_edges")
    @classmethod
    def _no_nan(cls, value: Any) -> Any:
        values = [value] if isinstance(value, float) else [x for v in (value or {}).values() for x in v]
        if any(math.isnan(x) for x in values):
            raise ValueError("holds NaN")
        return value

    @field_validator("q")
    @classmethod
    def _table(cls, q: list[list[float]]) -> list[list[float]]:
        if len({len(row) for row in q}) != 1:
            raise ValueError("must be a list of equal-length lists of numbers ([S][A])")
        return q

    @field_validator("state_encoding")
    @classmethod
    def _encoding(cls, enc: str) -> str:
        if enc not in STATE_ENCODINGS:
            raise ValueError(f"must be one of {STATE_ENCODINGS}, got {enc!r}")
        return enc

    @field_validator("decision_step_s")
    @classmethod
    def _whole_frames(cls, step: float) -> float:
        # a whole number of 0.1 s frames: the decision step the demonstrations were resampled to
        frames = round(step / 0.1) if math.isfinite(step) else 0
        if not (step > 0 and frames >= 1 and abs(frames * 0.1 - step) < 1e-9):
            raise ValueError(f"must be a positive multiple of 0.1 s, got {step!r}")
        return step

    @field_validator("feature_names")
    @classmethod
    def _one_name_per_weight(cls, names: list[str] | None, info: ValidationInfo) -> list[str] | None:
        theta = info.data.get("theta")
        if names and theta is not None and len(names) != len(theta):
            raise ValueError(f"has {len(names)} names for {len(theta)} weights in 'theta'")
        return names
