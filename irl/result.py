"""The result of an IRL fit, and the saved-model contract (``model.json``)."""

from __future__ import annotations

import json
import math
import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from irl.boltzmann import log_policy
from irl.config import IRLConfig
from irl.errors import ModelFileError

METHODS = ("qavg", "qsm", "mlirl", "reirl")


@dataclass(frozen=True)
class FitResult:
    """What every IRL method returns.

    Attributes:
        method: one of ``METHODS``.
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

    @classmethod
    def from_fit(cls, fit: FitResult, **kw: Any) -> "SavedModel":
        return cls(
            method=fit.method, theta=np.asarray(fit.theta), loglik=fit.loglik, q=np.asarray(fit.q),
            config=fit.config, converged=fit.converged, unbounded=fit.unbounded, **kw,
        )

    def log_policy(self) -> np.ndarray:
        """``[S, A]`` log pi(a|s)."""
        return log_policy(self.q, self.config.beta)

    def to_json_dict(self) -> dict[str, Any]:
        return {
            "format": "merge-irl-model/1",
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
        }

    def save(self, path: str | os.PathLike) -> Path:
        """Write atomically (temporary file, then rename)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=path.name + ".", suffix=".tmp", dir=path.parent)
        try:
            with os.fdopen(fd, "w") as f:
                json.dump(self.to_json_dict(), f, indent=1)
            os.replace(tmp, path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
        return path

    @classmethod
    def load(cls, path: str | os.PathLike) -> "SavedModel":
        path = Path(path)
        try:
            data = json.loads(path.read_text())
        except FileNotFoundError:
            raise ModelFileError(f"{path}: no such model file") from None
        except (json.JSONDecodeError, UnicodeDecodeError) as e:
            raise ModelFileError(f"{path}: not a JSON model file ({e})") from None
        if not isinstance(data, dict):
            raise ModelFileError(f"{path}: expected a JSON object at top level")
        for key in ("method", "theta", "loglik", "settings", "q"):
            if key not in data:
                raise ModelFileError(f"{path}: missing field {key!r}")
        if data["method"] not in METHODS:
            raise ModelFileError(f"{path}: field 'method' must be one of {METHODS}, got {data['method']!r}")
        try:
            theta = np.asarray(data["theta"], dtype=float)
            q = np.asarray(data["q"], dtype=float)
            loglik = float(data["loglik"])
        except (TypeError, ValueError) as e:
            raise ModelFileError(f"{path}: fields 'theta', 'q', 'loglik' must be numeric ({e})") from None
        if theta.ndim != 1 or theta.size == 0 or not np.all(np.isfinite(theta)):
            raise ModelFileError(f"{path}: field 'theta' must be a non-empty list of finite numbers")
        if q.ndim != 2 or q.size == 0 or not np.all(np.isfinite(q)):
            raise ModelFileError(f"{path}: field 'q' must be a finite [S][A] table")
        if math.isnan(loglik):
            raise ModelFileError(f"{path}: field 'loglik' is NaN")
        if not isinstance(data["settings"], dict):
            raise ModelFileError(f"{path}: field 'settings' must be an object")
        try:
            config = IRLConfig.from_dict(data["settings"])
        except (TypeError, ValueError) as e:
            raise ModelFileError(f"{path}: field 'settings': {e}") from None
        edges_raw = data.get("bin_edges", {}) or {}
        if not isinstance(edges_raw, dict):
            raise ModelFileError(f"{path}: field 'bin_edges' must be an object")
        try:
            edges = {str(k): tuple(float(x) for x in v) for k, v in edges_raw.items()}
        except (TypeError, ValueError) as e:
            raise ModelFileError(f"{path}: field 'bin_edges' must map names to number lists ({e})") from None
        return cls(
            method=data["method"], theta=theta, loglik=loglik, q=q, config=config,
            domain=str(data.get("domain", "")),
            feature_names=tuple(str(x) for x in data.get("feature_names", []) or []),
            bin_edges=edges,
            converged=bool(data.get("converged", True)),
            unbounded=bool(data.get("unbounded", False)),
            info=dict(data.get("info", {}) or {}),
        )
