"""Closed-loop metrics of one episode (one simulation run): :func:`~analysis.evaluation.metrics.episode_metrics`.

Aggregated over seeds they are :mod:`analysis.evaluation.aggregate`'s; the distances to the
demonstrations (Jensen-Shannon divergence, held-out log-likelihood, Wasserstein-1) are
:mod:`analysis.evaluation.distances`'.

An episode is one run of a scenario with a :class:`sim.closed_loop.controller.Controller`; its inputs are
the trajectory table, the controller's control episodes (one per lag car A) and decisions.
Definitions (NGSIM units in, SI where stated):

* ``collisions``: distinct colliding pairs (collider, victim) in the whole run (SUMO's collision
  detection), and ``a_collisions``: the distinct pairs among them that ended a control episode
  because A collided. A pair is counted once even when it ends several control episodes (with
  SUMO's ``--collision.action warn`` the cars keep overlapping, and a later take-over of the
  same A ends at once on the same pair), so ``a_collisions <= collisions``.
* ``emergency_brakings``: braking events strictly beyond ``emergency_decel_m_s2`` (default
  4.5 m/s^2 = 14.76 ft/s^2, the default ``decel`` of SUMO's passenger car, beyond which SUMO
  itself speaks of emergency braking) by more than ``emergency_tolerance_m_s2`` (default
  0.05 m/s^2): an acceleration ``acc < -(emergency_decel_m_s2 + emergency_tolerance_m_s2)``,
  compared in m/s^2 (:func:`is_emergency`), so a car braking at exactly its normal maximum
  (SUMO's 4.5 m/s^2, a hair below -4.5 after the trip through ft/s^2) is not counted; by A, B or
  the car following A while A is controlled. An event is a maximal run of consecutive frames of
  one vehicle beyond the threshold. ``emergency_brakings_A``, ``emergency_brakings_B`` and
  ``emergency_brakings_follower`` split them by role (a vehicle-frame in two roles takes the
  first of A, B, follower; an event the role of its first frame), so the three add up to
  ``emergency_brakings``. ``emergency_brakings_all`` counts the same over every vehicle of the run.
* ``close_to_c``: control episodes whose A came closer than ``close_gap_m`` (default 2 m) bumper
  to bumper to its lead car C while controlled (C: the nearest merge-lane vehicle ahead of A other
  than B, in the frames where A is in the merge lane;
  :func:`analysis.evaluation.human_likeness.min_gaps_to_c`).
* ``min_ttc_s``: smallest time-to-collision over the controlled windows, for A behind its
  leader and for A's follower behind A: ``gap / (v_follower - v_leader)`` when closing,
  ``gap = Space_Headway - leader length`` (bumper to bumper). ``inf`` if never closing.
* ``b_ahead_rate``: share of the merges (B reached lane 6 while A was controlled) with B ahead
  of A at the merge frame.
* ``travel_time_s``: mean time A needs to cross the section (first to last frame with
  ``0 <= Local_Y <= section length``), over the As whose record spans the whole section.
* ``action_counts``: A's actions at the decisions (for the SUMO baseline, the bin of A's
  measured acceleration); ``js_divergence``: Jensen-Shannon divergence (base 2, in [0, 1])
  between that distribution and the demonstrations' action distribution.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields

import numpy as np
import pandas as pd

from analysis.evaluation.distances import js_divergence
from analysis.evaluation.human_likeness import CLOSE_GAP_M, min_gaps_to_c
from irl.domains.merge.actions import N_ACTIONS
from merge_irl.units import FRAME_S, FT_PER_M, M_PER_FT
from sim.runtime.schema import RIGHTMOST_MAIN_LANE


@dataclass(frozen=True)
class MetricsConfig:
    """Thresholds of :func:`episode_metrics`.

    Attributes:
        emergency_decel_m_s2: deceleration beyond which braking counts as emergency (m/s^2).
        emergency_tolerance_m_s2: how far beyond ``emergency_decel_m_s2`` braking must be to
            count (m/s^2, >= 0): ``acc < -(emergency_decel_m_s2 + emergency_tolerance_m_s2)``.
        section_margin_ft: a travel time counts when A's record starts within this of the
            section start and ends within this of its end (ft).
        close_gap_m: bumper gap to C below which an A counts as close to C (m).
    """

    emergency_decel_m_s2: float = 4.5
    section_margin_ft: float = 60.0
    close_gap_m: float = CLOSE_GAP_M
    emergency_tolerance_m_s2: float = 0.05

    def __post_init__(self) -> None:
        if not (self.emergency_tolerance_m_s2 >= 0 and np.isfinite(self.emergency_tolerance_m_s2)):
            raise ValueError(f"MetricsConfig.emergency_tolerance_m_s2: must be a finite number >= 0, got "
                             f"{self.emergency_tolerance_m_s2}")

    @property
    def emergency_threshold_m_s2(self) -> float:
        """The acceleration (m/s^2, negative) below which braking counts as emergency."""
        return -(self.emergency_decel_m_s2 + self.emergency_tolerance_m_s2)


@dataclass(frozen=True)
class EpisodeMetrics:
    """Metrics of one episode. Counts are ints; rates and times floats (NaN when undefined)."""

    policy: str
    seed: int
    n_controls: int
    n_merges: int
    collisions: int
    a_collisions: int
    teleports: int
    emergency_brakings: int
    emergency_brakings_all: int
    min_ttc_s: float
    b_ahead_rate: float
    travel_time_s: float
    mean_speed_A_ft_s: float
    action_counts: tuple[int, ...]
    js_divergence: float
    release_reasons: dict[str, int] = field(default_factory=dict)
    n_decisions: int = 0
    safety_interventions: int = 0
    need_brakes: int = 0
    close_to_c: int = 0
    a_into_c: int = 0
    a_into_b: int = 0
    emergency_brakings_A: int = 0
    emergency_brakings_B: int = 0
    emergency_brakings_follower: int = 0
    a_collision_kinds: dict[str, int] = field(default_factory=dict)

    def to_dict(self) -> dict:
        d = asdict(self)
        d["action_counts"] = list(self.action_counts)
        return d

    @classmethod
    def from_dict(cls, d: dict) -> EpisodeMetrics:
        kw = {f.name: d[f.name] for f in fields(cls) if f.name in d}
        kw["action_counts"] = tuple(int(x) for x in kw["action_counts"])
        for k in ("min_ttc_s", "b_ahead_rate", "travel_time_s", "mean_speed_A_ft_s", "js_divergence"):
            kw[k] = float("nan") if kw[k] is None else float(kw[k])
        return cls(**kw)


#: The roles whose emergency brakings are counted apart (``emergency_brakings_<role>``), in the
#: order a vehicle-frame in two roles is given the first.
EMERGENCY_ROLES = ("A", "B", "follower")


def is_emergency(acc_ft_s2: np.ndarray, config: MetricsConfig) -> np.ndarray:
    """``[N]`` bool: accelerations (ft/s^2) strictly beyond the emergency threshold, compared in
    m/s^2: ``acc < -(emergency_decel_m_s2 + emergency_tolerance_m_s2)``."""
    return np.asarray(acc_ft_s2, dtype=np.float64) * M_PER_FT < config.emergency_threshold_m_s2


def _run_starts(below: np.ndarray, vid: np.ndarray, frame: np.ndarray) -> np.ndarray:
    """``[N]`` bool: the rows that start a maximal run of consecutive frames of one vehicle with
    ``below`` set. Inputs sorted by (vid, frame), all ``[N]``."""
    starts = np.zeros(below.size, dtype=bool)
    idx = np.flatnonzero(below)
    if idx.size:
        new = np.ones(idx.size, dtype=bool)
        new[1:] = (vid[idx[1:]] != vid[idx[:-1]]) | (frame[idx[1:]] != frame[idx[:-1]] + 1)
        starts[idx[new]] = True
    return starts


def _emergency_events(rows: pd.DataFrame, config: MetricsConfig) -> np.ndarray:
    """``[N]`` bool over ``rows`` (sorted by vehicle and frame): the first frame of each emergency braking."""
    return _run_starts(is_emergency(rows["v_Acc"].to_numpy(np.float64), config), rows["Vehicle_ID"].to_numpy(),
                       rows["Frame_ID"].to_numpy())


def _near_a(t: pd.DataFrame, wins: list[tuple[int, int, int, int]]) -> tuple[pd.DataFrame, pd.DataFrame, pd.DataFrame]:
    """``(near, a_rows, f_rows)``: the rows of A, B and A's follower inside the control windows
    (``near``, one row per vehicle-frame, sorted, with its role index into
    :data:`EMERGENCY_ROLES` in ``_role``), and those of A and of A's follower."""
    w = pd.DataFrame(wins, columns=["a_id", "b_id", "start", "end"])
    a_rows = t.merge(w[["a_id", "start", "end"]], left_on="Vehicle_ID", right_on="a_id")
    a_rows = a_rows[(a_rows["Frame_ID"] >= a_rows["start"]) & (a_rows["Frame_ID"] <= a_rows["end"])]
    b_rows = t.merge(w[["b_id", "start", "end"]], left_on="Vehicle_ID", right_on="b_id")
    b_rows = b_rows[(b_rows["Frame_ID"] >= b_rows["start"]) & (b_rows["Frame_ID"] <= b_rows["end"])]
    fol_keys = a_rows.loc[a_rows["Following"] > 0, ["Following", "Frame_ID"]].rename(columns={"Following": "fid"})
    f_rows = t.merge(fol_keys.drop_duplicates(), left_on=["Vehicle_ID", "Frame_ID"], right_on=["fid", "Frame_ID"])
    near = pd.concat([r[t.columns].assign(_role=i) for i, r in enumerate((a_rows, b_rows, f_rows))])
    near = near.drop_duplicates(["Vehicle_ID", "Frame_ID"]).sort_values(["Vehicle_ID", "Frame_ID"])
    return near, a_rows, f_rows


