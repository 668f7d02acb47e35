"""Congested car-following states, simulated and real, and the gaps ramp cars accepted: what the
calibration check (:mod:`analysis.calibration.check`) compares.

Both sides are filtered the same way: a leader in the same lane, spacing in (0, 300] ft, speed
in [1, 45] ft/s; the simulated states are further limited to the lanes the real pairs come from
(I-80 lanes 2-6, :data:`REAL_LANES`) and to the study area. Spacing is bumper to bumper, time
headway front to front / speed (NGSIM's Time_Headway).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from analysis.calibration import CarFollowingPair
from merge_irl.units import M_PER_FT
from sim.runtime.sites import I80, SiteProfile

#: Congested car following: speed range (ft/s) and largest spacing (ft) kept.
SPEED_RANGE_FT_S = (1.0, 45.0)
MAX_SPACING_FT = 300.0
VARIABLES = ("speed_ft_s", "spacing_ft", "time_headway_s")
#: I-80 lanes the real pairs were recorded on (ngsim_i80_car_following: lanes 2-6).
REAL_LANES = (2, 3, 4, 5, 6)
#: Quantiles of the accepted-gap summary.
GAP_QUANTILES = (0.1, 0.25, 0.5, 0.75, 0.9)


@dataclass(frozen=True)
class AcceptedGaps:
    """Gaps ramp cars accepted: at the first frame a car seen on the ramp / auxiliary lane
    (lane 7) is in lane 6, bumper-to-bumper distances (ft) to the lag car A behind it
    (``lag``: B's rear bumper minus A's front bumper), to the lead car C ahead (``lead``: C's
    rear minus B's front) and between them (``total``: C's rear minus A's front). float64[n]
    each, NaN where there is no such car in lane 6.
    """

    lag_ft: np.ndarray
    lead_ft: np.ndarray
    total_ft: np.ndarray

    @property
    def n(self) -> int:
        return len(self.total_ft)

    def quantiles(self) -> dict[str, list[float]]:
        """name -> the :data:`GAP_QUANTILES` of the finite values (NaN when there are none)."""
        out = {}
        for name in ("lag_ft", "lead_ft", "total_ft"):
            x = getattr(self, name)
            x = x[np.isfinite(x)]
            out[name] = [float(q) for q in np.quantile(x, GAP_QUANTILES)] if len(x) else [float("nan")] * len(GAP_QUANTILES)
        return out


def _vehicle_lengths(table: pd.DataFrame) -> pd.Series:
    """Vehicle_ID -> v_Length (ft) of a trajectory table (first row of each vehicle)."""
    return table.drop_duplicates("Vehicle_ID").set_index("Vehicle_ID")["v_Length"]


def accepted_gaps(table: pd.DataFrame, *, site: SiteProfile = I80) -> AcceptedGaps:
    """The gaps accepted by the ramp cars of a trajectory table (NGSIM schema, ft); see
    :class:`AcceptedGaps`. Lanes are ``site``'s (the simulated scenario's,
    :func:`sim.runtime.sites.site_of`; I-80's by default): cars never seen on a ramp lane (I-80: 7)
    before the merge lane (I-80: 6) are left out."""
    t = table.sort_values(["Vehicle_ID", "Frame_ID"], kind="stable")
    on_ramp = t["Lane_ID"].isin(site.ramp_lanes)
    was_ramp = on_ramp.groupby(t["Vehicle_ID"]).cummax()
    merged = t[(t["Lane_ID"] == site.merge_lane) & was_ramp].drop_duplicates("Vehicle_ID")
    where = table.set_index(["Vehicle_ID", "Frame_ID"])["Local_Y"]
    lengths = _vehicle_lengths(table)

    def y_of(ids: pd.Series) -> np.ndarray:
        keys = list(zip(ids.to_numpy(), merged["Frame_ID"].to_numpy()))
        return np.array([where.get(k, np.nan) if k[0] != 0 else np.nan for k in keys], dtype=float)

    y_b = merged["Local_Y"].to_numpy(dtype=float)
    len_b = merged["v_Length"].to_numpy(dtype=float)
    y_a = y_of(merged["Following"])
    y_c = y_of(merged["Preceding"])
    len_c = merged["Preceding"].map(lengths).to_numpy(dtype=float)
    return AcceptedGaps(lag_ft=y_b - len_b - y_a, lead_ft=y_c - len_c - y_b, total_ft=y_c - len_c - y_a)


def _congested(speed: np.ndarray, spacing: np.ndarray, headway_front: np.ndarray) -> dict[str, np.ndarray]:
    ok = (speed >= SPEED_RANGE_FT_S[0]) & (speed <= SPEED_RANGE_FT_S[1]) & (spacing > 0) & (spacing <= MAX_SPACING_FT)
    return {"speed_ft_s": speed[ok], "spacing_ft": spacing[ok], "time_headway_s": headway_front[ok] / speed[ok]}


def table_states(table: pd.DataFrame, *, lanes: tuple[int, ...] = REAL_LANES,
                 study_length_ft: float = np.inf) -> dict[str, np.ndarray]:
    """Congested following states of a trajectory table (NGSIM units); float64[n] per variable.

    Spacing = ``Space_Headway`` (front to front, ft) minus the preceding vehicle's ``v_Length``
    (bumper to bumper); time headway = ``Space_Headway / v_Vel``. Rows on ``lanes`` with
    ``0 <= Local_Y <= study_length_ft`` and a preceding vehicle are kept.
    """
    y = table["Local_Y"]
    t = table[table["Lane_ID"].isin(lanes) & (table["Preceding"] != 0) & (y >= 0) & (y <= study_length_ft)]
    lengths = _vehicle_lengths(table)
    lead_len = t["Preceding"].map(lengths).to_numpy(dtype=float)
    front = t["Space_Headway"].to_numpy(dtype=float)
    spacing = front - np.nan_to_num(lead_len, nan=np.inf)
    return _congested(t["v_Vel"].to_numpy(dtype=float), spacing, front)


def pair_states(pairs: list[CarFollowingPair]) -> dict[str, np.ndarray]:
    """The same variables from the real pairs (converted back to feet): the pairs' ``spacing``
    is bumper to bumper (``x_leader - x_follower - leader_length``, positions of the front
    bumpers), front to front adds the leader's length back."""
    v = np.concatenate([p.v_follower for p in pairs]) / M_PER_FT
    s = np.concatenate([p.spacing for p in pairs]) / M_PER_FT
    front = np.concatenate([p.spacing + p.leader_length for p in pairs]) / M_PER_FT
    return _congested(v, s, front)
