"""The freeway-merge domain of the paper's section 4.2: the one home of its definitions.

Everything that says what a merge state, action or encounter row *is* lives here, and
nowhere else: the simulator (``sim``: encounter extraction, closed-loop controller) and the
learner (``irl.merge_mdp``: transitions, tabular demonstrations) both import it, so the
closed loop encodes states exactly as learning does. Pure definitions: numpy, pandas, no
SUMO, nothing of ours outside ``irl``.

Roles: car B merges from the ramp (lane 7) into the rightmost main lane (lane 6); A is the
lag car behind B in lane 6 (the driver modelled), C the lead car ahead of B in lane 6. Units
are NGSIM's: feet, ft/s, ft/s^2, frames of 0.1 s (:mod:`irl.units`).

**State variables** (per frame): ``d_AC = Local_Y(C) - Local_Y(A)`` and
``d_AB = Local_Y(B) - Local_Y(A)`` (ft, front bumper to front bumper, positive when the other
car is ahead of A), ``v_AC = v(A) - v(C)`` and ``v_AB = v(A) - v(B)`` (ft/s, positive when A
is faster), ``B_is_truck`` (B's NGSIM class is 3).

**State index** (the authors' layout, 1250 states)::

    s = 625 * truck + 125 * x1 + 25 * x2 + 5 * x3 + x4

with ``x1..x4`` the 5-bin indices of ``d_AC, d_AB, v_AC, v_AB`` under :class:`MergeBins`.
A value equal to an inner edge falls in the bin above the edge. ``d_AC`` bins count from
the far end (bin 0 = farthest, bin 4 = closest: ``d_AC < 35 ft`` with the smallest edge at
35, which the Safe feature tests); the other three count up (bin 0 = smallest value).
``+inf`` and ``-inf`` fall in the outer bins. NaN is an :class:`~irl.errors.EncodingError`,
except for the no-lead-car rule.

**No-lead-car rule** (the one rule, in tables, encoders and the closed loop alike): when A has
no lead car C, ``d_AC`` and ``v_AC`` are both NaN. Such a frame encodes to the farthest
``d_AC`` bin (``x1 = 0``) and the ``v_AC`` bin that holds zero relative speed
(:meth:`MergeBins.no_lead_v_AC_bin`): an open road ahead. Exactly one of the two NaN is an
error.

**Actions**: A's acceleration (ft/s^2) in 5 bins, 0 High Brake ``a <= -4.8``, 1 Low Brake
``-4.8 < a <= -0.6``, 2 Zero ``-0.6 < a < 0.6``, 3 Low Accel ``0.6 <= a < 4.8``, 4 High Accel
``a >= 4.8``. The paper's outer limits are [-11.2, 11.2] (:data:`ACC_LIMITS`); values beyond
them, ``+-inf`` included, fall in the end bins. NaN raises :class:`~irl.errors.EncodingError`.
The closed loop applies :data:`ACTION_ACC_FT_S2` for each action.

**The action at frame t** is the acceleration from t to t + 0.1 s,
``acc_A(t) = (v_A(t+1) - v_A(t)) / 0.1 s`` (:func:`forward_acceleration`): what A does in
state t, as the controller applies it; not SUMO's or NGSIM's ``v_Acc``, the backward
difference that produced state t. A frame whose next speed of A is unknown has no action and
no row (see :data:`ENCOUNTER_SCHEMA`).

**Features** (the paper's three, binary): f0 Safe = 0 when ``d_AC < 35 ft`` and ``acc >= 0.6``
(``x1 == 4`` and ``a >= 3``), else 1; f1 Time-to-travel = 1 when ``acc > -0.6`` (``a >= 2``);
f2 Ahead-of-truck = 1 when B is a truck and ``acc >= 0.6`` (``a >= 3``).

**State encodings** (:data:`STATE_ENCODINGS`): ``"paper"`` is the index above (1250 states);
``"driver"`` adds A's previous action (issue 11, cause 5: human acceleration persists),
``s_driver = s_paper * N_ACTIONS + prev_action`` (6250 states, :func:`n_states`). The previous
action at an encounter's first decision is the bin of A's acceleration over the decision step
before it, from A's speed history (:func:`previous_action`); :data:`ZERO_ACTION` when that
history is unknown.
"""

