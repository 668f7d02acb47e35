"""The result of an IRL fit, and the saved-model contract (``model.json``)."""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from irl.boltzmann import log_policy
from irl.config import IRLConfig
from irl.domains.merge.actions import ACTION_ACC_FT_S2
from irl.domains.merge.states import STATE_ENCODINGS
from irl.errors import ModelFileError
from irl.methods.registry import method_names
from merge_irl.atomic import write_json_atomic
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
            ModelFileError: a missing, unreadable or malformed file (naming the field at fault).
        """
        path = Path(path)
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
        except FileNotFoundError:
            raise ModelFileError(f"{path}: no such model file") from None
        except OSError as e:
            raise ModelFileError(f"{path}: cannot read model file ({e.strerror or e})") from None
        except (ValueError, UnicodeDecodeError, RecursionError) as e:  # JSONDecodeError is a ValueError
            raise ModelFileError(f"{path}: not a JSON model file ({type(e).__name__}: {str(e)[:200]})") from None
        if not isinstance(data, dict):
            raise ModelFileError(f"{path}: expected a JSON object at top level, got {_json_type(data)}")
        fmt = data.get("format")
        if isinstance(fmt, str) and fmt.partition("/")[0] != MODEL_FORMAT.partition("/")[0]:
            raise ModelFileError(f"{path}: format {fmt!r} is not a tabular IRL model's ({MODEL_FORMAT!r}, "
                                 "'merge-irl learn')")
        for key in ("method", "theta", "loglik", "settings", "q"):
            if key not in data:
                raise ModelFileError(f"{path}: missing field {key!r}")
        if not isinstance(data["method"], str) or data["method"] not in method_names():
            raise ModelFileError(f"{path}: field 'method' must be one of {method_names()}, got {_brief(data['method'])}")
        theta = _number_array(path, "theta", data["theta"], 1)
        q = _number_array(path, "q", data["q"], 2)
        if not np.all(np.isfinite(theta)):
            raise ModelFileError(f"{path}: field 'theta' must be a non-empty list of finite numbers")
        if not np.all(np.isfinite(q)):
            raise ModelFileError(f"{path}: field 'q' must be a finite [S][A] table")
        loglik = data["loglik"]
        if isinstance(loglik, bool) or not isinstance(loglik, (int, float)):
            raise ModelFileError(f"{path}: field 'loglik' must be a number, got {_json_type(loglik)}")
        try:
            loglik = float(loglik)
        except OverflowError:
            raise ModelFileError(f"{path}: field 'loglik' is out of range") from None
        if math.isnan(loglik):
            raise ModelFileError(f"{path}: field 'loglik' is NaN")
        config = _settings(path, data["settings"])
        edges_raw = data.get("bin_edges", {})
        if edges_raw is None:
            edges_raw = {}
        if not isinstance(edges_raw, dict):
            raise ModelFileError(f"{path}: field 'bin_edges' must be an object, got {_json_type(edges_raw)}")
        edges = {}
        for k, v in edges_raw.items():
            arr = _number_array(path, f"bin_edges.{k}", v, 1, allow_empty=True)
            if np.any(np.isnan(arr)):
                raise ModelFileError(f"{path}: field 'bin_edges.{k}' holds NaN")
            edges[str(k)] = tuple(float(x) for x in arr)
        names = data.get("feature_names", [])
        if names is None:
            names = []
        if not isinstance(names, list) or not all(isinstance(x, str) for x in names):
            raise ModelFileError(f"{path}: field 'feature_names' must be a list of strings")
        if names and len(names) != theta.size:
            raise ModelFileError(
                f"{path}: field 'feature_names' has {len(names)} names for {theta.size} weights in 'theta'")
        domain = data.get("domain", "")
        if not isinstance(domain, str):
            raise ModelFileError(f"{path}: field 'domain' must be a string, got {_json_type(domain)}")
        flags = {}
        for key, default in (("converged", True), ("unbounded", False)):
            flags[key] = data.get(key, default)
            if not isinstance(flags[key], bool):
                raise ModelFileError(f"{path}: field {key!r} must be true or false, got {_brief(flags[key])}")
        info = data.get("info", {})
        if info is None:
            info = {}
        if not isinstance(info, dict):
            raise ModelFileError(f"{path}: field 'info' must be an object, got {_json_type(info)}")
        extra = _driver_fields(path, data)
        return cls(
            method=data["method"], theta=theta, loglik=loglik, q=q, config=config,
            domain=domain, feature_names=tuple(names), bin_edges=edges,
            converged=flags["converged"], unbounded=flags["unbounded"], info=dict(info), **extra,
        )


def _driver_fields(path: Path, data: dict) -> dict[str, Any]:
    """The driver fields (state encoding, decision step, action accelerations, ...), with the
    defaults of files written before them."""
    out: dict[str, Any] = {}
    enc = data.get("state_encoding", "paper")
    if enc not in STATE_ENCODINGS:
        raise ModelFileError(f"{path}: field 'state_encoding' must be one of {STATE_ENCODINGS}, got {_brief(enc)}")
    out["state_encoding"] = enc
    raw = data.get("decision_step_s", FRAME_S)
    try:  # a JSON integer may be too large for a float
        step = float(raw) if isinstance(raw, (int, float)) and not isinstance(raw, bool) else math.nan
    except OverflowError:
        step = math.nan
    # a whole number of 0.1 s frames: the decision step the demonstrations were resampled to
    frames = round(step / 0.1) if math.isfinite(step) else 0
    if not (math.isfinite(step) and step > 0 and frames >= 1 and abs(frames * 0.1 - step) < 1e-9):
        raise ModelFileError(f"{path}: field 'decision_step_s' must be a positive multiple of 0.1 s, got {_brief(raw)}")
    out["decision_step_s"] = step
    acc = _number_array(path, "action_acc_ft_s2", data.get("action_acc_ft_s2", list(DEFAULT_ACTION_ACC)), 1)
    if acc.size != len(DEFAULT_ACTION_ACC) or not np.all(np.isfinite(acc)):
        raise ModelFileError(f"{path}: field 'action_acc_ft_s2' must be {len(DEFAULT_ACTION_ACC)} finite numbers")
    out["action_acc_ft_s2"] = tuple(float(x) for x in acc)
    for key, default in (("feature_set", ""), ("unvisited_rule", "none")):
        val = data.get(key, default)
        if not isinstance(val, str):
            raise ModelFileError(f"{path}: field {key!r} must be a string, got {_brief(val)}")
        out[key] = val
    return out


def _json_type(value: Any) -> str:
    return {dict: "an object", list: "a list", str: "a string", bool: "a boolean", int: "a number",
            float: "a number", type(None): "null"}.get(type(value), type(value).__name__)


def _brief(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:50] + "..."


def _number_array(path: Path, name: str, value: Any, ndim: int, *, allow_empty: bool = False) -> np.ndarray:
    """``value`` as a float array of ``ndim`` dims (a list, or a list of equal-length lists)."""
    shape = "a list of numbers" if ndim == 1 else "a list of equal-length lists of numbers ([S][A])"

    def flat(v: Any, depth: int) -> list:
        if depth == 0:
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                raise ModelFileError(f"{path}: field {name!r} must be {shape}; found {_brief(v)}")
            return [v]
        if not isinstance(v, list):
            raise ModelFileError(f"{path}: field {name!r} must be {shape}; found {_json_type(v)}")
        return [x for item in v for x in flat(item, depth - 1)]

    flat(value, ndim)
    try:
        arr = np.asarray(value, dtype=float)
    except (ValueError, OverflowError) as e:
        raise ModelFileError(f"{path}: field {name!r} must be {shape} ({e})") from None
    if arr.ndim != ndim or (arr.size == 0 and not allow_empty):
        raise ModelFileError(f"{path}: field {name!r} must be non-empty {shape}, got shape {arr.shape}")
    return arr


def _settings(path: Path, raw: Any) -> IRLConfig:
    """``IRLConfig`` from the ``settings`` object, with each value's JSON type checked."""
    if not isinstance(raw, dict):
        raise ModelFileError(f"{path}: field 'settings' must be an object, got {_json_type(raw)}")
    defaults = IRLConfig()
    for key, value in raw.items():
        if not hasattr(defaults, key):
            continue  # reported by IRLConfig.from_dict below, with the known names
        want = type(getattr(defaults, key))
        ok = (isinstance(value, bool) if want is bool else
              isinstance(value, str) if want is str else
              isinstance(value, int) and not isinstance(value, bool) if want is int else
              isinstance(value, (int, float)) and not isinstance(value, bool))
        if not ok:
            raise ModelFileError(
                f"{path}: field 'settings.{key}' must be {'a number' if want in (int, float) else want.__name__}"
                f"{' (integer)' if want is int else ''}, got {_brief(value)}")
        if want is float:
            try:
                float(value)
            except OverflowError:
                raise ModelFileError(f"{path}: field 'settings.{key}' is out of range") from None
    try:
        return IRLConfig.from_dict(raw)
    except (TypeError, ValueError, OverflowError) as e:
        raise ModelFileError(f"{path}: field 'settings': {e}") from None
