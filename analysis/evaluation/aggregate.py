"""Closed-loop metrics of one policy aggregated over its episodes (seeds): :func:`~analysis.evaluation.aggregate.aggregate`
of the :class:`~analysis.evaluation.metrics.EpisodeMetrics` of :func:`analysis.evaluation.metrics.episode_metrics`.

Definitions beyond the per-episode ones (:mod:`analysis.evaluation.metrics`):

* ``a_collision_rate`` with ``a_collision_ci95``: A's distinct collision pairs (``a_collisions``)
  over control episodes, with the Wilson score 95 % interval (``scipy.stats.binomtest``).
* ``safety_interventions`` / ``intervention_rate``: decisions whose action the safety filter
  replaced (0 in the raw default), and their share of the commanded decisions.
* ``emergency_braking_rate`` with ``emergency_braking_ci95``: ``emergency_brakings`` (near A) per
  controlled A, with the exact Poisson 95 % interval of the count
  (:func:`~analysis.evaluation.intervals.poisson_rate_ci95`: an A can cause several events);
  ``emergency_brakings_A`` / ``_B`` / ``_follower``: the same events by role (they add up to
  ``emergency_brakings``; the threshold and its tolerance: :class:`~analysis.evaluation.metrics.MetricsConfig`).
* ``a_into_c`` / ``a_into_b``: of ``a_collisions``, those where A ran into its lead car C / into
  the merging car B (:data:`sim.closed_loop.records.COLLISION_KINDS`), counted apart;
  ``a_collision_kinds``: ``a_collisions`` by every kind (they add up to ``a_collisions``).
* ``close_to_c`` / ``close_to_c_rate`` with ``close_to_c_ci95``: the controlled As that came
  closer than 2 m bumper to bumper to their lead car C, their share of the controlled As and its
  Wilson 95 % interval (:mod:`analysis.evaluation.human_likeness`).
* ``flags``: what the model's fit reported (``not_converged``, ``unbounded``, ``infeasible``,
  ``uninformative``) and ``flagged`` (1 if any, for ``--fail-if 'flagged>0'``).

and the distances to the demonstrations of :mod:`analysis.evaluation.distances`
(``js_divergence`` over the summed action counts, ``heldout_loglik``, the ``w1_*`` distances, among
them :mod:`analysis.evaluation.human_likeness`' per-frame ``w1_acc_A_m_s2`` and ``w1_jerk_A_m_s3``).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

from analysis.evaluation.distances import js_divergence
from analysis.evaluation.intervals import poisson_rate_ci95, rate_ci95
from analysis.evaluation.metrics import EpisodeMetrics


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
    need_brakes: int = 0
    w1_speed_A_ft_s: float = float("nan")
    w1_acc_A_ft_s2: float = float("nan")
    w1_d_AC_ft: float = float("nan")
    w1_ttc_s: float = float("nan")
    flags: tuple[str, ...] = ()
    flagged: int = 0
    emergency_braking_rate: float = float("nan")
    emergency_braking_ci95: tuple[float, float] = (float("nan"), float("nan"))
    close_to_c: int = 0
    a_into_c: int = 0
    a_into_b: int = 0
    close_to_c_rate: float = float("nan")
    close_to_c_ci95: tuple[float, float] = (float("nan"), float("nan"))
    w1_acc_A_m_s2: float = float("nan")
    w1_jerk_A_m_s3: float = float("nan")
    emergency_brakings_A: int = 0
    emergency_brakings_B: int = 0
    emergency_brakings_follower: int = 0
    a_collision_kinds: dict[str, int] = field(default_factory=dict)

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


def aggregate(
    episodes: list[EpisodeMetrics],
    *,
    demo_action_counts: np.ndarray | None = None,
    heldout: tuple[float, float] | None = None,
    w1: dict[str, float] | None = None,
    flags: tuple[str, ...] = (),
) -> AggregateMetrics:
    """Aggregate the episodes of one policy (all must share ``policy``); ``w1``: the
    :func:`~analysis.evaluation.distances.w1_to_demos` distances of its decisions and the
    :func:`~analysis.evaluation.human_likeness.w1_acc_jerk` ones of its frames (keys of
    :class:`AggregateMetrics` starting ``w1_``; a missing one is NaN); ``flags``: its model's fit flags.

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
    kinds: dict[str, int] = {}
    for e in episodes:
        for k, v in e.release_reasons.items():
            reasons[k] = reasons.get(k, 0) + v
        for k, v in e.a_collision_kinds.items():
            kinds[k] = kinds.get(k, 0) + v
    merges = sum(e.n_merges for e in episodes)
    n_controls = sum(e.n_controls for e in episodes)
    a_coll = sum(e.a_collisions for e in episodes)
    rate, lo, hi = rate_ci95(a_coll, n_controls)
    n_eb = sum(e.emergency_brakings for e in episodes)
    eb_rate, eb_lo, eb_hi = poisson_rate_ci95(n_eb, n_controls)
    n_close = sum(e.close_to_c for e in episodes)
    close_rate, close_lo, close_hi = rate_ci95(n_close, n_controls)
    n_dec = sum(e.n_decisions for e in episodes)
    n_int = sum(e.safety_interventions for e in episodes)
    w1 = w1 or {}
    ahead = sum((e.b_ahead_rate * e.n_merges) for e in episodes if e.n_merges)
    return AggregateMetrics(
        policy=episodes[0].policy, n_episodes=len(episodes),
        n_controls=sum(e.n_controls for e in episodes), n_merges=merges,
        collisions=sum(e.collisions for e in episodes), a_collisions=sum(e.a_collisions for e in episodes),
        a_into_c=sum(e.a_into_c for e in episodes), a_into_b=sum(e.a_into_b for e in episodes),
        emergency_brakings=n_eb,
        emergency_brakings_A=sum(e.emergency_brakings_A for e in episodes),
        emergency_brakings_B=sum(e.emergency_brakings_B for e in episodes),
        emergency_brakings_follower=sum(e.emergency_brakings_follower for e in episodes),
        emergency_brakings_all=sum(e.emergency_brakings_all for e in episodes),
        min_ttc_s=float(min(e.min_ttc_s for e in episodes)),
        b_ahead_rate=(ahead / merges if merges else float("nan"), _mean_std([e.b_ahead_rate for e in episodes])[1]),
        travel_time_s=_mean_std([e.travel_time_s for e in episodes]),
        mean_speed_A_ft_s=_mean_std([e.mean_speed_A_ft_s for e in episodes]),
        action_counts=tuple(int(x) for x in counts),
        js_divergence=js_divergence(counts, demo_action_counts) if demo_action_counts is not None else float("nan"),
        heldout_loglik=heldout[0] if heldout else float("nan"),
        heldout_loglik_per_step=heldout[1] if heldout else float("nan"),
        release_reasons=reasons, a_collision_kinds=kinds,
        a_collision_rate=rate, a_collision_ci95=(lo, hi), n_decisions=n_dec, safety_interventions=n_int,
        intervention_rate=n_int / n_dec if n_dec else float("nan"),
        need_brakes=sum(e.need_brakes for e in episodes),
        w1_speed_A_ft_s=w1.get("w1_speed_A_ft_s", float("nan")), w1_acc_A_ft_s2=w1.get("w1_acc_A_ft_s2", float("nan")),
        w1_d_AC_ft=w1.get("w1_d_AC_ft", float("nan")), w1_ttc_s=w1.get("w1_ttc_s", float("nan")),
        flags=tuple(flags), flagged=int(bool(flags)),
        emergency_braking_rate=eb_rate, emergency_braking_ci95=(eb_lo, eb_hi),
        close_to_c=n_close, close_to_c_rate=close_rate, close_to_c_ci95=(close_lo, close_hi),
        w1_acc_A_m_s2=w1.get("w1_acc_A_m_s2", float("nan")), w1_jerk_A_m_s3=w1.get("w1_jerk_A_m_s3", float("nan")),
    )
