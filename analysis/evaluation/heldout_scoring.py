"""Held-out demonstrations of a closed-loop evaluation and every policy's held-out score.

:func:`load_heldout` reads an encounter table (:data:`irl.domains.merge.encounters.ENCOUNTER_SCHEMA`)
as :class:`HeldOut`; :func:`policy_heldout_loglik` scores a policy on it by the policy's own
:meth:`~sim.drivers.policy.Policy.heldout_loglik` (as learning sees the demonstrations: resampled at the
decision step). Used by :func:`analysis.evaluation.evaluate.evaluate`.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np
import pandas as pd

from irl.domains.merge.actions import N_ACTIONS, actions_of
from irl.domains.merge.car_following import CFDecisions
from irl.domains.merge.encounters import REQUIRED_COLUMNS
from irl.errors import DemonstrationError
from irl.domains.merge.mdp import DEFAULT_DECISION_STEP_S, read_encounters
from sim.drivers.policy import Policy, check_policy
from sim.drivers.learned import CarFollowingLogitPolicy


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


def policy_heldout_loglik(policy: Policy, heldout: HeldOut, decision_step_s: float = DEFAULT_DECISION_STEP_S, *,
                          cf_decisions: CFDecisions | None = None) -> tuple[float, float]:
    """``(sum, per step)`` log-likelihood of the held-out demonstrations under ``policy``: the
    policy's own :meth:`~sim.drivers.policy.Policy.heldout_loglik` at the evaluation's
    ``decision_step_s`` (NaN, NaN where it has no likelihood, as SUMO's driver and the IDM
    reference). ``cf_decisions``: the held-out decisions of a car-following driver when already
    taken (:func:`~irl.domains.merge.car_following.car_following_decisions` at its step).

    Raises:
        PolicyError: ``policy`` does not implement ``heldout_loglik`` (the class named): a
            number from a guess at its kind would be silently wrong.
        DemonstrationError: the held-out frames cannot be scored.
    """
    check_policy(policy, where="held-out scoring")
    if cf_decisions is not None and isinstance(policy, CarFollowingLogitPolicy):
        return policy.heldout_loglik(heldout.encounters, decision_step_s=decision_step_s, where=heldout.source,
                                     cf_decisions=cf_decisions)
    return policy.heldout_loglik(heldout.encounters, decision_step_s=decision_step_s, where=heldout.source)
