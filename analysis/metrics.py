"""Closed-loop metrics: per episode (one simulation run) and aggregated over seeds.

An episode is one run of a scenario with a :class:`sim.controller.Controller`; its inputs are
the trajectory table, the controller's control episodes (one per lag car A) and decisions.
Definitions (NGSIM units in, SI where stated):

* ``collisions``: collision events in the whole run (SUMO's collision detection, pairs), and
  ``a_collisions``: control episodes that ended because A collided.
* ``emergency_brakings``: braking events harder than ``emergency_decel_m_s2`` (default
  4.5 m/s^2 = 14.76 ft/s^2, the default ``decel`` of SUMO's passenger car, beyond which SUMO
  itself speaks of emergency braking) by A, B or the car following A while A is controlled;
  an event is a maximal run of consecutive frames of one vehicle below the threshold.
  ``emergency_brakings_all`` counts the same over every vehicle of the run.
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
* ``a_collision_rate`` with ``a_collision_ci95``: control episodes ended by A colliding over
  control episodes, with the Wilson score 95 % interval (``scipy.stats.binomtest``).
* ``safety_interventions`` / ``intervention_rate``: decisions whose action the safety filter
  replaced (0 in the raw default), and their share of the commanded decisions.
* ``w1_speed_A_ft_s``, ``w1_acc_A_ft_s2``, ``w1_d_AC_ft``, ``w1_ttc_s``: Wasserstein-1
  distances (``scipy.stats.wasserstein_distance``) between the closed-loop values at A's
  decisions (speed, applied acceleration, d_AC, TTC to C) and the held-out demonstration
  frames (``v_A`` when the table has it, ``acc_A``, ``d_AC``, TTC). TTC to C is front-to-front
  ``d_AC / v_AC`` over the closing steps (``v_AC > 0``), capped at ``TTC_CAP_S``. The SUMO
  driver's distances are the floor the learned drivers are compared to.
* ``flags``: what the model's fit reported (``not_converged``, ``unbounded``, ``infeasible``,
  ``uninformative``) and ``flagged`` (1 if any, for ``--fail-if 'flagged>0'``).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields

import numpy as np
import pandas as pd
from scipy.stats import binomtest, wasserstein_distance

from irl.domains.merge_actions import N_ACTIONS
from irl.units import FRAME_S, FT_PER_M

#: TTC values above this (s) are set to it before the Wasserstein distance.
TTC_CAP_S = 30.0


@dataclass(frozen=True)
class MetricsConfig:
    """Thresholds of :func:`episode_metrics`.

    Attributes:
        emergency_decel_m_s2: deceleration beyond which braking counts as emergency (m/s^2).
        section_margin_ft: a travel time counts when A's record starts within this of the
            section start and ends within this of its end (ft).
    """

    emergency_decel_m_s2: float = 4.5
    section_margin_ft: float = 60.0


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


def js_divergence(p: np.ndarray, q: np.ndarray) -> float:
    """Jensen-Shannon divergence (base 2, in [0, 1]) of two histograms ``[A]`` (normalised here).

    NaN if either is all zero.
    """
    p = np.asarray(p, dtype=np.float64)
    q = np.asarray(q, dtype=np.float64)
    if p.sum() <= 0 or q.sum() <= 0:
        return float("nan")
    p, q = p / p.sum(), q / q.sum()
    m = 0.5 * (p + q)

    def kl(x, y):
        nz = x > 0
        return float(np.sum(x[nz] * np.log2(x[nz] / y[nz])))

    return max(0.0, 0.5 * kl(p, m) + 0.5 * kl(q, m))


def heldout_loglik(log_pi: np.ndarray, states: np.ndarray, actions: np.ndarray) -> tuple[float, float]:
    """Log-likelihood of demonstration steps under a policy.

    Args:
        log_pi: ``[S, A]`` log pi(a|s).
        states, actions: ``[N]`` int steps (all trajectories concatenated).

    Returns:
        ``(sum, mean per step)`` of ``log pi(a_t|s_t)`` (Eq. 5 without ``log Pr(s_1)``).
    """
    s = np.asarray(states, dtype=np.int64)
    a = np.asarray(actions, dtype=np.int64)
    if s.size == 0:
        return float("nan"), float("nan")
    total = float(np.sum(np.asarray(log_pi)[s, a]))
    return total, total / s.size


def _runs_below(acc: np.ndarray, vid: np.ndarray, frame: np.ndarray, thr: float) -> int:
    """Number of maximal runs of consecutive frames per vehicle with ``acc < thr``.

    Inputs sorted by (vid, frame), all ``[N]``.
    """
    below = acc < thr
    if not below.any():
        return 0
    idx = np.flatnonzero(below)
    new = np.ones(idx.size, dtype=bool)
    new[1:] = (vid[idx[1:]] != vid[idx[:-1]]) | (frame[idx[1:]] != frame[idx[:-1]] + 1)
    return int(new.sum())


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
) -> EpisodeMetrics:
    """Metrics of one episode (see the module docstring).

    Args:
        table: the run's trajectory table (NGSIM schema).
        controls: ``Controller.control_table()``; decisions: ``Controller.decision_table()``.
        policy, seed: labels.
        section_length_ft: length of the main road (ft).
        collisions, teleports: whole-run counts (``Controller.n_collisions`` / ``n_teleports``).
        demo_action_counts: ``[5]`` action counts of the demonstrations (for the divergence).
    """
    thr = -config.emergency_decel_m_s2 * FT_PER_M
    t = table.sort_values(["Vehicle_ID", "Frame_ID"], kind="stable")
    vid = t["Vehicle_ID"].to_numpy()
    frm = t["Frame_ID"].to_numpy()
    acc = t["v_Acc"].to_numpy(dtype=np.float64)
    eb_all = _runs_below(acc, vid, frm, thr)
    last_frame = int(frm.max()) if frm.size else 0
    wins = _windows(controls, last_frame)

    # rows of A, B and A's follower inside their windows
    if wins:
        w = pd.DataFrame(wins, columns=["a_id", "b_id", "start", "end"])
        a_rows = t.merge(w[["a_id", "start", "end"]], left_on="Vehicle_ID", right_on="a_id")
        a_rows = a_rows[(a_rows["Frame_ID"] >= a_rows["start"]) & (a_rows["Frame_ID"] <= a_rows["end"])]
        b_rows = t.merge(w[["b_id", "start", "end"]], left_on="Vehicle_ID", right_on="b_id")
        b_rows = b_rows[(b_rows["Frame_ID"] >= b_rows["start"]) & (b_rows["Frame_ID"] <= b_rows["end"])]
        fol_keys = a_rows.loc[a_rows["Following"] > 0, ["Following", "Frame_ID"]].rename(columns={"Following": "fid"})
        f_rows = t.merge(fol_keys.drop_duplicates(), left_on=["Vehicle_ID", "Frame_ID"], right_on=["fid", "Frame_ID"])
        near = pd.concat([a_rows[t.columns], b_rows[t.columns], f_rows[t.columns]])
        near = near.drop_duplicates(["Vehicle_ID", "Frame_ID"]).sort_values(["Vehicle_ID", "Frame_ID"])
        eb_near = _runs_below(near["v_Acc"].to_numpy(float), near["Vehicle_ID"].to_numpy(),
                              near["Frame_ID"].to_numpy(), thr)
        ttc = _min_ttc(t, pd.concat([a_rows[t.columns], f_rows[t.columns]]))
        mean_speed = float(a_rows["v_Vel"].mean()) if len(a_rows) else float("nan")
    else:
        eb_near, ttc, mean_speed = 0, float("inf"), float("nan")

    merged = controls[controls["merge_frame"] >= 0] if len(controls) else controls
    b_ahead = float(np.mean(merged["b_ahead"].astype(bool))) if len(merged) else float("nan")
    tt = _travel_times(t, [x[0] for x in wins], section_length_ft, config.section_margin_ft)
    counts = np.zeros(N_ACTIONS, dtype=np.int64)
    if len(decisions):
        np.add.at(counts, decisions["action"].to_numpy(dtype=np.int64), 1)
    jsd = js_divergence(counts, demo_action_counts) if demo_action_counts is not None else float("nan")
    reasons = controls["reason"].value_counts().to_dict() if len(controls) else {}
    return EpisodeMetrics(
        policy=policy, seed=int(seed), n_controls=int(len(controls)), n_merges=int(len(merged)),
        collisions=int(collisions), a_collisions=int(reasons.get("collision", 0)), teleports=int(teleports),
        emergency_brakings=int(eb_near), emergency_brakings_all=int(eb_all), min_ttc_s=float(ttc),
        b_ahead_rate=b_ahead, travel_time_s=float(np.nanmean(tt)) if np.isfinite(tt).any() else float("nan"),
        mean_speed_A_ft_s=mean_speed, action_counts=tuple(int(x) for x in counts), js_divergence=jsd,
        release_reasons={str(k): int(v) for k, v in reasons.items()},
        n_decisions=int(len(decisions)),
        safety_interventions=int(decisions["filtered"].astype(bool).sum()) if "filtered" in decisions else 0,
    )


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


@dataclass(frozen=True)
class AggregateMetrics:
    """Metrics of one policy over several episodes (seeds).

    Scalars are ``(mean, std)`` over episodes (NaN-aware); counts are totals.
    """

    policy: str
    n_episodes: int
    n_controls: int
    n_merges: int
    collisions: int
    a_collisions: int
    emergency_brakings: int
    emergency_brakings_all: int
    min_ttc_s: float
    b_ahead_rate: tuple[float, float]
    travel_time_s: tuple[float, float]
    mean_speed_A_ft_s: tuple[float, float]
    action_counts: tuple[int, ...]
    js_divergence: float
    heldout_loglik: float = float("nan")
    heldout_loglik_per_step: float = float("nan")
    release_reasons: dict[str, int] = field(default_factory=dict)
    a_collision_rate: float = float("nan")
    a_collision_ci95: tuple[float, float] = (float("nan"), float("nan"))
    n_decisions: int = 0
    safety_interventions: int = 0
    intervention_rate: float = float("nan")
    w1_speed_A_ft_s: float = float("nan")
    w1_acc_A_ft_s2: float = float("nan")
    w1_d_AC_ft: float = float("nan")
    w1_ttc_s: float = float("nan")
    flags: tuple[str, ...] = ()
    flagged: int = 0

    def to_dict(self) -> dict:
        d = asdict(self)
        for k, v in d.items():
            if isinstance(v, tuple):
                d[k] = list(v)
        return d


def _mean_std(x: list[float]) -> tuple[float, float]:
    a = np.asarray(x, dtype=np.float64)
    a = a[np.isfinite(a)]
    if a.size == 0:
        return float("nan"), float("nan")
    return float(a.mean()), float(a.std(ddof=1)) if a.size > 1 else 0.0


def rate_ci95(k: int, n: int) -> tuple[float, float, float]:
    """``(k / n, low, high)``: a rate with its Wilson score 95 % interval (NaN when ``n == 0``)."""
    if n <= 0:
        return float("nan"), float("nan"), float("nan")
    ci = binomtest(int(k), int(n)).proportion_ci(confidence_level=0.95, method="wilson")
    return k / n, float(ci.low), float(ci.high)


def ttc_to_c(d_ac: np.ndarray, v_ac: np.ndarray) -> np.ndarray:
    """``[M]`` front-to-front TTC to C (s), ``d_AC / v_AC`` over the closing steps of ``d_ac,
    v_ac [N]`` (``v_AC > 0``, finite), capped at ``TTC_CAP_S``."""
    d = np.asarray(d_ac, dtype=np.float64)
    v = np.asarray(v_ac, dtype=np.float64)
    ok = np.isfinite(d) & np.isfinite(v) & (v > 1e-6)
    return np.minimum(np.maximum(d[ok], 0.0) / v[ok], TTC_CAP_S)


def wasserstein(x, y) -> float:
    """Wasserstein-1 distance of two samples (finite values only; NaN if either is empty)."""
    a = np.asarray(x, dtype=np.float64)
    b = np.asarray(y, dtype=np.float64)
    a, b = a[np.isfinite(a)], b[np.isfinite(b)]
    if a.size == 0 or b.size == 0:
        return float("nan")
    return float(wasserstein_distance(a, b))


def w1_to_demos(decisions: pd.DataFrame, demos: pd.DataFrame) -> dict[str, float]:
    """Wasserstein-1 distances of the closed-loop decisions (``Controller.decision_table()``
    rows, all episodes) to held-out encounter frames: keys ``w1_speed_A_ft_s`` (needs a
    ``v_A`` column in ``demos``, else NaN), ``w1_acc_A_ft_s2``, ``w1_d_AC_ft``, ``w1_ttc_s``."""
    speed = demos["v_A"] if "v_A" in demos else pd.Series(dtype="float64")
    return {
        "w1_speed_A_ft_s": wasserstein(decisions["speed_A"], speed),
        "w1_acc_A_ft_s2": wasserstein(decisions["acc_cmd"], demos["acc_A"]),
        "w1_d_AC_ft": wasserstein(decisions["d_AC"], demos["d_AC"]),
        "w1_ttc_s": wasserstein(ttc_to_c(decisions["d_AC"], decisions["v_AC"]), ttc_to_c(demos["d_AC"], demos["v_AC"])),
    }


def aggregate(
    episodes: list[EpisodeMetrics],
    *,
    demo_action_counts: np.ndarray | None = None,
    heldout: tuple[float, float] | None = None,
    w1: dict[str, float] | None = None,
    flags: tuple[str, ...] = (),
) -> AggregateMetrics:
    """Aggregate the episodes of one policy (all must share ``policy``); ``w1``: the
    :func:`w1_to_demos` distances of its decisions; ``flags``: its model's fit flags.

    Raises:
        ValueError: no episodes, or episodes of more than one policy.
    """
    if not episodes:
        raise ValueError("aggregate: no episodes")
    names = {e.policy for e in episodes}
    if len(names) != 1:
        raise ValueError(f"aggregate: episodes of several policies {sorted(names)}")
    counts = np.sum([e.action_counts for e in episodes], axis=0)
    reasons: dict[str, int] = {}
    for e in episodes:
        for k, v in e.release_reasons.items():
            reasons[k] = reasons.get(k, 0) + v
    merges = sum(e.n_merges for e in episodes)
    n_controls = sum(e.n_controls for e in episodes)
    a_coll = sum(e.a_collisions for e in episodes)
    rate, lo, hi = rate_ci95(a_coll, n_controls)
    n_dec = sum(e.n_decisions for e in episodes)
    n_int = sum(e.safety_interventions for e in episodes)
    w1 = w1 or {}
    ahead = sum((e.b_ahead_rate * e.n_merges) for e in episodes if e.n_merges)
    return AggregateMetrics(
        policy=episodes[0].policy, n_episodes=len(episodes),
        n_controls=sum(e.n_controls for e in episodes), n_merges=merges,
        collisions=sum(e.collisions for e in episodes), a_collisions=sum(e.a_collisions for e in episodes),
        emergency_brakings=sum(e.emergency_brakings for e in episodes),
        emergency_brakings_all=sum(e.emergency_brakings_all for e in episodes),
        min_ttc_s=float(min(e.min_ttc_s for e in episodes)),
        b_ahead_rate=(ahead / merges if merges else float("nan"), _mean_std([e.b_ahead_rate for e in episodes])[1]),
        travel_time_s=_mean_std([e.travel_time_s for e in episodes]),
        mean_speed_A_ft_s=_mean_std([e.mean_speed_A_ft_s for e in episodes]),
        action_counts=tuple(int(x) for x in counts),
        js_divergence=js_divergence(counts, demo_action_counts) if demo_action_counts is not None else float("nan"),
        heldout_loglik=heldout[0] if heldout else float("nan"),
        heldout_loglik_per_step=heldout[1] if heldout else float("nan"),
        release_reasons=reasons,
        a_collision_rate=rate, a_collision_ci95=(lo, hi), n_decisions=n_dec, safety_interventions=n_int,
        intervention_rate=n_int / n_dec if n_dec else float("nan"),
        w1_speed_A_ft_s=w1.get("w1_speed_A_ft_s", float("nan")), w1_acc_A_ft_s2=w1.get("w1_acc_A_ft_s2", float("nan")),
        w1_d_AC_ft=w1.get("w1_d_AC_ft", float("nan")), w1_ttc_s=w1.get("w1_ttc_s", float("nan")),
        flags=tuple(flags), flagged=int(bool(flags)),
    )