from __future__ import annotations

import json
import os
import warnings
from bisect import bisect_right
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from irl.atomic import write_json_atomic
from irl.errors import ConfigError, DemonstrationError, EncodingError
from irl.units import FRAME_S

# --------------------------------------------------------------------------------------
# actions

N_ACTIONS = 5
#: Action names, in action-index order.
ACTION_NAMES = ("High Brake", "Low Brake", "Zero", "Low Accel", "High Accel")
#: Inner edges of the acceleration bins (ft/s^2).
ACC_EDGES = (-4.8, -0.6, 0.6, 4.8)
#: The paper's outer limits of the acceleration bins (ft/s^2); values beyond go to the end bins.
ACC_LIMITS = (-11.2, 11.2)
#: The acceleration (ft/s^2) the closed loop applies for each action: the midpoint of its bin
#: within ``ACC_LIMITS``.
ACTION_ACC_FT_S2 = (-8.0, -2.7, 0.0, 2.7, 8.0)
#: Index of the Zero action (constant velocity).
ZERO_ACTION = 2


def action_of(acc: float) -> int:
    """Action index (0..4) of one acceleration; the scalar twin of :func:`actions_of`.

    Args:
        acc: ft/s^2; ``+-inf`` go to the end bins.

    Returns:
        the action index.

    Raises:
        EncodingError: ``acc`` is NaN.
    """
    if acc <= -0.6:
        return 0 if acc <= -4.8 else 1
    if acc < 0.6:
        return 2
    if acc >= 0.6:
        return 4 if acc >= 4.8 else 3
    raise EncodingError(f"acceleration is NaN: an action needs a number (ft/s^2), got {acc!r}")


def actions_of(acc) -> np.ndarray:
    """Action indices of accelerations (bins in the module docstring).

    Args:
        acc: ft/s^2, any shape; ``+-inf`` go to the end bins.

    Returns:
        int64 array of the same shape, values 0..4.

    Raises:
        EncodingError: an element is NaN (the message gives the first flat index).
    """
    a = np.asarray(acc, dtype=np.float64)
    nan = np.isnan(a)
    if nan.any():
        raise EncodingError(f"acceleration at flat index {int(np.flatnonzero(nan)[0])} is NaN: "
                            "an action needs a number (ft/s^2)")
    out = np.full(a.shape, ZERO_ACTION, dtype=np.int64)
    out[a <= -0.6] = 1
    out[a <= -4.8] = 0
    out[a >= 0.6] = 3
    out[a >= 4.8] = 4
    return out


def forward_acceleration(speed, next_speed, dt: float = FRAME_S):
    """The action's acceleration at frame t: ``(v(t+dt) - v(t)) / dt`` (ft/s^2).

    Args:
        speed, next_speed: A's speed at t and at t + dt (ft/s), scalars or arrays that
            broadcast.
        dt: seconds between the two speeds (one NGSIM frame by default).

    Returns:
        the forward difference, the broadcast shape.
    """
    return (np.asarray(next_speed, dtype=np.float64) - np.asarray(speed, dtype=np.float64)) / dt


# --------------------------------------------------------------------------------------
# states

N_BINS = 5
N_STATES = 2 * N_BINS**4  # 1250
#: The four continuous state variables, in state-index order (x1..x4).
VARIABLES = ("d_AC", "d_AB", "v_AC", "v_AB")
#: Variables whose bin index runs in decreasing order of the value.
DESCENDING = frozenset({"d_AC"})
#: d_AC below this (ft) is the closest bin and makes accelerating unsafe (the Safe feature).
SAFE_DISTANCE_FT = 35.0


