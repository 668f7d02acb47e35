"""Held-out demonstrations of a closed-loop evaluation and every policy's held-out score.

:func:`load_heldout` reads an encounter table (:data:`irl.domains.merge.encounters.ENCOUNTER_SCHEMA`)
as :class:`HeldOut`; :func:`policy_heldout_loglik` scores a policy on it as learning sees the
demonstrations (resampled at the decision step). Used by :func:`analysis.evaluation.evaluate.evaluate`.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np
import pandas as pd

from analysis.evaluation.distances import heldout_loglik
from irl.domains.merge.actions import N_ACTIONS, actions_of
from irl.domains.merge.bins import MergeBins
from irl.domains.merge.car_following import CFDecisions, car_following_decisions
from irl.domains.merge.encounters import REQUIRED_COLUMNS
from irl.errors import DemonstrationError
from irl.domains.merge.mdp import discretize, read_encounters
from sim.idm_policy import IdmPolicy
from sim.observe import MergeObservation
from sim.policy import BaselineTabularPolicy, CarFollowingLogitPolicy, LearnedPolicy, Policy


@dataclass(frozen=True)
class HeldOut:
    """Demonstrations used for the divergence and the held-out log-likelihood.

    Attributes:
        encounters: encounter frames (``irl.domains.merge.encounters.ENCOUNTER_SCHEMA``; NaN d_AC and
            v_AC = no lead car, encoded by the domain's no-lead-car rule).
        action_counts: ``[5]`` counts of the binned ``acc_A``.
        source: where they came from.
    """

    encounters: pd.DataFrame
    action_counts: np.ndarray
    source: str = ""


def prepare_encounters(frames: pd.DataFrame, where: str = "encounters") -> pd.DataFrame:
    """Encounter frames ready to discretize: rows with A, B and an action only (frames without
    car C stay, with d_AC and v_AC NaN: the domain's no-lead-car rule encodes them).

    Raises:
        DemonstrationError: a column of :data:`irl.domains.merge.encounters.REQUIRED_COLUMNS` is
            missing (``where`` names the table).
    """
    missing = [c for c in REQUIRED_COLUMNS if c not in frames.columns]
    if missing:
        raise DemonstrationError(f"{where}: encounter table lacks column(s) {missing}; expected {list(REQUIRED_COLUMNS)} "
                                 "(an encounters.parquet of 'merge-irl generate' or 'merge-irl encounters')")
    df = frames.copy()
    df = df[np.isfinite(df["d_AB"]) & np.isfinite(df["v_AB"]) & np.isfinite(df["acc_A"])]
    return df.reset_index(drop=True)


def load_heldout(demos: str | os.PathLike | pd.DataFrame) -> HeldOut:
    """Held-out demonstrations from an encounter table (Parquet/CSV path or DataFrame)."""
    if isinstance(demos, pd.DataFrame):
        df, src = demos, "encounters"
    else:
        df, src = read_encounters(demos), str(demos)
    df = prepare_encounters(df, src)
    counts = np.bincount(actions_of(df["acc_A"].to_numpy(float)), minlength=N_ACTIONS)
    return HeldOut(df, counts.astype(np.int64), src)


def policy_heldout_loglik(policy: Policy, heldout: HeldOut, decision_step_s: float = 0.1, *,
                          cf_decisions: CFDecisions | None = None) -> tuple[float, float]:
    """``(sum, per step)`` state-conditional log-likelihood of the held-out demonstrations under
    ``policy`` (NaN for SUMO), scored as learning sees them: resampled at the decision step
    (:func:`irl.domains.merge.mdp.discretize`; a learned policy at its model's ``decision_step_s`` and
    state encoding, every other policy at ``decision_step_s``), so an action is the forward
    difference of A's speed over one decision. ``markov`` scores a trajectory's first step by
    its marginal. ``cf_decisions``: the held-out decisions of a car-following driver when
    already taken (:func:`~irl.domains.merge.car_following.car_following_decisions` at its step).
    NaN for the deterministic IDM reference driver as well (no likelihood to speak of)."""
    if not policy.controls or isinstance(policy, IdmPolicy):
        return float("nan"), float("nan")
    df = heldout.encounters
    if isinstance(policy, CarFollowingLogitPolicy):
        dec = cf_decisions if cf_decisions is not None else car_following_decisions(
            df, decision_step_s=policy.decision_step_s, where=heldout.source)
        total = policy.model.loglik_of(dec)
        return total, total / dec.n
    if isinstance(policy, LearnedPolicy):
        d = discretize(df, policy.encoder, where=heldout.source, encoding=policy.state_encoding,
                       decision_step_s=policy.decision_step_s)
        s, a, _ = d.flat()
        return heldout_loglik(policy.log_pi, s, a)
    bins = policy.encoder if isinstance(policy, BaselineTabularPolicy) else MergeBins.assumed_authors()
    d = discretize(df, bins, where=heldout.source, decision_step_s=decision_step_s)
    n = sum(len(x) for x in d.actions)
    if isinstance(policy, BaselineTabularPolicy):
        total = float(policy.baseline.loglik(d))
        return total, total / n if n else float("nan")
    # state-independent policies (uniform, constant): log p(a)
    _, actions, _ = d.flat()
    p = np.asarray(policy.probs(MergeObservation(0, 0, 0, 0, False, 0)), dtype=float)
    with np.errstate(divide="ignore"):
        lp = np.log(p)[actions]
    return float(lp.sum()), float(lp.mean()) if lp.size else float("nan")
