"""The recorded drivers as a human reference of a closed-loop evaluation: the real car-following
pairs (:func:`analysis.calibration.pairs.load_pairs`, e.g. NGSIM I-80) beside the drivers of A.

Four distributions, the same definitions on both sides (SI units):

* acceleration (m/s^2) and jerk (m/s^3) **per 0.1 s frame**: the recorded follower's forward
  difference of its speed over one frame, and of that acceleration over one frame, within a
  pair; A's from its speed profiles while controlled
  (:func:`analysis.evaluation.human_likeness.frame_acc_jerk`), as the held-out demonstrations'
  W1 acc/jerk are taken.
* bumper gap to the leader (m) and time headway (s, gap / own speed) **at the decision step**:
  the recorded follower's every ``decision_step_s`` (every third frame at 0.3 s) from each pair's
  first step; A's at its decisions (``d_AC - len_C`` and ``speed_A`` of the decision table,
  ft -> m), only decisions with a lead car C and a known ``len_C``. The time headway counts only
  steps with speed at least :data:`MIN_HEADWAY_SPEED_M_S` (a stopped car has none) and is capped
  at :data:`HEADWAY_CAP_S`.

:func:`recorded_drivers` reads the distributions of the pairs once (the plan does it, before
any episode); :func:`w1_to_recorded` gives a driver's Wasserstein-1 distances to them, and
:func:`driver_summary` / :attr:`RecordedDrivers.summary` the cells both rows of the report show.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from analysis.calibration.pairs import CarFollowingPair
from analysis.evaluation.distances import wasserstein
from analysis.evaluation.human_likeness import CLOSE_GAP_M, frame_acc_jerk
from analysis.evaluation.intervals import rate_ci95
from merge_irl.units import FRAME_S, M_PER_FT

#: Time headways above this (s) are set to it.
HEADWAY_CAP_S = 30.0
#: Slowest speed (m/s) at which a time headway is taken.
MIN_HEADWAY_SPEED_M_S = 1.0
#: The keys of :func:`w1_to_recorded`.
W1_KEYS = ("w1_acc_recorded_m_s2", "w1_jerk_recorded_m_s3", "w1_gap_recorded_m", "w1_headway_recorded_s")


def time_headway(gap_m: np.ndarray, speed_m_s: np.ndarray) -> np.ndarray:
    """``[M]`` time headways (s) ``gap / speed`` of ``gap_m, speed_m_s [N]`` over the finite steps
    with speed >= :data:`MIN_HEADWAY_SPEED_M_S`, capped at :data:`HEADWAY_CAP_S` (a gap <= 0: 0)."""
    g = np.asarray(gap_m, dtype=np.float64)
    v = np.asarray(speed_m_s, dtype=np.float64)
    ok = np.isfinite(g) & np.isfinite(v) & (v >= MIN_HEADWAY_SPEED_M_S)
    return np.minimum(np.maximum(g[ok], 0.0) / v[ok], HEADWAY_CAP_S)


def _frames_per_step(step_s: float) -> int:
    k = int(round(step_s / FRAME_S))
    if k < 1 or abs(k * FRAME_S - step_s) > 1e-6:
        raise ValueError(f"decision step {step_s} s is not a positive multiple of {FRAME_S} s")
    return k


@dataclass(frozen=True)
class RecordedDrivers:
    """The recorded followers' distributions (:func:`recorded_drivers`; see the module docstring).

    Attributes:
        source: the pairs folder.
        n_pairs: pairs read; n_followers: distinct followers (``CarFollowingPair.group``).
        n_close: pairs whose bumper gap fell below ``gap_m`` at a decision step.
        decision_step_s: the step the gaps and headways are sampled at (s).
        acc: float64[M] per-frame acceleration (m/s^2); jerk: float64[K] per-frame jerk (m/s^3).
        gap: float64[G] bumper gap at the decision steps (m); headway: float64[H] time headway (s).
        gap_m: the close threshold (m).
    """

    source: str
    n_pairs: int
    n_followers: int
    n_close: int
    decision_step_s: float
    acc: np.ndarray = field(repr=False)
    jerk: np.ndarray = field(repr=False)
    gap: np.ndarray = field(repr=False)
    headway: np.ndarray = field(repr=False)
    gap_m: float = CLOSE_GAP_M

    @property
    def close_rate(self) -> tuple[float, float, float]:
        """``(share, low, high)``: the share of pairs within ``gap_m`` and its Wilson 95 % interval."""
        return rate_ci95(self.n_close, self.n_pairs)

    @property
    def summary(self) -> dict[str, float]:
        """:func:`summary_of` the recorded distributions."""
        return summary_of(self.acc, self.gap, self.headway)

    def to_dict(self) -> dict:
        """metrics.json's ``recorded_drivers``: counts, the summary and the close share."""
        rate, lo, hi = self.close_rate
        return {"source": self.source, "n_pairs": self.n_pairs, "n_followers": self.n_followers,
                "decision_step_s": self.decision_step_s, "n_acc": int(self.acc.size), "n_jerk": int(self.jerk.size),
                "n_gap": int(self.gap.size), "n_headway": int(self.headway.size), **self.summary,
                "close_gap_m": self.gap_m, "close_pairs": self.n_close, "close_rate": rate,
                "close_ci95": [lo, hi]}


