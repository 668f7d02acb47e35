"""The planner's decisions: continuous observations, the continuous acceleration held before
and during each decision, C's estimated acceleration, the paper action, and the group (encounter
or car-following pair) each decision belongs to.

Two builders, one contract (units ft, ft/s, ft/s^2; observation columns
:data:`~irl.domains.merge.car_following.OBS_COLUMNS`):

* :func:`encounter_decisions`: the rows of an encounter table that learning uses elsewhere
  (:func:`irl.domains.merge.car_following.car_following_decisions`, i.e.
  :func:`irl.domains.merge.mdp.resample_encounters` with the driver encoding);
* :func:`pair_decisions`: real leader-follower pairs (arrays; reading the files is
  :func:`analysis.calibration.pairs.load_pairs`' job), C the recorded leader, no B.
"""

from __future__ import annotations

import warnings
from collections.abc import Hashable, Sequence
from dataclasses import dataclass, fields

import numpy as np
import pandas as pd

from irl.domains.merge.actions import N_ACTIONS, actions_of
from irl.domains.merge.bins import MergeBins
from irl.domains.merge.car_following import OBS_COLUMNS, car_following_decisions
from irl.domains.merge.mdp import (
    DEFAULT_DECISION_STEP_S,
    FrameGapWarning,
    ShortEncounterWarning,
    encounter_runs,
    frames_per_step,
    resample_encounters,
)
from irl.errors import DemonstrationError
from merge_irl.units import FRAME_S

#: Columns a pair table must have (ft, ft/s, s; 0.1 s rows).
PAIR_COLUMNS = ("t", "x_follower", "v_follower", "x_leader", "v_leader", "leader_length")


@dataclass(frozen=True)
class PlanningDecisions:
    """``N`` decisions of the planning driver.

    Attributes:
        obs: ``[N, 7]`` float64, ``d_AC, v_AC, d_AB, v_AB, v_A, len_C, len_B`` (ft, ft/s; NaN for
            C when there is none; a length NaN: unknown).
        prev_acc: ``[N]`` the continuous acceleration A held over the previous decision (its
            forward speed difference over the step, ft/s^2; NaN unknown, used as 0).
        acc_C: ``[N]`` C's acceleration from its speed change over the previous decision
            (ft/s^2; 0 when unknown or C changed).
        actions: ``[N]`` int64, the paper action (bin of ``acc``).
        acc: ``[N]`` the decision's continuous acceleration (forward difference of A's speed
            over the step, ft/s^2).
        groups: ``[N]`` int64, the encounter / pair each decision belongs to (splits keep a
            group together).
        decision_step_s: seconds per decision.

    Raises:
        DemonstrationError: arrays of the wrong shape, or actions that are not the bins of ``acc``.
    """

    obs: np.ndarray
    prev_acc: np.ndarray
    acc_C: np.ndarray
    actions: np.ndarray
    acc: np.ndarray
    groups: np.ndarray
    decision_step_s: float = DEFAULT_DECISION_STEP_S

    def __post_init__(self) -> None:
        obs = np.asarray(self.obs, dtype=np.float64).reshape(-1, len(OBS_COLUMNS))
        object.__setattr__(self, "obs", obs)
        n = obs.shape[0]
        for name, dtype in (("prev_acc", np.float64), ("acc_C", np.float64), ("actions", np.int64),
                            ("acc", np.float64), ("groups", np.int64)):
            x = np.asarray(getattr(self, name)).astype(dtype)
            if x.shape != (n,):
                raise DemonstrationError(f"PlanningDecisions: {name} must be [{n}], got {x.shape}")
            object.__setattr__(self, name, x)
        if not np.array_equal(actions_of(self.acc), self.actions):
            raise DemonstrationError("PlanningDecisions: actions must be the paper bins of acc")
        frames_per_step(self.decision_step_s)

    @property
    def n(self) -> int:
        """The number of decisions ``N``."""
        return int(self.actions.size)

    def take(self, idx: np.ndarray) -> PlanningDecisions:
        """The decisions ``idx`` (int indices or a bool mask)."""
        return PlanningDecisions(self.obs[idx], self.prev_acc[idx], self.acc_C[idx], self.actions[idx],
                                 self.acc[idx], self.groups[idx], self.decision_step_s)

    @staticmethod
    def concat(parts: Sequence[PlanningDecisions]) -> PlanningDecisions:
        """One set of decisions; each part's groups numbered apart from the others'.

        Raises:
            DemonstrationError: no parts, or parts of different decision steps.
        """
        if not parts or len({p.decision_step_s for p in parts}) != 1:
            raise DemonstrationError("PlanningDecisions.concat: needs one or more parts of one decision step")
        off, groups = 0, []
        for p in parts:
            groups.append(p.groups + off)
            off += int(p.groups.max()) + 1 if p.n else 0
        arrays = {f.name: np.concatenate([getattr(p, f.name) for p in parts])
                  for f in fields(PlanningDecisions) if f.name not in ("groups", "decision_step_s")}
        return PlanningDecisions(**arrays, groups=np.concatenate(groups), decision_step_s=parts[0].decision_step_s)

    def action_acc_ft_s2(self) -> tuple[float, ...]:
        """``[5]`` mean ``acc`` of each paper action's decisions (the bin midpoint where none)."""
        mids = (-8.0, -2.7, 0.0, 2.7, 8.0)
        return tuple(float(self.acc[self.actions == a].mean()) if (self.actions == a).any() else mids[a]
                     for a in range(N_ACTIONS))


