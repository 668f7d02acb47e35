"""Observe the merge variables of car A (with merging car B and lead car C) in a frame.

Conventions (the paper's section 4.2, as in ``sim.encounters``; NGSIM units):

* ``d_AC = Local_Y(C) - Local_Y(A)`` and ``d_AB = Local_Y(B) - Local_Y(A)`` (ft, front bumper
  to front bumper along the road; positive when the other car is ahead of A).
* ``v_AC = v(A) - v(C)`` and ``v_AB = v(A) - v(B)`` (ft/s; positive when A is faster).
* ``B_is_truck``: B's NGSIM class is 3.

When there is no lead car C, A's view ahead is open: ``d_AC = NO_LEAD_GAP_FT`` and
``v_AC = 0``. The discrete state uses the model's saved bin edges through
:class:`StateEncoder` (state = 625 truck + 125 x1 + 25 x2 + 5 x3 + x4).
"""

from __future__ import annotations

from bisect import bisect_right
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from sim.errors import SimError
from sim.hooks import FrameState
from sim.schema import RIGHTMOST_MAIN_LANE, V_CLASS_TRUCK

VARIABLES = ("d_AC", "d_AB", "v_AC", "v_AB")
#: d_AC used when A has no lead car C (ft): far beyond any bin edge.
NO_LEAD_GAP_FT = 1000.0


class ObservationError(SimError, ValueError):
    """Bin edges or an observation are malformed."""


@dataclass(frozen=True)
class MergeObservation:
    """What car A sees at one decision step.

    Attributes:
        d_AC, d_AB: gaps (ft); v_AC, v_AB: relative speeds (ft/s); see the module docstring.
        b_is_truck: whether B is a truck.
        state: discrete state index in ``[0, 1250)`` (-1 when no encoder was given).
        speed_A: A's speed (ft/s), for logging.
    """

    d_AC: float
    d_AB: float
    v_AC: float
    v_AB: float
    b_is_truck: bool
    state: int = -1
    speed_A: float = 0.0

    def as_array(self) -> np.ndarray:
        """``[5]``: d_AC, d_AB, v_AC, v_AB, B_is_truck."""
        return np.array([self.d_AC, self.d_AB, self.v_AC, self.v_AB, float(self.b_is_truck)])


class StateEncoder:
    """Continuous merge variables -> discrete state, with a model's bin edges.

    ``bin_edges[name]`` holds the 4 increasing inner edges of variable ``name`` (d_AC, d_AB,
    v_AC, v_AB). The bin of value ``x`` is ``searchsorted(edges, x, side="right")`` in 0..4
    (a value equal to an edge goes to the upper bin); the variables listed in ``descending``
    count bins from the top instead (``4 - bin``), as the merge MDP does for d_AC (its bin 4
    means the smallest gap, d_AC < 35 ft in the authors' data).

    ``sim`` does not import ``irl``; ``analysis.policies`` checks this encoder against
    ``irl.merge_mdp``'s discretisation (or passes that one in its place).
    """

    def __init__(self, bin_edges: Mapping[str, Sequence[float]], *, descending: Sequence[str] = ("d_AC",)):
        edges = []
        for name in VARIABLES:
            if name not in bin_edges:
                raise ObservationError(f"bin_edges: missing variable {name!r}; expected keys {VARIABLES}")
            e = np.asarray(bin_edges[name], dtype=np.float64)
            if e.ndim != 1 or e.size != 4 or not np.all(np.isfinite(e)) or np.any(np.diff(e) < 0):
                raise ObservationError(
                    f"bin_edges[{name!r}]: expected 4 finite increasing inner edges, got {list(e)}"
                )
            edges.append(e)
        self.edges = tuple(edges)
        self._edge_lists = tuple(e.tolist() for e in edges)
        self.descending = tuple(name in descending for name in VARIABLES)

    def bins(self, values: np.ndarray) -> np.ndarray:
        """``values [N, 4]`` (d_AC, d_AB, v_AC, v_AB) -> bins ``[N, 4]`` int64 in 0..4."""
        v = np.atleast_2d(np.asarray(values, dtype=np.float64))
        out = np.empty(v.shape, dtype=np.int64)
        for j, (e, desc) in enumerate(zip(self.edges, self.descending)):
            b = np.searchsorted(e, v[:, j], side="right")
            out[:, j] = 4 - b if desc else b
        return out

    def states(self, values: np.ndarray, truck: np.ndarray) -> np.ndarray:
        """``values [N, 4]``, ``truck [N]`` bool -> states ``[N]`` int64 in [0, 1250)."""
        b = self.bins(values)
        t = np.asarray(truck, dtype=np.int64).reshape(-1)
        return 625 * t + 125 * b[:, 0] + 25 * b[:, 1] + 5 * b[:, 2] + b[:, 3]

    def state(self, d_AC: float, d_AB: float, v_AC: float, v_AB: float, truck: bool) -> int:
        """One observation -> state in [0, 1250); same bins as :meth:`states`, without numpy."""
        s = 625 if truck else 0
        for x, edges, desc, weight in zip((d_AC, d_AB, v_AC, v_AB), self._edge_lists, self.descending, (125, 25, 5, 1)):
            b = bisect_right(edges, x)  # NaN sorts last, like searchsorted
            s += weight * (4 - b if desc else b)
        return s


def observe(frame: FrameState, ia: int, ib: int, ic: int | None) -> tuple[float, float, float, float, bool]:
    """The merge variables at ``frame`` for rows ``ia`` (A), ``ib`` (B), ``ic`` (C or None).

    Returns ``(d_AC, d_AB, v_AC, v_AB, B_is_truck)``.
    """
    ya, va = float(frame.local_y[ia]), float(frame.speed[ia])
    d_ab = float(frame.local_y[ib]) - ya
    v_ab = va - float(frame.speed[ib])
    if ic is None:
        d_ac, v_ac = NO_LEAD_GAP_FT, 0.0
    else:
        d_ac = float(frame.local_y[ic]) - ya
        v_ac = va - float(frame.speed[ic])
    return d_ac, d_ab, v_ac, v_ab, bool(frame.v_class[ib] == V_CLASS_TRUCK)


def lead_of(frame: FrameState, y_ref: float, *, lane: int = RIGHTMOST_MAIN_LANE, exclude: Sequence[int | None] = ()) -> int | None:
    """Row of the nearest vehicle in ``lane`` strictly ahead of ``y_ref`` (ft), or None.

    Rows in ``exclude`` are skipped; among vehicles at the same position the lowest row wins.
    """
    ys, rows = frame.lane_order(lane)
    for k in range(bisect_right(ys, y_ref), len(rows)):
        if rows[k] not in exclude:
            return rows[k]
    return None


def lag_of(frame: FrameState, y_ref: float, *, lane: int = RIGHTMOST_MAIN_LANE, max_gap_ft: float = np.inf) -> int | None:
    """Row of the nearest vehicle in ``lane`` at or behind ``y_ref`` within ``max_gap_ft``, or None.

    Among vehicles at the same position the lowest row wins.
    """
    ys, rows = frame.lane_order(lane)
    k = bisect_right(ys, y_ref) - 1
    if k < 0 or ys[k] < y_ref - max_gap_ft:
        return None
    while k > 0 and ys[k - 1] == ys[k]:
        k -= 1
    return rows[k]