#: The state encodings: the paper's 1250 states, or those times A's previous action.
STATE_ENCODINGS = ("paper", "driver")


def n_states(encoding: str = "paper") -> int:
    """Number of states of ``encoding``: 1250 (``"paper"``) or 6250 (``"driver"``).

    Raises:
        ConfigError: an unknown encoding.
    """
    if encoding == "paper":
        return N_STATES
    if encoding == "driver":
        return N_STATES * N_ACTIONS
    raise ConfigError(f"state encoding must be one of {STATE_ENCODINGS}, got {encoding!r}")


def driver_state(s_paper, prev_action):
    """``s_paper * N_ACTIONS + prev_action`` (integer arrays broadcast)."""
    return np.asarray(s_paper, dtype=np.int64) * N_ACTIONS + np.asarray(prev_action, dtype=np.int64)


def split_driver_state(s):
    """Inverse of :func:`driver_state`: ``(s_paper, prev_action)`` arrays of ``s``'s shape."""
    s = np.asarray(s, dtype=np.int64)
    return s // N_ACTIONS, s % N_ACTIONS


def previous_action(speed_before, speed_now, dt: float) -> int:
    """A's previous action at a decision: the bin of ``(speed_now - speed_before) / dt``.

    Args:
        speed_before: A's speed (ft/s) one decision step ``dt`` (s) before, or None/NaN when
            unknown (A's history starts at this frame).
        speed_now: A's speed (ft/s) now.

    Returns:
        the action index; :data:`ZERO_ACTION` when either speed is unknown.
    """
    if speed_before is None or speed_now is None or speed_before != speed_before or speed_now != speed_now:
        return ZERO_ACTION
    return action_of((speed_now - speed_before) / dt)


def _check_prev_action(prev_action, encoding: str):
    if encoding not in STATE_ENCODINGS:
        raise ConfigError(f"state encoding must be one of {STATE_ENCODINGS}, got {encoding!r}")
    if encoding == "paper":
        return None
    if prev_action is None:
        raise EncodingError("state encoding 'driver' needs prev_action (A's previous action, 0..4), got None")
    p = np.asarray(prev_action)
    if p.dtype.kind not in "iub" or np.any((p < 0) | (p >= N_ACTIONS)):
        raise EncodingError(f"prev_action must be action indices 0..{N_ACTIONS - 1}, got {prev_action!r}")
    return p.astype(np.int64)


def state_index(truck, x1, x2, x3, x4):
    """``625 truck + 125 x1 + 25 x2 + 5 x3 + x4`` (integer arrays broadcast)."""
    return 625 * np.asarray(truck) + 125 * np.asarray(x1) + 25 * np.asarray(x2) + 5 * np.asarray(x3) + np.asarray(x4)