def encounter_decisions(df: pd.DataFrame, decision_step_s: float = DEFAULT_DECISION_STEP_S, *,
                        where: str = "encounters") -> PlanningDecisions:
    """Decisions of an encounter table (:mod:`irl.domains.merge.encounters`), exactly the rows
    of :func:`~irl.domains.merge.car_following.car_following_decisions`.

    With ``k`` frames per decision and row ``r`` a decision: ``acc`` is the mean of ``acc_A``
    over rows ``r .. r+k-1``; ``prev_acc`` over ``r-k .. r-1`` when those rows are the same
    encounter run (:func:`~irl.domains.merge.mdp.encounter_runs`: consecutive frames; else
    NaN); ``acc_C = (v_C(r) - v_C(r-k)) / (k 0.1 s)``, ``v_C = v_A - v_AC``, when row ``r-k``
    is the same run with the same ``C_id`` (a table without ``C_id``: the same run) and both
    speeds are known, else 0. Groups: the encounter runs.

    Raises:
        DemonstrationError: what ``car_following_decisions`` raises (``where`` named).
        ConfigError: a bad decision step.
    """
    cf = car_following_decisions(df, decision_step_s=decision_step_s, where=where)
    with warnings.catch_warnings():  # car_following_decisions said it already (the same rows)
        warnings.simplefilter("ignore", FrameGapWarning)
        warnings.simplefilter("ignore", ShortEncounterWarning)
        rows = resample_encounters(df, MergeBins.assumed_authors(), where=where, encoding="driver",
                                   decision_step_s=decision_step_s).rows
    k = frames_per_step(decision_step_s)
    acc_A = df["acc_A"].to_numpy(np.float64)
    run = encounter_runs(df).run  # consecutive frames of one encounter: a step never spans a gap
    csum = np.concatenate([[0.0], np.cumsum(acc_A)])
    acc = (csum[rows + k] - csum[rows]) / k
    back = np.maximum(rows - k, 0)
    same = (rows >= k) & (run[back] == run[rows])
    prev_acc = np.where(same, (csum[np.maximum(rows, k)] - csum[back]) / k, np.nan)
    cid = df["C_id"].to_numpy() if "C_id" in df.columns else np.zeros(len(df))
    v_C = df["v_A"].to_numpy(np.float64) - pd.to_numeric(df["v_AC"], errors="coerce").to_numpy(np.float64)
    ok = same & (cid[back] == cid[rows]) & np.isfinite(v_C[back]) & np.isfinite(v_C[rows])
    acc_C = np.where(ok, (np.where(ok, v_C[rows], 0.0) - np.where(ok, v_C[back], 0.0)) / (k * FRAME_S), 0.0)
    _, groups = np.unique(run[rows], return_inverse=True)
    out = PlanningDecisions(cf.obs, prev_acc, acc_C, actions_of(acc), acc, groups, float(decision_step_s))
    if not np.array_equal(out.actions, cf.actions):  # the same rows and steps as learning elsewhere
        raise DemonstrationError(f"{where}: step accelerations do not reproduce the resampled actions")
    return out


