"""Tabular demonstrations: ragged trajectories of (state, action) pairs plus reward features.

This is the one input type of every IRL method. Next states are implied by order: the state
after step ``t`` of a trajectory is its step ``t+1``; a trajectory's last step has no observed
successor.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from irl.errors import DemonstrationError


@dataclass(frozen=True)
class Demonstrations:
    """Ragged (state, action) trajectories over a finite MDP, with features.

    Attributes:
        states: ``n_trajectories`` int64 arrays, trajectory ``i`` of shape ``[T_i]``.
        actions: same shapes as ``states``.
        features: float64 ``[S, A, K]``, the reward features ``phi(s, a)`` (not assumed binary).
        n_states: ``S``.
        n_actions: ``A``.
        source: where the data came from (a path or a description), used in error messages.
        names: optional trajectory names (file names), one per trajectory.
    """

    states: tuple[np.ndarray, ...]
    actions: tuple[np.ndarray, ...]
    features: np.ndarray
    n_states: int
    n_actions: int
    source: str = ""
    names: tuple[str, ...] = field(default=())

    def __post_init__(self) -> None:
        where = f" in {self.source}" if self.source else ""
        states = tuple(np.asarray(s) for s in self.states)
        actions = tuple(np.asarray(a) for a in self.actions)
        if len(states) == 0:
            raise DemonstrationError(f"no trajectories{where}")
        if len(states) != len(actions):
            raise DemonstrationError(
                f"{len(states)} state sequences but {len(actions)} action sequences{where}"
            )
        if self.names and len(self.names) != len(states):
            raise DemonstrationError(f"{len(self.names)} names for {len(states)} trajectories{where}")
        if int(self.n_states) <= 0 or int(self.n_actions) <= 0:
            raise DemonstrationError(
                f"n_states and n_actions must be positive, got {self.n_states}, {self.n_actions}{where}"
            )
        feats = np.asarray(self.features, dtype=np.float64)
        if feats.ndim != 3 or feats.shape[:2] != (self.n_states, self.n_actions):
            raise DemonstrationError(
                f"features must have shape [S={self.n_states}, A={self.n_actions}, K], "
                f"got {feats.shape}{where}"
            )
        if feats.shape[2] == 0:
            raise DemonstrationError(f"features have no columns (K = 0){where}")
        if not np.all(np.isfinite(feats)):
            s, a, k = np.argwhere(~np.isfinite(feats))[0]
            raise DemonstrationError(f"feature [{s}, {a}, {k}] is not finite{where}")
        clean_s, clean_a = [], []
        for i, (s, a) in enumerate(zip(states, actions)):
            label = self.names[i] if self.names else f"trajectory {i}"
            if s.ndim != 1 or a.ndim != 1 or s.shape != a.shape:
                raise DemonstrationError(
                    f"{label}{where}: states {s.shape} and actions {a.shape} must be equal-length 1-D"
                )
            if s.size == 0:
                raise DemonstrationError(f"{label}{where} is empty")
            for arr, kind, n in ((s, "state", self.n_states), (a, "action", self.n_actions)):
                if not np.issubdtype(arr.dtype, np.integer):
                    if not np.all(np.isfinite(arr)) or np.any(arr != np.round(arr)):
                        raise DemonstrationError(f"{label}{where}: {kind}s must be integers")
                bad = np.flatnonzero((arr < 0) | (arr >= n))
                if bad.size:
                    raise DemonstrationError(
                        f"{label}{where}, step {bad[0]}: {kind} {arr[bad[0]]} out of range [0, {n})"
                    )
            clean_s.append(np.ascontiguousarray(s, dtype=np.int64))
            clean_a.append(np.ascontiguousarray(a, dtype=np.int64))
        feats = np.ascontiguousarray(feats)
        feats.setflags(write=False)
        for arr in (*clean_s, *clean_a):
            arr.setflags(write=False)
        object.__setattr__(self, "states", tuple(clean_s))
        object.__setattr__(self, "actions", tuple(clean_a))
        object.__setattr__(self, "features", feats)
        object.__setattr__(self, "n_states", int(self.n_states))
        object.__setattr__(self, "n_actions", int(self.n_actions))
        object.__setattr__(self, "names", tuple(self.names))

    @property
    def n_features(self) -> int:
        """``K``."""
        return int(self.features.shape[2])

    @property
    def n_trajectories(self) -> int:
        return len(self.states)

    @property
    def n_steps(self) -> int:
        """Total number of (state, action) steps over all trajectories."""
        return int(sum(s.size for s in self.states))

    def flat(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Concatenated ``states [N]``, ``actions [N]`` and ``offsets [n_trajectories + 1]``.

        Trajectory ``i`` is ``states[offsets[i]:offsets[i + 1]]``.
        """
        lengths = np.array([s.size for s in self.states], dtype=np.int64)
        offsets = np.concatenate([[0], np.cumsum(lengths)])
        return np.concatenate(self.states), np.concatenate(self.actions), offsets

    def transitions(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Observed transitions in data order: ``s [M]``, ``a [M]``, ``s_next [M]``.

        ``M = N - n_trajectories``: every step but each trajectory's last.
        """
        s = np.concatenate([x[:-1] for x in self.states])
        a = np.concatenate([x[:-1] for x in self.actions])
        s2 = np.concatenate([x[1:] for x in self.states])
        return s, a, s2

    def subset(self, indices) -> Demonstrations:
        """The demonstrations restricted to the trajectories at ``indices`` (same features)."""
        idx = [int(i) for i in indices]
        return Demonstrations(
            states=tuple(self.states[i] for i in idx),
            actions=tuple(self.actions[i] for i in idx),
            features=self.features,
            n_states=self.n_states,
            n_actions=self.n_actions,
            source=self.source,
            names=tuple(self.names[i] for i in idx) if self.names else (),
        )

    def deduplicated(self) -> Demonstrations:
        """Drop trajectories identical (same states and actions) to an earlier one."""
        seen: set[bytes] = set()
        keep = []
        for i, (s, a) in enumerate(zip(self.states, self.actions)):
            key = s.tobytes() + b"|" + a.tobytes()
            if key not in seen:
                seen.add(key)
                keep.append(i)
        return self.subset(keep)
