"""The state bins of the freeway-merge domain (paper section 4.2): :class:`MergeBins`, the
encoder of continuous merge variables into the state index of :mod:`irl.domains.merge.states`,
and :func:`~irl.domains.merge.bins.fit_quantile_bins`, its edges fitted on training encounters.

**Bins**: ``x1..x4`` are the 5-bin indices of ``d_AC, d_AB, v_AC, v_AB`` under
:class:`MergeBins`. A value equal to an inner edge falls in the bin above the edge. ``d_AC``
bins count from the far end (bin 0 = farthest, bin 4 = closest: ``d_AC < 35 ft`` with the
smallest edge at 35, which the Safe feature tests); the other three count up (bin 0 = smallest
value). ``+inf`` and ``-inf`` fall in the outer bins. NaN is an
:class:`~irl.errors.EncodingError`, except for the no-lead-car rule.

**No-lead-car rule** (the one rule, in tables, encoders and the closed loop alike): when A has
no lead car C, ``d_AC`` and ``v_AC`` are both NaN. Such a frame encodes to the farthest
``d_AC`` bin (``x1 = 0``) and the ``v_AC`` bin that holds zero relative speed
(:meth:`MergeBins.no_lead_v_AC_bin`): an open road ahead. Exactly one of the two NaN is an
error.
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

from irl.domains.merge.actions import N_ACTIONS
from irl.domains.merge.encounters import validate_encounters
from irl.domains.merge.states import (
    DESCENDING,
    N_BINS,
    SAFE_DISTANCE_FT,
    STATE_ENCODINGS,
    VARIABLES,
    driver_state,
    state_index,
)
from irl.errors import ConfigError, DemonstrationError, EncodingError
from merge_irl.atomic import write_json_atomic


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
            encoding: one of :data:`~irl.domains.merge.states.STATE_ENCODINGS`.

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
    """Quantile bin edges fitted on training encounters (the default binning).

    ``d_AB, v_AB``: the 20/40/60/80 % quantiles; ``v_AC`` the same over the frames with a car
    C (:meth:`MergeBins.assumed_authors`' ``v_AC`` edges when no frame has one). ``d_AC``: the
    smallest edge is fixed at ``safe_distance`` (35 ft) so that bin 4 means ``d_AC < 35 ft`` as
    the Safe feature requires; the other three are the 25/50/75 % quantiles of the values
    ``>= safe_distance``. Edges that coincide (ties in the data) are spread apart by a tiny
    amount to stay strictly increasing, with a :class:`DegenerateBinsWarning`.

    Raises:
        DemonstrationError: ``table`` breaks :func:`~irl.domains.merge.encounters.validate_encounters`, or a variable is
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