def _windows(controls: pd.DataFrame, last_frame: int) -> list[tuple[int, int, int, int]]:
    """(a_id, b_id, start, end) frames of each control episode (end inclusive)."""
    out = []
    for r in controls.itertuples(index=False):
        end = int(r.end_frame) if int(r.end_frame) >= 0 else last_frame
        out.append((int(r.a_id), int(r.b_id), int(r.start_frame), end))
    return out


def episode_metrics(
    table: pd.DataFrame,
    controls: pd.DataFrame,
    decisions: pd.DataFrame,
    *,
    policy: str,
    seed: int,
    section_length_ft: float,
    collisions: int = 0,
    teleports: int = 0,
    demo_action_counts: np.ndarray | None = None,
    config: MetricsConfig = MetricsConfig(),
    merge_lane: int = RIGHTMOST_MAIN_LANE,
) -> EpisodeMetrics:
    """Metrics of one episode (see the module docstring).

    Args:
        table: the run's trajectory table (NGSIM schema).
        controls: ``Controller.control_table()``; decisions: ``Controller.decision_table()``.
        policy, seed: labels.
        section_length_ft: length of the main road (ft).
        collisions, teleports: whole-run counts (``Controller.n_collisions`` / ``n_teleports``).
        demo_action_counts: ``[5]`` action counts of the demonstrations (for the divergence).
        merge_lane: the site's merge lane code (where A's lead car C is looked for; lane 6 on
            I-80, every preset).
    """
    t = table.sort_values(["Vehicle_ID", "Frame_ID"], kind="stable")
    frm = t["Frame_ID"].to_numpy()
    eb_all = int(_emergency_events(t, config).sum())
    last_frame = int(frm.max()) if frm.size else 0
    wins = _windows(controls, last_frame)

    # rows of A, B and A's follower inside their windows
    eb_role = np.zeros(len(EMERGENCY_ROLES), dtype=np.int64)
    if wins:
        near, a_rows, f_rows = _near_a(t, wins)
        eb_role = np.bincount(near["_role"].to_numpy()[_emergency_events(near, config)], minlength=len(EMERGENCY_ROLES))
        ttc = _min_ttc(t, pd.concat([a_rows[t.columns], f_rows[t.columns]]))
        mean_speed = float(a_rows["v_Vel"].mean()) if len(a_rows) else float("nan")
    else:
        ttc, mean_speed = float("inf"), float("nan")

    merged = controls[controls["merge_frame"] >= 0] if len(controls) else controls
    b_ahead = float(np.mean(merged["b_ahead"].astype(bool))) if len(merged) else float("nan")
    tt = _travel_times(t, [x[0] for x in wins], section_length_ft, config.section_margin_ft)
    counts = np.zeros(N_ACTIONS, dtype=np.int64)
    if len(decisions):
        np.add.at(counts, decisions["action"].to_numpy(dtype=np.int64), 1)
    jsd = js_divergence(counts, demo_action_counts) if demo_action_counts is not None else float("nan")
    reasons = controls["reason"].value_counts().to_dict() if len(controls) else {}
    a_coll = _a_collisions(controls)
    a_into_c = _a_collisions(controls, "A into C")
    a_into_b = _a_collisions(controls, "A into B")
    return EpisodeMetrics(
        policy=policy, seed=int(seed), n_controls=int(len(controls)), n_merges=int(len(merged)),
        collisions=int(collisions), a_collisions=a_coll, a_into_c=a_into_c, a_into_b=a_into_b,
        teleports=int(teleports),
        emergency_brakings=int(eb_role.sum()), emergency_brakings_all=eb_all, min_ttc_s=float(ttc),
        emergency_brakings_A=int(eb_role[0]), emergency_brakings_B=int(eb_role[1]),
        emergency_brakings_follower=int(eb_role[2]),
        b_ahead_rate=b_ahead, travel_time_s=float(np.nanmean(tt)) if np.isfinite(tt).any() else float("nan"),
        mean_speed_A_ft_s=mean_speed, action_counts=tuple(int(x) for x in counts), js_divergence=jsd,
        release_reasons={str(k): int(v) for k, v in reasons.items()},
        n_decisions=int(len(decisions)),
        safety_interventions=int(decisions["filtered"].astype(bool).sum()) if "filtered" in decisions else 0,
        need_brakes=int(decisions["need_brake"].astype(bool).sum()) if "need_brake" in decisions else 0,
        close_to_c=int(np.sum(min_gaps_to_c(t, wins, merge_lane) < config.close_gap_m * FT_PER_M)),
        a_collision_kinds=a_collision_kinds(controls),
    )


