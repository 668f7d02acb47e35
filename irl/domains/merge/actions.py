"""The actions of the freeway-merge domain (paper section 4.2): A's acceleration in 5 bins.

**Actions**: A's acceleration (ft/s^2) in 5 bins, 0 High Brake ``a <= -4.8``, 1 Low Brake
``-4.8 < a <= -0.6``, 2 Zero ``-0.6 < a < 0.6``, 3 Low Accel ``0.6 <= a < 4.8``, 4 High Accel
``a >= 4.8``. The paper's outer limits are [-11.2, 11.2] (:data:`ACC_LIMITS`); values beyond
them, ``+-inf`` included, fall in the end bins. NaN raises :class:`~irl.errors.EncodingError`.
The closed loop applies :data:`ACTION_ACC_FT_S2` for each action.

**The action at frame t** is the acceleration from t to t + 0.1 s,
``acc_A(t) = (v_A(t+1) - v_A(t)) / 0.1 s`` (:func:`forward_acceleration`): what A does in
state t, as the controller applies it; not SUMO's or NGSIM's ``v_Acc``, the backward
difference that produced state t. A frame whose next speed of A is unknown has no action and
no row (see :data:`irl.domains.merge.encounters.ENCOUNTER_SCHEMA`).
"""

from __future__ import annotations

import numpy as np

from irl.errors import EncodingError
from merge_irl.units import FRAME_S

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
#: Index of the High Brake action (the hardest braking bin).
HIGH_BRAKE = 0


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
