"""Named, composable reward features of the merge domain.

Every feature is a function of one state's bin representatives and one action, evaluated on
the whole table: :func:`feature_array` returns ``[S, A, K]`` for a tuple of names, ``S`` the
states of the encoding (1250 ``"paper"``, 6250 ``"driver"``). Two named sets:

* ``"paper"`` (:data:`PAPER_FEATURES`): the paper's three binary features (section 4.2), exactly
  :func:`features` on the paper encoding.
* ``"driver"`` (:data:`DRIVER_FEATURES`): the paper's three plus

  - ``bias_<action>``: one-hot action (4 of them, Zero is the reference), the action's bias;
  - ``ittc_C``, ``ittc_B``: inverse time to collision (1/s) to C and to B one decision step
    after the action, ``max(v_AX', 0) / max(d_AX', 1 ft)`` (0 when opening; the inverse keeps
    it finite at zero closing speed). Time gap (gap / A's speed) is not available: A's own
    speed is not in the state;
  - ``rel_speed_C``, ``rel_speed_B``: ``|v_AX'|`` after the step, per 10 ft/s;
  - ``abs_acc``: ``|a|`` per 8 ft/s^2 (comfort);
  - ``jerk``: ``|a - a_prev|`` per 8 ft/s^2, the change of acceleration against A's previous
    action (persistence, cause 5), and ``keep_action``: 1 when the action repeats the previous
    one. Both need the ``"driver"`` encoding.

Representatives: :meth:`~irl.domains.merge.bins.MergeBins.representatives` for the state variables (no car C: the
farthest ``d_AC`` bin and the zero ``v_AC`` bin stand for it), and an acceleration per action
(``action_acc``, ft/s^2, default the bin midpoints :data:`~irl.domains.merge.actions.ACTION_ACC_FT_S2`).

Users pass their own features from Python: a :class:`FeatureSet` of names and an ``[S, A, K]``
array (any function of the state index and action), e.g. ``FeatureSet.custom(names, array)``,
to :func:`irl.problems.load_problem` (``features=``) or :func:`analysis.experiments.learn.learn`.

**The paper's features** (section 4.2, binary; :func:`features`, :func:`paper_features`): f0
Safe = 0 when ``d_AC < 35 ft`` and ``acc >= 0.6`` (``x1 == 4`` and ``a >= 3``), else 1; f1
Time-to-travel = 1 when ``acc > -0.6`` (``a >= 2``); f2 Ahead-of-truck = 1 when B is a truck and
``acc >= 0.6`` (``a >= 3``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from irl.domains.merge.actions import ACTION_ACC_FT_S2, ACTION_NAMES, N_ACTIONS, ZERO_ACTION
from irl.domains.merge.bins import MergeBins
from irl.domains.merge.states import (
    N_STATES,
    SAFE_DISTANCE_FT,
    VARIABLES,
    n_states,
    split_driver_state,
    state_parts,
)
from irl.errors import ConfigError
from merge_irl.units import FRAME_S

#: The paper's three binary features (section 4.2), the ``"paper"`` feature set.
PAPER_FEATURES = ("safe", "time_to_travel", "ahead_of_truck")
BIAS_FEATURES = tuple(f"bias_{ACTION_NAMES[a].lower().replace(' ', '_')}" for a in range(N_ACTIONS) if a != ZERO_ACTION)
#: The ``"driver"`` feature set: the paper's three, action biases, and the driver terms.
DRIVER_FEATURES = PAPER_FEATURES + BIAS_FEATURES + (
    "ittc_C", "ittc_B", "rel_speed_C", "rel_speed_B", "abs_acc", "jerk", "keep_action")
#: Named feature sets: ``--features paper|driver``.
FEATURE_SETS: dict[str, tuple[str, ...]] = {"paper": PAPER_FEATURES, "driver": DRIVER_FEATURES}
#: Features that need A's previous action (the ``"driver"`` state encoding).
NEEDS_PREVIOUS_ACTION = frozenset({"jerk", "keep_action"})

FEATURE_NAMES = ("safe", "time_to_travel", "ahead_of_truck")
#: Accelerations are featured per 8 ft/s^2 (the High Accel midpoint), so features stay of order 1.
ACC_SCALE_FT_S2 = 8.0


def bias_columns(n: int) -> list[np.ndarray]:
    """The action-bias features :data:`BIAS_FEATURES`, each ``[n, 5]`` (one-hot action, Zero the
    reference), for ``n`` states or decisions."""
    a = np.arange(N_ACTIONS)[None, :]
    return [np.broadcast_to((a == k).astype(np.float64), (n, N_ACTIONS)) for k in range(N_ACTIONS) if k != ZERO_ACTION]


def persistence_columns(prev: np.ndarray, action_acc) -> tuple[np.ndarray, np.ndarray]:
    """``(keep_action, jerk)``, each ``[N, 5]``, for previous actions ``prev [N]`` (0..4) and the
    actions' accelerations ``action_acc [5]`` (ft/s^2): ``keep_action`` is 1 when the action
    repeats the previous one, ``jerk`` is ``|acc_a - acc_prev|`` per :data:`ACC_SCALE_FT_S2`
    (persistence: human acceleration persists)."""
    prev = np.asarray(prev, dtype=np.int64)
    acc = np.asarray(action_acc, dtype=np.float64)
    keep = (np.arange(N_ACTIONS)[None, :] == prev[:, None]).astype(np.float64)
    return keep, np.abs(acc[None, :] - acc[prev][:, None]) / ACC_SCALE_FT_S2


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


@dataclass(frozen=True)
class FeatureSet:
    """Names and the ``[S, A, K]`` array of a merge feature set.

    Attributes:
        name: ``"paper"``, ``"driver"`` or ``"custom"``.
        names: ``K`` feature names.
        array: float64 ``[S, A, K]``.
    """

    name: str
    names: tuple[str, ...]
    array: np.ndarray

    @classmethod
    def custom(cls, names, array) -> FeatureSet:
        """A user's own features: ``K`` names and an ``[S, A, K]`` array.

        Raises:
            ConfigError: the array is not 3-D or its last axis has not ``len(names)`` columns.
        """
        arr = np.asarray(array, dtype=np.float64)
        names = tuple(str(n) for n in names)
        if arr.ndim != 3 or arr.shape[2] != len(names):
            raise ConfigError(f"custom features: expected an [S, A, {len(names)}] array for names {names}, got {arr.shape}")
        return cls("custom", names, arr)


def feature_set(name_or_names, bins: MergeBins, encoding: str = "paper", *, decision_step_s: float = FRAME_S,
                action_acc=ACTION_ACC_FT_S2) -> FeatureSet:
    """The :class:`FeatureSet` of a set name (``FEATURE_SETS``) or a tuple of feature names.

    Raises:
        ConfigError: an unknown set or feature name, or a feature that needs the driver encoding.
    """
    if isinstance(name_or_names, FeatureSet):
        return name_or_names
    if isinstance(name_or_names, str):
        if name_or_names not in FEATURE_SETS:
            raise ConfigError(f"feature set must be one of {tuple(FEATURE_SETS)}, got {name_or_names!r}")
        label, names = name_or_names, FEATURE_SETS[name_or_names]
    else:
        label, names = "custom", tuple(name_or_names)
    return FeatureSet(label, names, feature_array(names, bins, encoding, decision_step_s=decision_step_s, action_acc=action_acc))


def feature_array(names, bins: MergeBins, encoding: str = "paper", *, decision_step_s: float = FRAME_S,
                  action_acc=ACTION_ACC_FT_S2) -> np.ndarray:
    """``[n_states(encoding), 5, K]`` features ``names`` on bin representatives (module doc).

    Args:
        names: feature names of :data:`DRIVER_FEATURES`, in the order wanted.
        bins: state bin edges (their representatives are the state's values).
        encoding: ``"paper"`` or ``"driver"``.
        decision_step_s: decision step (s) over which the action acts (ITTC, relative speeds after it).
        action_acc: ``[5]`` acceleration of each action, ft/s^2.

    Raises:
        ConfigError: an unknown name, or ``jerk``/``keep_action`` with the paper encoding.
    """
    S = n_states(encoding)
    s = np.arange(S)
    if encoding == "driver":
        s_paper, prev = split_driver_state(s)
    else:
        s_paper, prev = s, None
    parts = state_parts(s_paper)  # [S, 5]
    rep = {v: bins.representatives(v)[parts[:, i + 1]][:, None] for i, v in enumerate(VARIABLES)}  # [S, 1]
    acc = np.asarray(action_acc, dtype=np.float64)[None, :]  # [1, A]
    paper = features()[s_paper]  # [S, A, 3]

    def after(d, v):
        return d - v * decision_step_s - 0.5 * acc * decision_step_s * decision_step_s, v + acc * decision_step_s

    d_ac, v_ac = after(rep["d_AC"], rep["v_AC"])
    d_ab, v_ab = after(rep["d_AB"], rep["v_AB"])
    out = []
    for n in names:
        if n in NEEDS_PREVIOUS_ACTION and prev is None:
            raise ConfigError(f"feature {n!r} needs A's previous action: use the 'driver' state encoding")
        if n in PAPER_FEATURES:
            col = paper[..., PAPER_FEATURES.index(n)]
        elif n in BIAS_FEATURES:
            col = bias_columns(S)[BIAS_FEATURES.index(n)]
        elif n == "ittc_C":
            col = np.maximum(v_ac, 0.0) / np.maximum(d_ac, 1.0)
        elif n == "ittc_B":
            col = np.maximum(v_ab, 0.0) / np.maximum(d_ab, 1.0)
        elif n == "rel_speed_C":
            col = np.abs(v_ac) / 10.0
        elif n == "rel_speed_B":
            col = np.abs(v_ab) / 10.0
        elif n == "abs_acc":
            col = np.broadcast_to(np.abs(acc) / ACC_SCALE_FT_S2, (S, N_ACTIONS))
        elif n in NEEDS_PREVIOUS_ACTION:
            col = persistence_columns(prev, action_acc)[0 if n == "keep_action" else 1]
        else:
            raise ConfigError(f"unknown merge feature {n!r}; known: {DRIVER_FEATURES}")
        out.append(np.broadcast_to(col, (S, N_ACTIONS)))
    if not out:
        raise ConfigError("a feature set needs at least one feature")
    return np.stack(out, axis=-1).astype(np.float64)


def driver_encode_sequence(states_paper, actions, first_prev: int = ZERO_ACTION) -> np.ndarray:
    """``[T]`` driver-encoded states of one trajectory of paper states and actions ``[T]``: the
    previous action of step t is action t-1; of step 0, ``first_prev`` (unknown: Zero)."""
    s = np.asarray(states_paper, dtype=np.int64)
    a = np.asarray(actions, dtype=np.int64)
    prev = np.concatenate([[first_prev], a[:-1]]).astype(np.int64)
    return s * N_ACTIONS + prev