def a_collision_kinds(controls: pd.DataFrame) -> dict[str, int]:
    """The distinct collision pairs that ended a control episode (``a_collisions``) by who hit whom
    (:data:`~sim.closed_loop.records.COLLISION_KINDS`; a pair takes the kind of its first release,
    "unknown" without the column), so the counts add up to ``a_collisions`` exactly."""
    if not len(controls):
        return {}
    ended = controls[controls["reason"] == "collision"]
    kinds = (ended["collision_kind"].astype(str).replace("", "unknown") if "collision_kind" in ended
             else pd.Series("unknown", index=ended.index))
    if "collision_pair" in ended:
        pairs = ended["collision_pair"].astype(str)
        first = ~pairs.duplicated() | (pairs == "")  # an unnamed pair counts each time, as in _a_collisions
        kinds = kinds[first.to_numpy()]
    return {str(k): int(v) for k, v in kinds.value_counts().sort_index().items()}


def _a_collisions(controls: pd.DataFrame, kind: str | None = None) -> int:
    """Distinct collision pairs that ended a control episode (control episodes ended by a
    collision, when the table has no ``collision_pair`` column); ``kind``: only those of that
    :data:`~sim.closed_loop.records.COLLISION_KINDS` (``"A into C"``, ``"A into B"``)."""
    if not len(controls):
        return 0
    ended = controls[controls["reason"] == "collision"]
    if kind is not None:
        ended = ended[ended["collision_kind"] == kind] if "collision_kind" in ended else ended.iloc[:0]
    if "collision_pair" not in ended:
        return int(len(ended))
    pairs = ended["collision_pair"].astype(str)
    return int(pairs[pairs != ""].nunique() + (pairs == "").sum())


