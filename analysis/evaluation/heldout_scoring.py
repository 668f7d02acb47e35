"""Held-out demonstrations of a closed-loop evaluation and every policy's held-out score.

:func:`load_heldout` reads an encounter table (:data:`irl.domains.merge.encounters.ENCOUNTER_SCHEMA`)
as :class:`HeldOut`; :func:`policy_heldout_loglik` scores a policy on it by the policy's own
:meth:`~sim.drivers.policy.Policy.heldout_loglik` (as learning sees the demonstrations: resampled at the
decision step). Used by :func:`analysis.evaluation.evaluate.evaluate`.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from irl.domains.merge.actions import N_ACTIONS, actions_of
from irl.domains.merge.encounters import prepare_encounters
from irl.domains.merge.mdp import DEFAULT_DECISION_STEP_S, read_encounters
from sim.drivers.policy import Policy, check_policy


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


def load_heldout(demos: str | os.PathLike | pd.DataFrame | Sequence[str | os.PathLike]) -> HeldOut:
    """Held-out demonstrations from an encounter table (Parquet/CSV path or DataFrame), or from
    several tables read as one set (a sequence of paths: each table's ``encounter_id`` offset past
    the previous tables', so encounters of different files stay apart).

    Raises:
        DemonstrationError: a table cannot be read or lacks columns (the file named).
    """
    if isinstance(demos, pd.DataFrame):
        df, src = demos, "encounters"
    elif isinstance(demos, (str, os.PathLike)):
        df, src = read_encounters(demos), str(demos)
    else:
        df, src = _merged_tables(demos), ", ".join(str(p) for p in demos)
    df = prepare_encounters(df, src)
    counts = np.bincount(actions_of(df["acc_A"].to_numpy(float)), minlength=N_ACTIONS)
    return HeldOut(df, counts.astype(np.int64), src)


def _merged_tables(paths: Sequence[str | os.PathLike]) -> pd.DataFrame:
    """The encounter tables of ``paths`` as one, ``encounter_id`` offset per table."""
    frames, offset = [], 0
    for path in paths:
        df = prepare_encounters(read_encounters(path), str(path)).copy()
        df["encounter_id"] = df["encounter_id"].astype("int64") + offset
        offset = int(df["encounter_id"].max()) + 1 if len(df) else offset
        frames.append(df)
    return pd.concat(frames, ignore_index=True)


def policy_heldout_loglik(policy: Policy, heldout: HeldOut, decision_step_s: float = DEFAULT_DECISION_STEP_S, *,
                          cache: dict | None = None) -> tuple[float, float]:
    """``(sum, per step)`` log-likelihood of the held-out demonstrations under ``policy``: the
    policy's own :meth:`~sim.drivers.policy.Policy.heldout_loglik` at the evaluation's
    ``decision_step_s`` (NaN, NaN where it has no likelihood, as SUMO's driver and the IDM
    reference), with the extra inputs its optional ``heldout_inputs`` prepares (``cache``: one
    dict shared by the policies scored on ``heldout``, so shared work is done once).

    Raises:
        PolicyError: ``policy`` does not implement ``heldout_loglik`` (the class named): a
            number from a guess at its kind would be silently wrong.
        DemonstrationError: the held-out frames cannot be scored.
    """
    check_policy(policy, where="held-out scoring")
    prepare = getattr(policy, "heldout_inputs", None)
    extra = prepare(heldout.encounters, where=heldout.source, cache={} if cache is None else cache) \
        if prepare is not None else {}
    return policy.heldout_loglik(heldout.encounters, decision_step_s=decision_step_s, where=heldout.source, **extra)
