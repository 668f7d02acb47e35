"""The freeway-merge MDP of the paper's section 4.2, with the authors' state layout.

State of car A (the lag car in the rightmost main lane; B merges from the ramp, C leads A):

    s = 625 * truck + 125 * x1 + 25 * x2 + 5 * x3 + x4        (1250 states)

with ``truck = B_is_truck`` and ``x1..x4`` the 5-bin indices of ``d_AC, d_AB, v_AC, v_AB``
(feet, ft/s; ``v_XY = v_X - v_Y``, ``d_XY`` the gap from A forward to X). Bin direction:
``d_AC`` bins run in DEcreasing order of distance (bin 4 = closest, ``d_AC < 35 ft`` when the
smallest inner edge is 35, as in REFERENCE.md: the Safe feature tests ``x1 == 4``); ``d_AB``,
``v_AC`` and ``v_AB`` bins run in increasing order (bin 0 = smallest value). The direction of the
velocity bins matches the authors' data: braking steps move ``x3``/``x4`` down.

Actions: A's acceleration (ft/s^2) in 5 bins, 0 High Brake ``<= -4.8``, 1 Low Brake
``(-4.8, -0.6]``, 2 Zero ``(-0.6, 0.6)``, 3 Low Accel ``[0.6, 4.8)``, 4 High Accel ``>= 4.8``
(values outside [-11.2, 11.2] clip to the end bins).

Features (REFERENCE.md's f0..f2, which agree with DESIGN.md's wording):
f0 Safe = 0 if ``x1 == 4`` and ``a >= 3`` (d_AC < 35 ft and acc >= 0.6) else 1;
f1 Time-to-travel = 1 if ``a >= 2`` (acc > -0.6); f2 Ahead-of-truck = 1 if truck and ``a >= 3``.
"""

from __future__ import annotations

import json
import os
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from irl.atomic import write_json_atomic
from irl.demonstrations import Demonstrations
from irl.errors import ConfigError, DemonstrationError

N_BINS = 5
N_STATES = 2 * N_BINS**4  # 1250
N_ACTIONS = 5
VARIABLES = ("d_AC", "d_AB", "v_AC", "v_AB")
#: Variables whose bin index runs in decreasing order of the value.
DESCENDING = frozenset({"d_AC"})
FEATURE_NAMES = ("safe", "time_to_travel", "ahead_of_truck")
ACTION_NAMES = ("high_brake", "low_brake", "zero", "low_accel", "high_accel")
#: Inner edges of the acceleration bins (ft/s^2) and the outer limits.
ACC_EDGES = (-4.8, -0.6, 0.6, 4.8)
ACC_LIMITS = (-11.2, 11.2)
#: Representative (midpoint) acceleration of each action, ft/s^2.
ACC_MIDPOINTS = (-8.0, -2.7, 0.0, 2.7, 8.0)
SAFE_DISTANCE_FT = 35.0
#: Columns an encounter table must have (DESIGN.md section 2).
ENCOUNTER_COLUMNS = ("encounter_id", "d_AC", "d_AB", "v_AC", "v_AB", "B_is_truck", "acc_A")


def state_index(truck, x1, x2, x3, x4):
    """``625 truck + 125 x1 + 25 x2 + 5 x3 + x4`` (arrays broadcast)."""
    return 625 * np.asarray(truck) + 125 * np.asarray(x1) + 25 * np.asarray(x2) + 5 * np.asarray(x3) + np.asarray(x4)