def _pair_samples(pair: CarFollowingPair, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per-frame acceleration and jerk, and the gap and headway every ``k`` frames, of one pair."""
    acc = np.diff(pair.v_follower) / FRAME_S
    jerk = np.diff(acc) / FRAME_S
    gap = pair.spacing[::k]
    return acc, jerk, gap, time_headway(gap, pair.v_follower[::k])


def recorded_drivers(pairs: Sequence[CarFollowingPair], decision_step_s: float, *, source: str = "",
                     gap_m: float = CLOSE_GAP_M) -> RecordedDrivers:
    """The recorded followers' distributions of ``pairs`` (SI, :class:`CarFollowingPair`), gaps
    and headways sampled every ``decision_step_s`` (s).

    Raises:
        ValueError: no pairs, or a decision step that is not a positive multiple of 0.1 s.
    """
    if not pairs:
        raise ValueError("no recorded pairs given")
    k = _frames_per_step(decision_step_s)
    parts = [_pair_samples(p, k) for p in pairs]
    acc, jerk, gap, headway = (np.concatenate([s[i] for s in parts]) for i in range(4))
    n_close = sum(bool((s[2] < gap_m).any()) for s in parts)
    return RecordedDrivers(source, len(pairs), len({p.group for p in pairs}), n_close, float(decision_step_s),
                           acc, jerk, gap, headway, gap_m)


def decision_gap_headway(decisions: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
    """A's bumper gap to C (m, ``[G]``) and time headway (s, ``[H]``, :func:`time_headway`) at its
    decisions (decision-table rows: ``d_AC``, ``len_C``, ``speed_A`` in ft, ft/s); decisions
    without C or ``len_C`` are left out."""
    if decisions.empty or not {"d_AC", "len_C", "speed_A"} <= set(decisions.columns):
        return np.zeros(0), np.zeros(0)
    gap = (decisions["d_AC"].to_numpy(np.float64) - decisions["len_C"].to_numpy(np.float64)) * M_PER_FT
    speed = decisions["speed_A"].to_numpy(np.float64) * M_PER_FT
    ok = np.isfinite(gap)
    return gap[ok], time_headway(gap[ok], speed[ok])


def summary_of(acc: np.ndarray, gap: np.ndarray, headway: np.ndarray) -> dict[str, float]:
    """``mean_abs_acc_m_s2``, ``median_gap_m``, ``median_headway_s`` of the samples (NaN if empty)."""
    def stat(f, x):
        x = np.asarray(x, dtype=np.float64)
        x = x[np.isfinite(x)]
        return float(f(x)) if x.size else float("nan")
    return {"mean_abs_acc_m_s2": stat(lambda x: np.mean(np.abs(x)), acc), "median_gap_m": stat(np.median, gap),
            "median_headway_s": stat(np.median, headway)}


@dataclass(frozen=True)
class DriverVsRecorded:
    """One driver of A beside the recorded drivers: its W1 distances (:data:`W1_KEYS`, NaN where
    a side has no sample) and its own :func:`summary_of`."""

    w1: dict[str, float]
    summary: dict[str, float]

    def to_dict(self) -> dict:
        return {**self.w1, **self.summary}


def w1_to_recorded(profiles: Iterable[pd.DataFrame], decisions: pd.DataFrame,
                   recorded: RecordedDrivers) -> DriverVsRecorded:
    """A driver's Wasserstein-1 distances to the recorded drivers: per-frame acceleration and
    jerk from its episodes' speed ``profiles`` (:func:`frame_acc_jerk`), gap and headway at its
    ``decisions`` (:func:`decision_gap_headway`, all episodes' rows)."""
    acc, jerk = frame_acc_jerk(profiles)
    gap, headway = decision_gap_headway(decisions)
    w1 = dict(zip(W1_KEYS, (wasserstein(acc, recorded.acc), wasserstein(jerk, recorded.jerk),
                            wasserstein(gap, recorded.gap), wasserstein(headway, recorded.headway))))
    return DriverVsRecorded(w1, summary_of(acc, gap, headway))


@dataclass(frozen=True)
class RecordedComparison:
    """Every driver of an evaluation beside the recorded drivers (:func:`compare_to_recorded`).

    Attributes:
        recorded: the recorded drivers' distributions.
        drivers: policy name -> its W1 distances and summary.
    """

    recorded: RecordedDrivers
    drivers: dict[str, DriverVsRecorded]


def compare_to_recorded(recorded: RecordedDrivers, by_policy: dict[str, list]) -> RecordedComparison:
    """:func:`w1_to_recorded` of each policy's episodes (``by_policy``: name -> its
    :class:`~analysis.evaluation.episode.EpisodeResult` list; no episodes: every W1 NaN)."""
    out = {}
    for name, rs in by_policy.items():
        decisions = pd.concat([r.decisions for r in rs], ignore_index=True) if rs else pd.DataFrame()
        out[name] = w1_to_recorded([r.speed_profiles for r in rs], decisions, recorded)
    return RecordedComparison(recorded, out)