def pair_decisions(frames: Sequence[pd.DataFrame], decision_step_s: float = DEFAULT_DECISION_STEP_S, *,
                   groups: Sequence[Hashable] | None = None, where: str = "pairs") -> PlanningDecisions:
    """Decisions of car-following pairs, one table per pair (columns :data:`PAIR_COLUMNS`, ft,
    ft/s, uniform 0.1 s rows), C the recorded leader and no B.

    Decisions every ``k`` rows from row ``k`` (so the previous step is known) while a whole
    step follows: ``d_AC = x_leader - x_follower``, ``v_AC = v_follower - v_leader``, ``v_A =
    v_follower``, ``len_C = leader_length``; ``acc = (v_f(t+k) - v_f(t)) / (k 0.1)``,
    ``prev_acc = (v_f(t) - v_f(t-k)) / (k 0.1)``, ``acc_C = (v_l(t) - v_l(t-k)) / (k 0.1)``.

    Args:
        frames: the pair tables; decision_step_s: seconds per decision;
        groups: one label per table (e.g. the follower; tables of one label form one group),
            None: each table its own group; where: named in errors.

    Raises:
        DemonstrationError: no tables, a missing column, a value that is not a finite number,
            a negative speed, non-uniform 0.1 s steps, groups of the wrong length, or no table
            long enough for one decision (table and column named).
    """
    k = frames_per_step(decision_step_s)
    h = k * FRAME_S
    if len(frames) == 0:
        raise DemonstrationError(f"{where}: no pair tables")
    if groups is not None and len(groups) != len(frames):
        raise DemonstrationError(f"{where}: {len(groups)} group labels for {len(frames)} tables")
    labels = list(range(len(frames))) if groups is None else list(groups)
    codes = {g: i for i, g in enumerate(dict.fromkeys(labels))}
    parts = []
    for i, df in enumerate(frames):
        missing = [c for c in PAIR_COLUMNS if c not in df.columns]
        if missing:
            raise DemonstrationError(f"{where}: table {i}: missing column(s) {missing}; a pair table needs "
                                     f"{list(PAIR_COLUMNS)} (ft, ft/s)")
        a = {c: pd.to_numeric(df[c], errors="coerce").to_numpy(np.float64) for c in PAIR_COLUMNS}
        for c, x in a.items():
            bad = ~np.isfinite(x) | ((x < 0) if c in ("v_follower", "v_leader") else False)
            if c == "leader_length":
                bad |= ~(x > 0)
            if bad.any():
                j = int(np.argmax(bad))
                raise DemonstrationError(f"{where}: table {i}, row {j}, column {c!r}: expected a finite number"
                                         f"{' >= 0' if c.startswith('v_') else ' > 0' if c == 'leader_length' else ''}"
                                         f", got {df[c].iloc[j]!r}")
        if a["t"].size > 1 and np.abs(np.diff(a["t"]) - FRAME_S).max() > 1e-6:
            raise DemonstrationError(f"{where}: table {i}, column 't': rows must be {FRAME_S} s apart")
        t = np.arange(k, a["t"].size - k, k)
        if t.size == 0:
            continue
        xf, vf, xl, vl, ln = a["x_follower"], a["v_follower"], a["x_leader"], a["v_leader"], a["leader_length"]
        nan = np.full(t.size, np.nan)
        obs = np.column_stack([xl[t] - xf[t], vf[t] - vl[t], nan, nan, vf[t], ln[t], nan])
        acc = (vf[t + k] - vf[t]) / h
        parts.append(PlanningDecisions(obs, (vf[t] - vf[t - k]) / h, (vl[t] - vl[t - k]) / h, actions_of(acc), acc,
                                       np.full(t.size, codes[labels[i]]), float(decision_step_s)))
    if not parts:
        raise DemonstrationError(f"{where}: no table has the {2 * k + 1} rows one decision needs")
    arrays = {f.name: np.concatenate([getattr(p, f.name) for p in parts])
              for f in fields(PlanningDecisions) if f.name != "decision_step_s"}
    return PlanningDecisions(**arrays, decision_step_s=float(decision_step_s))


def split_groups(groups: np.ndarray, test_fraction: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """``(train_mask, test_mask)`` over decisions: ``round(test_fraction G)`` (at least 1) of the
    ``G`` groups drawn for test with ``numpy.random.default_rng(seed)``.

    Raises:
        DemonstrationError: fewer than 2 groups, or ``test_fraction`` not in (0, 1).
    """
    u = np.unique(groups)
    if u.size < 2 or not 0 < test_fraction < 1:
        raise DemonstrationError(f"split_groups: needs 2 or more groups and a fraction in (0, 1), got {u.size} "
                                 f"groups and {test_fraction}")
    rng = np.random.default_rng(seed)
    n_test = min(u.size - 1, max(1, int(round(test_fraction * u.size))))
    te = np.isin(groups, rng.choice(u, size=n_test, replace=False))
    return ~te, te
