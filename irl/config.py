"""Configuration of an IRL fit (frozen, serialisable)."""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields, replace
from typing import Any

from irl.errors import ConfigError

SOLVERS = ("exact", "faithful")
#: What a model-free method (Q-Avg, Q-SM) bootstraps from at a pair with no observed successor
#: (:mod:`irl.unobserved_successors`).
UNOBSERVED_RULES = ("terminal", "self", "kinematic")


@dataclass(frozen=True)
class IRLConfig:
    """Settings shared by every IRL method.

    Defaults are the paper's (section 4): beta 0.01, alpha 0.01, gamma 0.99, theta initialised
    uniformly in [-1, 1]. ``IRLConfig.reference()`` gives the authors' code's settings.

    Attributes:
        beta: Boltzmann inverse temperature of ``pi(a|s) = softmax_a(beta Q(s, a))``.
        gamma: discount factor.
        alpha: learning rate of the damped Q sweep (``faithful`` solver only; the fixed point
            does not depend on it).
        solver: ``"exact"`` (fixed point solved directly, L-BFGS ascent) or ``"faithful"``
            (paper-literal damped sweeps and fixed-length gradient steps).
        init_low, init_high: theta is initialised uniform in ``[init_low, init_high]``.
        tol: outer stopping tolerance ``eps``; the faithful ascent stops when
            ``|L' - L| < tol`` (``stop_scale_by_gamma`` multiplies it by ``(1-gamma)/gamma``).
        stop_scale_by_gamma: apply the paper's ``(1-gamma)/gamma`` factor to ``tol``.
        max_outer: cap on outer (gradient) iterations.
        max_inner: cap on inner (Q) sweeps / fixed-point iterations per outer step.
        inner_tol: inner loop stops when the largest change of Q is below this.
        step_size: length of the faithful solver's unit-normalised gradient step.
        l2: L2 penalty ``l2/2 ||theta||^2`` subtracted from the objective (0 = none).
        unobserved: Q-Avg and Q-SM only: the successor of a pair with no observed successor,
            one of :data:`UNOBSERVED_RULES` (:mod:`irl.unobserved_successors`): ``"terminal"`` (``Q = R``,
            the paper's and the authors' code's), ``"self"`` (the state itself,
            ``Q = R + gamma V(s)``) or ``"kinematic"`` (a domain model's next state, passed to
            the fit as ``fallback_next``). The exact solver only.
    """

    beta: float = 0.01
    gamma: float = 0.99
    alpha: float = 0.01
    solver: str = "exact"
    init_low: float = -1.0
    init_high: float = 1.0
    tol: float = 1e-4
    stop_scale_by_gamma: bool = True
    max_outer: int = 20000
    max_inner: int = 10000
    inner_tol: float = 1e-4
    step_size: float = 0.1
    l2: float = 0.0
    unobserved: str = "terminal"

    def __post_init__(self) -> None:
        if not (self.beta > 0 and self.beta < float("inf")):
            raise ConfigError(f"beta must be a positive finite number, got {self.beta}")
        if not (0.0 <= self.gamma < 1.0):
            raise ConfigError(f"gamma must be in [0, 1), got {self.gamma}")
        if not (0.0 < self.alpha <= 1.0):
            raise ConfigError(f"alpha must be in (0, 1], got {self.alpha}")
        if self.solver not in SOLVERS:
            raise ConfigError(f"solver must be one of {SOLVERS}, got {self.solver!r}")
        if not self.init_low <= self.init_high:
            raise ConfigError(f"init_low {self.init_low} > init_high {self.init_high}")
        for name in ("tol", "inner_tol", "step_size"):
            if not getattr(self, name) > 0:
                raise ConfigError(f"{name} must be positive, got {getattr(self, name)}")
        for name in ("max_outer", "max_inner"):
            if int(getattr(self, name)) < 1:
                raise ConfigError(f"{name} must be >= 1, got {getattr(self, name)}")
        if not self.l2 >= 0:
            raise ConfigError(f"l2 must be >= 0, got {self.l2}")
        if self.unobserved not in UNOBSERVED_RULES:
            raise ConfigError(f"unobserved must be one of {UNOBSERVED_RULES}, got {self.unobserved!r}")
        if self.unobserved != "terminal" and self.solver == "faithful":
            raise ConfigError(f"unobserved={self.unobserved!r} needs the exact solver (the faithful one "
                              "reproduces the authors' terminal pairs)")

    @property
    def outer_tol(self) -> float:
        """The effective outer stopping threshold on ``|L' - L|``."""
        if self.stop_scale_by_gamma and self.gamma > 0:
            return self.tol * (1.0 - self.gamma) / self.gamma
        return self.tol

    @classmethod
    def paper(cls, **overrides: Any) -> IRLConfig:
        """The paper's settings (gamma 0.99, alpha 0.01, beta 0.01)."""
        return replace(cls(), **overrides)

    @classmethod
    def reference(cls, **overrides: Any) -> IRLConfig:
        """The authors' code's settings: gamma 0.9, alpha 0.1, stop at ``|dL| <= 1e-4`` unscaled."""
        return replace(cls(gamma=0.9, alpha=0.1, tol=1e-4, stop_scale_by_gamma=False), **overrides)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> IRLConfig:
        """The settings in ``data`` (as written by :meth:`to_dict`); missing ones take the defaults.

        Raises:
            ConfigError: an unknown setting, or a value the settings' checks reject.
        """
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise ConfigError(f"unknown IRL setting(s) {unknown}; known: {sorted(known)}")
        return cls(**data)