def state_parts(s) -> np.ndarray:
    """Inverse of ``state_index``: ``[..., 5]`` of ``(truck, x1, x2, x3, x4)``."""
    s = np.asarray(s, dtype=np.int64)
    return np.stack([s // 625, (s // 125) % 5, (s // 25) % 5, (s // 5) % 5, s % 5], axis=-1)


def action_of(acc) -> np.ndarray:
    """Acceleration (ft/s^2, any shape) to action index 0..4; NaN is an error of the caller."""
    acc = np.asarray(acc, dtype=np.float64)
    # bins: (-inf,-4.8] (-4.8,-0.6] (-0.6,0.6) [0.6,4.8) [4.8,inf)
    a = np.where(acc <= -4.8, 0, np.where(acc <= -0.6, 1, np.where(acc < 0.6, 2, np.where(acc < 4.8, 3, 4))))
    return a.astype(np.int64)


def features() -> np.ndarray:
    """``[1250, 5, 3]`` binary features f0 Safe, f1 Time-to-travel, f2 Ahead-of-truck."""
    parts = state_parts(np.arange(N_STATES))  # [S, 5]
    truck, x1 = parts[:, 0][:, None], parts[:, 1][:, None]
    a = np.arange(N_ACTIONS)[None, :]
    phi = np.zeros((N_STATES, N_ACTIONS, 3))
    phi[..., 0] = np.where((x1 == 4) & (a >= 3), 0.0, 1.0)
    phi[..., 1] = np.where(a >= 2, 1.0, 0.0)
    phi[..., 2] = np.where((truck == 1) & (a >= 3), 1.0, 0.0)
    return phi


@dataclass(frozen=True)
class MergeBins:
    """Inner bin edges (4 per variable, strictly increasing values) of the 4 state variables.

    Bin index of a value ``v`` with edges ``e``: ``#{e_j <= v}`` (0..4), reversed (``4 - .``)
    for ``d_AC``. So with ``d_AC`` edges ``(35, ...)``, ``d_AC < 35`` is bin 4.
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
    def assumed_authors(cls) -> "MergeBins":
        """The edges we assume for the authors' 12 trajectories (none are published).

        ``d_AC`` (35, 60, 90, 130) ft, ``d_AB`` (10, 30, 60, 100) ft, ``v_AC`` and ``v_AB``
        (-7.5, -2.5, 2.5, 7.5) ft/s. Only the kinematic fallback of the transition model uses
        them; the demonstrations themselves are the authors' state indices.
        """
        return cls(d_AC=(35.0, 60.0, 90.0, 130.0), d_AB=(10.0, 30.0, 60.0, 100.0),
                   v_AC=(-7.5, -2.5, 2.5, 7.5), v_AB=(-7.5, -2.5, 2.5, 7.5))

    def edges(self, name: str) -> np.ndarray:
        return np.asarray(getattr(self, name), dtype=np.float64)

    def to_dict(self) -> dict[str, list[float]]:
        return {name: list(getattr(self, name)) for name in VARIABLES}

    @classmethod
    def from_dict(cls, data: dict, where: str = "bin edges") -> "MergeBins":
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
    def load(cls, path: str | os.PathLike) -> "MergeBins":
        path = Path(path)
        try:
            data = json.loads(path.read_text())
        except FileNotFoundError:
            raise ConfigError(f"{path}: no such bin-edge file") from None
        except json.JSONDecodeError as e:
            raise ConfigError(f"{path}: not JSON ({e})") from None
        return cls.from_dict(data, where=str(path))

    def bin_index(self, name: str, values) -> np.ndarray:
        """Bin indices 0..4 of ``values`` (any shape) for variable ``name``."""
        idx = np.searchsorted(self.edges(name), np.asarray(values, dtype=np.float64), side="right")
        return (N_BINS - 1 - idx if name in DESCENDING else idx).astype(np.int64)

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


def _validate_encounters(df, where: str):
    import pandas as pd

    if not isinstance(df, pd.DataFrame):
        raise DemonstrationError(f"{where}: expected a pandas DataFrame of encounters, got {type(df).__name__}")
    missing = [c for c in ENCOUNTER_COLUMNS if c not in df.columns]
    if missing:
        raise DemonstrationError(
            f"{where}: encounter table lacks column(s) {missing}; expected {list(ENCOUNTER_COLUMNS)}"
        )
    if len(df) == 0:
        raise DemonstrationError(f"{where}: encounter table has no rows")
    for c in ENCOUNTER_COLUMNS[1:]:
        col = pd.to_numeric(df[c], errors="coerce").to_numpy(dtype=np.float64)
        bad = np.flatnonzero(~np.isfinite(col))
        if bad.size:
            raise DemonstrationError(
                f"{where}: row {bad[0]}, column {c!r}: expected a finite number, got {df[c].iloc[bad[0]]!r}"
            )


def fit_quantile_bins(encounters_df, *, safe_distance: float = SAFE_DISTANCE_FT, where: str = "encounters") -> MergeBins:
    """Quantile bin edges fitted on training encounters.

    ``d_AB, v_AC, v_AB``: the 20/40/60/80 % quantiles. ``d_AC``: the smallest edge is fixed at
    ``safe_distance`` (35 ft) so that bin 4 means ``d_AC < 35 ft`` as the Safe feature requires;
    the other three are the 25/50/75 % quantiles of the values ``>= safe_distance``. Edges that
    coincide (ties in the data) are spread apart by a tiny amount to stay strictly increasing,
    with a :class:`DegenerateBinsWarning`.

    Raises:
        DemonstrationError: a variable is constant over the table (no bins can be fitted).
    """
    _validate_encounters(encounters_df, where)
    edges: dict[str, tuple[float, ...]] = {}
    for name in VARIABLES:
        v = encounters_df[name].to_numpy(dtype=np.float64)
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


def discretize_states(encounters_df, bins: MergeBins) -> np.ndarray:
    """``[rows]`` state index of every encounter row."""
    parts = [bins.bin_index(name, encounters_df[name].to_numpy(dtype=np.float64)) for name in VARIABLES]
    truck = (encounters_df["B_is_truck"].to_numpy(dtype=np.float64) != 0).astype(np.int64)
    return state_index(truck, *parts).astype(np.int64)


def discretize(encounters_df, bins: MergeBins, *, where: str = "encounters") -> Demonstrations:
    """One trajectory per run of rows with one ``encounter_id`` (rows in table order = frame order;
    a new trajectory also starts where ``Frame_ID``, when present, does not increase), so tables
    concatenated from several files keep same-numbered encounters apart.

    Args:
        encounters_df: DESIGN.md's encounter table (columns ``ENCOUNTER_COLUMNS``, others
            ignored).
        bins: state bin edges.

    Returns:
        Demonstrations over 1250 states and 5 actions with the merge features; trajectories in
        order of first appearance of their encounter id, named ``encounter <id>``.
    """
    _validate_encounters(encounters_df, where)
    states = discretize_states(encounters_df, bins)
    actions = action_of(encounters_df["acc_A"].to_numpy(dtype=np.float64))
    ids = encounters_df["encounter_id"].to_numpy()
    # a trajectory is a run of rows with one id (and increasing Frame_ID when present): tables
    # concatenated from several files or runs may reuse ids, and must not be glued together
    brk = np.ones(len(ids), dtype=bool)
    brk[1:] = ids[1:] != ids[:-1]
    if "Frame_ID" in encounters_df.columns and len(ids) > 1:
        fr = encounters_df["Frame_ID"].to_numpy()
        brk[1:] |= fr[1:] <= fr[:-1]
    run = np.cumsum(brk)
    order: dict = {}
    for i, (k, r) in enumerate(zip(ids, run)):
        order.setdefault((k, r), []).append(i)
    return Demonstrations(
        states=tuple(states[idx] for idx in order.values()),
        actions=tuple(actions[idx] for idx in order.values()),
        features=features(),
        n_states=N_STATES,
        n_actions=N_ACTIONS,
        source=where,
        names=tuple(f"encounter {k}" for k, _ in order),
    )


def kinematic_next_state(states, actions, bins: MergeBins, dt: float = 0.1) -> np.ndarray:
    """Next state predicted by constant-acceleration kinematics (the paper's fallback model).

    Takes each state's bin representatives (``MergeBins.representatives``) and the action's
    midpoint acceleration ``a`` (``ACC_MIDPOINTS``), holds them over one decision step ``dt``
    seconds and re-bins. Only A accelerates; B and C keep their speeds, and B's truck flag is
    unchanged:

        v_AC' = v_AC + a dt            v_AB' = v_AB + a dt
        d_AC' = d_AC - v_AC dt - a dt^2 / 2
        d_AB' = d_AB - v_AB dt - a dt^2 / 2

    (``d_AX`` is the gap from A forward to X, so it shrinks when A is faster than X.)

    Args:
        states, actions: integer arrays of equal shape.

    Returns:
        next states, same shape.
    """
    if not dt > 0:
        raise ConfigError(f"decision step dt must be positive, got {dt}")
    parts = state_parts(states)
    acc = np.asarray(ACC_MIDPOINTS)[np.asarray(actions, dtype=np.int64)]
    rep = {name: bins.representatives(name)[parts[..., i + 1]] for i, name in enumerate(VARIABLES)}
    v_ac = rep["v_AC"] + acc * dt
    v_ab = rep["v_AB"] + acc * dt
    d_ac = rep["d_AC"] - rep["v_AC"] * dt - 0.5 * acc * dt * dt
    d_ab = rep["d_AB"] - rep["v_AB"] * dt - 0.5 * acc * dt * dt
    new = [bins.bin_index("d_AC", d_ac), bins.bin_index("d_AB", d_ab),
           bins.bin_index("v_AC", v_ac), bins.bin_index("v_AB", v_ab)]
    return state_index(parts[..., 0], *new).astype(np.int64)


def kinematic_model(bins: MergeBins, dt: float = 0.1) -> np.ndarray:
    """``[1250, 5, 1250]`` deterministic transition model of ``kinematic_next_state``."""
    s = np.repeat(np.arange(N_STATES), N_ACTIONS)
    a = np.tile(np.arange(N_ACTIONS), N_STATES)
    nxt = kinematic_next_state(s, a, bins, dt)
    t = np.zeros((N_STATES, N_ACTIONS, N_STATES))
    t[s, a, nxt] = 1.0
    return t


def estimated_transitions(demos: Demonstrations, bins: MergeBins, dt: float = 0.1) -> np.ndarray:
    """``[1250, 5, 1250]`` relative transition counts of ``demos``, with the kinematic model for
    every (s, a) never observed (the paper's MLIRL model for the merge domain)."""
    from irl.transitions import estimate_transitions

    return estimate_transitions(demos, fallback=kinematic_model(bins, dt))


@dataclass(frozen=True)
class ConstantVelocityPad:
    """REIRL padding for the merge domain (paper section 4.2): beyond its last frame a trajectory
    continues with A, B and C at constant velocity, i.e. the Zero-acceleration action under the
    kinematic model. Callable ``state -> (next_state, action)``; picklable."""

    bins: MergeBins
    dt: float = 0.1

    def __call__(self, state: int) -> tuple[int, int]:
        zero = 2
        return int(kinematic_next_state(np.array([state]), np.array([zero]), self.bins, self.dt)[0]), zero


def load(path) -> Demonstrations:
    """Merge trajectories in the authors' text format (their state layout), with the features."""
    from irl.io import load_railusm

    return load_railusm(path, n_states=N_STATES, n_actions=N_ACTIONS, features=features())


def read_encounters(path: str | os.PathLike):
    """An encounter table from Parquet (``.parquet``/``.pq``) or CSV (anything else)."""
    import pandas as pd

    path = Path(path)
    if not path.is_file():
        raise DemonstrationError(f"{path}: no such encounter file")
    try:
        if path.suffix.lower() in (".parquet", ".pq"):
            return pd.read_parquet(path)
        return pd.read_csv(path)
    except Exception as e:  # pandas/pyarrow raise many types for unreadable files
        raise DemonstrationError(f"{path}: cannot read encounter table ({type(e).__name__}: {e})") from None