def state_parts(s) -> np.ndarray:
    """Inverse of :func:`state_index`: ``s [...]`` -> ``[..., 5]`` of ``(truck, x1, x2, x3, x4)``."""
    s = np.asarray(s, dtype=np.int64)
    return np.stack([s // 625, (s // 125) % 5, (s // 25) % 5, (s // 5) % 5, s % 5], axis=-1)


@dataclass(frozen=True)
class MergeBins:
    """Inner bin edges (4 per variable, strictly increasing) of the 4 state variables, and the
    encoder of continuous merge variables into the state index.

    Bin index of a value ``v`` with edges ``e``: ``#{e_j <= v}`` (0..4), reversed (``4 - .``)
    for ``d_AC``. So with ``d_AC`` edges ``(35, ...)``, ``d_AC < 35`` is bin 4.

    Raises:
        ConfigError: edges that are not 4 finite, strictly increasing numbers.
    """

    d_AC: tuple[float, float, float, float]
    d_AB: tuple[float, float, float, float]
    v_AC: tuple[float, float, float, float]
    v_AB: tuple[float, float, float, float]

    def __post_init__(self) -> None:
        for name in VARIABLES:
            raw = getattr(self, name)
            try:
                edges = tuple(float(x) for x in raw)
            except (TypeError, ValueError):
                raise ConfigError(f"bin edges {name}: expected 4 numbers, got {raw!r}") from None
            if len(edges) != N_BINS - 1 or not np.all(np.isfinite(edges)):
                raise ConfigError(f"bin edges {name}: expected 4 finite numbers, got {raw!r}")
            if not all(a < b for a, b in zip(edges, edges[1:])):
                raise ConfigError(f"bin edges {name}: must be strictly increasing, got {edges}")
            object.__setattr__(self, name, edges)

    @classmethod
    def assumed_authors(cls) -> MergeBins:
        """The edges we assume for the authors' 12 trajectories (none are published).

        ``d_AC`` (35, 60, 90, 130) ft, ``d_AB`` (10, 30, 60, 100) ft, ``v_AC`` and ``v_AB``
        (-7.5, -2.5, 2.5, 7.5) ft/s. Only the kinematic fallback of the transition model uses
        them; the demonstrations themselves are the authors' state indices.
        """
        return cls(d_AC=(35.0, 60.0, 90.0, 130.0), d_AB=(10.0, 30.0, 60.0, 100.0),
                   v_AC=(-7.5, -2.5, 2.5, 7.5), v_AB=(-7.5, -2.5, 2.5, 7.5))

    def edges(self, name: str) -> np.ndarray:
        """``[4]`` inner edges of variable ``name``."""
        return np.asarray(getattr(self, name), dtype=np.float64)

    def to_dict(self) -> dict[str, list[float]]:
        return {name: list(getattr(self, name)) for name in VARIABLES}

    @classmethod
    def from_dict(cls, data: dict, where: str = "bin edges") -> MergeBins:
        """From ``{variable: [4 edges]}`` (``to_dict``'s form, as saved in model.json).

        Raises:
            ConfigError: not a mapping, a variable missing, or bad edges (names ``where``).
        """
        if not isinstance(data, dict):
            raise ConfigError(f"{where}: expected an object mapping {VARIABLES} to 4 edges each")
        missing = [v for v in VARIABLES if v not in data]
        if missing:
            raise ConfigError(f"{where}: missing variable(s) {missing}")
        try:
            return cls(**{v: tuple(data[v]) for v in VARIABLES})
        except ConfigError as e:
            raise ConfigError(f"{where}: {e}") from None
        except TypeError as e:
            raise ConfigError(f"{where}: {e}") from None

    def save(self, path: str | os.PathLike) -> Path:
        """Write as JSON, atomically."""
        return write_json_atomic(path, self.to_dict())

    @classmethod
    def load(cls, path: str | os.PathLike) -> MergeBins:
        """Read a file written by :meth:`save`.

        Raises:
            ConfigError: the file is missing, not JSON, or holds bad edges.
        """
        path = Path(path)
        try:
            data = json.loads(path.read_text())
        except FileNotFoundError:
            raise ConfigError(f"{path}: no such bin-edge file") from None
        except json.JSONDecodeError as e:
            raise ConfigError(f"{path}: not JSON ({e})") from None
        return cls.from_dict(data, where=str(path))

    # -- encoding ----------------------------------------------------------------------
    def bin_index(self, name: str, values) -> np.ndarray:
        """Bin indices 0..4 of ``values`` (any shape) for variable ``name``.

        Raises:
            EncodingError: a value is NaN (the no-lead-car rule is :meth:`states`'s).
        """
        v = np.asarray(values, dtype=np.float64)
        if np.isnan(v).any():
            raise EncodingError(f"{name} is NaN at flat index {int(np.flatnonzero(np.isnan(v))[0])}")
        idx = np.searchsorted(self.edges(name), v, side="right")
        return (N_BINS - 1 - idx if name in DESCENDING else idx).astype(np.int64)

    def no_lead_v_AC_bin(self) -> int:
        """The ``v_AC`` bin of a frame without car C: the bin holding zero relative speed."""
        return bisect_right(self.v_AC, 0.0)

    def states(self, d_AC, d_AB, v_AC, v_AB, truck, prev_action=None, encoding: str = "paper") -> np.ndarray:
        """State indices of continuous merge variables (the module docstring's rules).

        Args:
            d_AC, d_AB: gaps (ft); v_AC, v_AB: relative speeds (ft/s); truck: B is a truck
                (bool or 0/1). Arrays of one broadcast shape ``[...]``; ``d_AC`` and ``v_AC``
                both NaN where there is no car C.
            prev_action: A's previous action (0..4), broadcast with the others; required by
                the ``"driver"`` encoding, ignored by ``"paper"``.
            encoding: one of :data:`STATE_ENCODINGS`.

        Returns:
            int64 ``[...]`` in ``[0, n_states(encoding))``.

        Raises:
            EncodingError: NaN in ``d_AB``, ``v_AB`` or ``truck``, or in only one of ``d_AC``
                and ``v_AC``; ``prev_action`` None or outside 0..4 with encoding ``"driver"``.
            ConfigError: an unknown encoding.
        """
        prev = _check_prev_action(prev_action, encoding)
        s = self._paper_states(d_AC, d_AB, v_AC, v_AB, truck)
        return s if prev is None else driver_state(s, prev)

    def _paper_states(self, d_AC, d_AB, v_AC, v_AB, truck) -> np.ndarray:
        d_ac, d_ab, v_ac, v_ab = np.broadcast_arrays(*(np.asarray(x, dtype=np.float64) for x in (d_AC, d_AB, v_AC, v_AB)))
        no_c = np.isnan(d_ac)
        odd = no_c != np.isnan(v_ac)
        if odd.any():
            i = int(np.flatnonzero(odd)[0])
            raise EncodingError(f"flat index {i}: d_AC={d_ac.flat[i]!r}, v_AC={v_ac.flat[i]!r}; "
                                "without car C both are NaN, with C both are numbers")
        x1 = self.bin_index("d_AC", np.where(no_c, np.inf, d_ac))  # inf: the farthest bin, 0
        x3 = np.where(no_c, self.no_lead_v_AC_bin(), self.bin_index("v_AC", np.where(no_c, 0.0, v_ac)))
        t = np.asarray(truck)
        if t.dtype.kind == "f" and np.isnan(t).any():
            raise EncodingError(f"B_is_truck is NaN at flat index {int(np.flatnonzero(np.isnan(t))[0])}")
        t = np.broadcast_to(t != 0, d_ac.shape).astype(np.int64)
        return state_index(t, x1, self.bin_index("d_AB", d_ab), x3, self.bin_index("v_AB", v_ab)).astype(np.int64)

    def state(self, d_AC: float, d_AB: float, v_AC: float, v_AB: float, truck: bool,
              prev_action: int | None = None, encoding: str = "paper") -> int:
        """One state index, for the closed loop: the scalar twin of :meth:`states` (same
        bins, same NaN rules, same encodings), without numpy.

        Raises:
            EncodingError: as :meth:`states`.
            ConfigError: an unknown encoding.
        """
        if encoding == "driver":
            if prev_action is None:
                raise EncodingError("state encoding 'driver' needs prev_action (A's previous action, 0..4), got None")
            if isinstance(prev_action, bool) or int(prev_action) != prev_action or not 0 <= prev_action < N_ACTIONS:
                raise EncodingError(f"prev_action must be an action index 0..{N_ACTIONS - 1}, got {prev_action!r}")
            return self._paper_state(d_AC, d_AB, v_AC, v_AB, truck) * N_ACTIONS + int(prev_action)
        if encoding != "paper":
            raise ConfigError(f"state encoding must be one of {STATE_ENCODINGS}, got {encoding!r}")
        return self._paper_state(d_AC, d_AB, v_AC, v_AB, truck)

    def _paper_state(self, d_AC: float, d_AB: float, v_AC: float, v_AB: float, truck: bool) -> int:
        if d_AC != d_AC:  # NaN: no car C
            if v_AC == v_AC:
                raise EncodingError(f"d_AC is NaN but v_AC={v_AC!r}; without car C both are NaN")
            x1, x3 = 0, bisect_right(self.v_AC, 0.0)
        elif v_AC != v_AC:
            raise EncodingError(f"v_AC is NaN but d_AC={d_AC!r}; without car C both are NaN")
        else:
            x1, x3 = 4 - bisect_right(self.d_AC, d_AC), bisect_right(self.v_AC, v_AC)
        if d_AB != d_AB or v_AB != v_AB or truck != truck:
            raise EncodingError(f"NaN in d_AB={d_AB!r}, v_AB={v_AB!r} or B_is_truck={truck!r}")
        return (625 if truck else 0) + 125 * x1 + 25 * bisect_right(self.d_AB, d_AB) + 5 * x3 + bisect_right(self.v_AB, v_AB)

    def encode(self, table: pd.DataFrame, prev_action=None, encoding: str = "paper") -> np.ndarray:
        """``[rows]`` state index of every row of an encounter table (columns by name);
        ``prev_action [rows]`` as in :meth:`states`."""
        d_AC, d_AB, v_AC, v_AB = (table[c].to_numpy(dtype=np.float64) for c in VARIABLES)
        return self.states(d_AC, d_AB, v_AC, v_AB, table["B_is_truck"].to_numpy(dtype=np.float64),
                           prev_action, encoding)

    def representatives(self, name: str) -> np.ndarray:
        """``[5]`` a finite representative value of each bin of ``name``, in bin-index order.

        Inner bins: the midpoint of their two edges. Outer bins (unbounded): the outer edge
        moved outward by half the width of the neighbouring inner bin (the midpoint spacing
        continued). For distances with a positive smallest edge, the lowest bin's value is at
        least half that edge (a gap is never negative).
        """
        e = self.edges(name)
        mids = np.empty(N_BINS)
        mids[1:4] = 0.5 * (e[:-1] + e[1:])
        mids[0] = e[0] - 0.5 * (e[1] - e[0])
        mids[4] = e[3] + 0.5 * (e[3] - e[2])
        if name.startswith("d_") and e[0] > 0:
            mids[0] = max(mids[0], 0.5 * e[0])
        return mids[::-1].copy() if name in DESCENDING else mids


def fit_quantile_bins(table: pd.DataFrame, *, safe_distance: float = SAFE_DISTANCE_FT,
                      where: str = "encounters") -> MergeBins:
    """Quantile bin edges fitted on training encounters (DESIGN.md section 4's default).

    ``d_AB, v_AB``: the 20/40/60/80 % quantiles; ``v_AC`` the same over the frames with a car
    C (:meth:`MergeBins.assumed_authors`' ``v_AC`` edges when no frame has one). ``d_AC``: the
    smallest edge is fixed at ``safe_distance`` (35 ft) so that bin 4 means ``d_AC < 35 ft`` as
    the Safe feature requires; the other three are the 25/50/75 % quantiles of the values
    ``>= safe_distance``. Edges that coincide (ties in the data) are spread apart by a tiny
    amount to stay strictly increasing, with a :class:`DegenerateBinsWarning`.

    Raises:
        DemonstrationError: ``table`` breaks :func:`validate_encounters`, or a variable is
            constant over the table (no bins can be fitted).
    """
    validate_encounters(table, where)
    edges: dict[str, Any] = {}  # four edges per variable: MergeBins.__post_init__ checks the count
    for name in VARIABLES:
        v = table[name].to_numpy(dtype=np.float64)
        v = v[~np.isnan(v)]
        if v.size > 1 and np.all(v == v[0]):
            raise DemonstrationError(
                f"{where}: column {name!r}: all {v.size} rows are {v[0]:g}; quantile bins need values that "
                "vary (a constant column carries no information: check how the encounters were extracted, "
                "or give bin edges explicitly)"
            )
        if name == "d_AC":
            far = v[v >= safe_distance]
            upper = np.quantile(far, [0.25, 0.5, 0.75]) if far.size else safe_distance + np.array([10.0, 20.0, 30.0])
            e = np.concatenate([[safe_distance], upper])
        elif v.size == 0:
            e = np.asarray(getattr(MergeBins.assumed_authors(), name))
        else:
            e = np.quantile(v, [0.2, 0.4, 0.6, 0.8])
        tied = int(np.sum(np.diff(e) <= 0))
        if tied:
            warnings.warn(
                f"{where}: column {name!r}: {tied} of the quantile bin edges {np.round(e, 6).tolist()} coincide "
                "(many equal values); they are spread 1e-6 apart, so some bins hold (almost) no data",
                DegenerateBinsWarning, stacklevel=2,
            )
        edges[name] = tuple(_strictly_increasing(e))
    return MergeBins(**edges)


class DegenerateBinsWarning(UserWarning):
    """Quantile bin edges that coincide because of ties in the data."""


def _strictly_increasing(e: np.ndarray) -> np.ndarray:
    e = np.asarray(e, dtype=np.float64).copy()
    for i in range(1, e.size):
        if e[i] <= e[i - 1]:
            e[i] = e[i - 1] + max(1e-6, 1e-9 * abs(e[i - 1]))
    return e


# --------------------------------------------------------------------------------------
# the encounter table


@dataclass(frozen=True)
class EncounterColumn:
    """One column of the encounter table: ``name``, pandas ``dtype``, ``unit`` and meaning."""

    name: str
    dtype: str
    unit: str
    doc: str


#: The per-frame encounter table (DESIGN.md section 2), one row per frame t of an encounter
#: in which A, B and A's speed at t + 0.1 s are known. ``sim.encounters`` writes it from any
#: NGSIM-schema trajectory table (simulated or real); ``irl.merge_mdp`` learns from it.
ENCOUNTER_SCHEMA: tuple[EncounterColumn, ...] = (
    EncounterColumn("encounter_id", "int64", "", "one id per merge (per car B), from 1"),
    EncounterColumn("B_id", "int64", "", "Vehicle_ID of the merging car B"),
    EncounterColumn("A_id", "int64", "", "Vehicle_ID of the lag car A (lane 6, behind B at the merge frame)"),
    EncounterColumn("C_id", "int64", "", "Vehicle_ID of the lead car C (lane 6, ahead of B at the merge frame); 0: none"),
    EncounterColumn("Frame_ID", "int64", "0.1 s frame", "the frame t of this row"),
    EncounterColumn("Global_Time", "int64", "ms", "time of frame t"),
    EncounterColumn("merge_frame", "int64", "0.1 s frame", "B's first frame in lane 6"),
    EncounterColumn("d_AC", "float64", "ft", "Local_Y(C) - Local_Y(A); NaN when C is not there (no-lead-car rule)"),
    EncounterColumn("d_AB", "float64", "ft", "Local_Y(B) - Local_Y(A); negative while B is behind A"),
    EncounterColumn("v_AC", "float64", "ft/s", "v(A) - v(C); NaN exactly when d_AC is"),
    EncounterColumn("v_AB", "float64", "ft/s", "v(A) - v(B)"),
    EncounterColumn("B_is_truck", "bool", "", "B's v_Class is 3 (truck)"),
    EncounterColumn("acc_A", "float64", "ft/s^2",
                    "the action: (v_A(t+1) - v_A(t)) / 0.1 s, forward difference of A's speed "
                    "(not v_Acc, the backward difference)"),
)
#: Column name -> pandas dtype, in table order.
ENCOUNTER_COLUMNS: dict[str, str] = {c.name: c.dtype for c in ENCOUNTER_SCHEMA}
#: Column name -> unit ("" for ids and flags).
ENCOUNTER_UNITS: dict[str, str] = {c.name: c.unit for c in ENCOUNTER_SCHEMA}
#: The columns a table must have to be learned from (others are ignored).
REQUIRED_COLUMNS = ("encounter_id", "d_AC", "d_AB", "v_AC", "v_AB", "B_is_truck", "acc_A")


def validate_encounters(table, where: str = "encounters") -> None:
    """Check an encounter table before it is binned or learned from.

    ``d_AB``, ``v_AB``, ``B_is_truck`` and ``acc_A`` must be finite numbers; ``d_AC`` and
    ``v_AC`` finite numbers or both NaN (no car C). A table never holds ``+-inf``.

    Raises:
        DemonstrationError: not a DataFrame, a column of :data:`REQUIRED_COLUMNS` missing, no
            rows, or a bad value (the message names ``where``, the row and the column).
    """
    if not isinstance(table, pd.DataFrame):
        raise DemonstrationError(f"{where}: expected a pandas DataFrame of encounters, got {type(table).__name__}")
    missing = [c for c in REQUIRED_COLUMNS if c not in table.columns]
    if missing:
        raise DemonstrationError(
            f"{where}: encounter table lacks column(s) {missing}; expected {list(REQUIRED_COLUMNS)}"
        )
    if len(table) == 0:
        raise DemonstrationError(f"{where}: encounter table has no rows")
    cols = {c: pd.to_numeric(table[c], errors="coerce").to_numpy(dtype=np.float64) for c in REQUIRED_COLUMNS[1:]}
    no_c = np.isnan(cols["d_AC"]) & np.isnan(cols["v_AC"])
    for c, col in cols.items():
        bad = ~np.isfinite(col)
        if c in ("d_AC", "v_AC"):
            bad &= ~no_c
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            got = table[c].iloc[i]
            got = got.item() if isinstance(got, np.generic) else got
            hint = " (d_AC and v_AC are NaN together when there is no car C)" if c in ("d_AC", "v_AC") else ""
            raise DemonstrationError(
                f"{where}: row {i}, column {c!r}: expected a finite number, got {got!r}{hint}"
            )


# --------------------------------------------------------------------------------------
# features

FEATURE_NAMES = ("safe", "time_to_travel", "ahead_of_truck")


def paper_features(d_AC: float, b_is_truck: bool, action: int) -> tuple[float, float, float]:
    """The paper's three features of taking ``action`` with gap ``d_AC`` (ft), continuous form.

    Safe = 0 only when ``d_AC < SAFE_DISTANCE_FT`` and the action accelerates (actions 3-4);
    Time-to-travel = 1 for actions 2-4; Ahead-of-truck = 1 when B is a truck and A accelerates.
    Without car C (``d_AC`` NaN) Safe is 1, as in the farthest bin. Equals :func:`features`
    when the smallest ``d_AC`` edge is ``SAFE_DISTANCE_FT`` (the quantile bins' default).
    """
    accel = action >= 3
    return (0.0 if (d_AC < SAFE_DISTANCE_FT and accel) else 1.0, 1.0 if action >= 2 else 0.0,
            1.0 if (b_is_truck and accel) else 0.0)


def features() -> np.ndarray:
    """``[1250, 5, 3]`` the paper's binary features f0 Safe, f1 Time-to-travel, f2 Ahead-of-truck
    (module docstring; paper section 4.2)."""
    parts = state_parts(np.arange(N_STATES))  # [S, 5]
    truck, x1 = parts[:, 0][:, None], parts[:, 1][:, None]
    a = np.arange(N_ACTIONS)[None, :]
    phi = np.zeros((N_STATES, N_ACTIONS, 3))
    phi[..., 0] = np.where((x1 == 4) & (a >= 3), 0.0, 1.0)
    phi[..., 1] = np.where(a >= 2, 1.0, 0.0)
    phi[..., 2] = np.where((truck == 1) & (a >= 3), 1.0, 0.0)
    return phi