def _min_ttc(table: pd.DataFrame, rows: pd.DataFrame) -> float:
    """Smallest TTC (s) of the follower->leader pairs of ``rows`` (each row = a follower)."""
    rows = rows[rows["Preceding"] > 0]
    if rows.empty:
        return float("inf")
    lead = table[["Vehicle_ID", "Frame_ID", "v_Vel", "v_Length", "Local_Y"]].rename(
        columns={"Vehicle_ID": "Preceding", "v_Vel": "v_lead", "v_Length": "len_lead", "Local_Y": "y_lead"})
    m = rows.merge(lead, on=["Preceding", "Frame_ID"])
    gap = (m["y_lead"] - m["Local_Y"] - m["len_lead"]).to_numpy(float)
    closing = (m["v_Vel"] - m["v_lead"]).to_numpy(float)
    ok = closing > 1e-6
    if not ok.any():
        return float("inf")
    return float(max(0.0, np.min(np.maximum(gap[ok], 0.0) / closing[ok])))


def _travel_times(table: pd.DataFrame, a_ids: list[int], section_ft: float, margin: float) -> np.ndarray:
    """Section crossing time (s) of each A whose record spans the section; NaN otherwise."""
    out = np.full(len(a_ids), np.nan)
    if not a_ids:
        return out
    sub = table[table["Vehicle_ID"].isin(a_ids) & (table["Local_Y"] >= 0) & (table["Local_Y"] <= section_ft)]
    g = sub.groupby("Vehicle_ID").agg(f0=("Frame_ID", "min"), f1=("Frame_ID", "max"),
                                      y0=("Local_Y", "min"), y1=("Local_Y", "max"))
    for i, a in enumerate(a_ids):
        if a in g.index:
            r = g.loc[a]
            if r.y0 <= margin and r.y1 >= section_ft - margin:
                out[i] = (r.f1 - r.f0) * FRAME_S
    return out
