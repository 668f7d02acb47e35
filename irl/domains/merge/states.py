"""The states of the freeway-merge domain (paper section 4.2): the state variables, the
state index and the state encodings.

**State variables** (per frame): ``d_AC = Local_Y(C) - Local_Y(A)`` and
``d_AB = Local_Y(B) - Local_Y(A)`` (ft, front bumper to front bumper, positive when the other
car is ahead of A), ``v_AC = v(A) - v(C)`` and ``v_AB = v(A) - v(B)`` (ft/s, positive when A
is faster), ``B_is_truck`` (B's NGSIM class is 3).

**State index** (the authors' layout, 1250 states)::

    s = 625 * truck + 125 * x1 + 25 * x2 + 5 * x3 + x4

with ``x1..x4`` the 5-bin indices of ``d_AC, d_AB, v_AC, v_AB`` under
:class:`~irl.domains.merge.bins.MergeBins` (the bin rules are in :mod:`irl.domains.merge.bins`).

**State encodings** (:data:`STATE_ENCODINGS`): ``"paper"`` is the index above (1250 states);
``"driver"`` adds A's previous action (human acceleration persists from one decision to the next),
``s_driver = s_paper * N_ACTIONS + prev_action`` (6250 states, :func:`n_states`). The previous
action at an encounter's first decision is the bin of A's acceleration over the decision step
before it, from A's speed history (:func:`previous_action`);
:data:`~irl.domains.merge.actions.ZERO_ACTION` when that history is unknown.
"""

from __future__ import annotations

import numpy as np

from irl.domains.merge.actions import N_ACTIONS, ZERO_ACTION, action_of
from irl.errors import ConfigError

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
        the action index; :data:`~irl.domains.merge.actions.ZERO_ACTION` when either speed is unknown.
    """
    if speed_before is None or speed_now is None or speed_before != speed_before or speed_now != speed_now:
        return ZERO_ACTION
    return action_of((speed_now - speed_before) / dt)


def state_index(truck, x1, x2, x3, x4):
    """``625 truck + 125 x1 + 25 x2 + 5 x3 + x4`` (integer arrays broadcast)."""
    return 625 * np.asarray(truck) + 125 * np.asarray(x1) + 25 * np.asarray(x2) + 5 * np.asarray(x3) + np.asarray(x4)


def state_parts(s) -> np.ndarray:
    """Inverse of :func:`state_index`: ``s [...]`` -> ``[..., 5]`` of ``(truck, x1, x2, x3, x4)``."""
    s = np.asarray(s, dtype=np.int64)
    return np.stack([s // 625, (s // 125) % 5, (s // 25) % 5, (s // 5) % 5, s % 5], axis=-1)
