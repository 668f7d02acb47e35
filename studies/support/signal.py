"""How much signal a demonstrator gives: how often A's action bin changes between decisions.

Krauss drivers with sigma 0.5 change action bin in 63 % of 0.1 s frames and
sit at the braking cap in 11 %; the authors' NGSIM humans change bin in 26 % of frames. A
learner cannot tell such noise from a response to the state.

:func:`bin_change_rate` measures it on an encounter table (``irl.domains.merge.encounters`` schema):
the share of consecutive decision pairs of the same encounter whose action bins differ, at a
decision step of ``step_frames`` 0.1 s frames (the action over a step is the mean of the
per-frame ``acc_A`` over it: A's speed change over the step divided by its length).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from irl.domains.merge.actions import ACTION_ACC_FT_S2, actions_of


def step_actions(frames: pd.DataFrame, step_frames: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """``(actions [M], encounter ids [M])`` at one decision every ``step_frames`` frames.

    Each encounter's rows (consecutive, in frame order) are cut into whole blocks of
    ``step_frames`` rows; a block's action is the bin of the mean ``acc_A`` of its rows.

    Raises:
        ValueError: ``step_frames < 1``.
    """
    if step_frames < 1:
        raise ValueError(f"step_frames must be >= 1, got {step_frames}")
    acc = frames["acc_A"].to_numpy(np.float64)
    eid = frames["encounter_id"].to_numpy()
    pos = frames.groupby("encounter_id", sort=False).cumcount().to_numpy()
    block = pos // step_frames
    df = pd.DataFrame({"e": eid, "b": block, "acc": acc})
    full = df.groupby(["e", "b"], sort=False)["acc"].agg(["mean", "size"])
    full = full[full["size"] == step_frames]
    return actions_of(full["mean"].to_numpy()), full.index.get_level_values(0).to_numpy()


def bin_change_rate(frames: pd.DataFrame, step_frames: int = 1) -> float:
    """Share of consecutive decisions (same encounter) whose action bin changes (NaN: no pair)."""
    a, e = step_actions(frames, step_frames)
    same = e[1:] == e[:-1]
    if not same.any():
        return float("nan")
    return float(np.mean(a[1:][same] != a[:-1][same]))


def braking_cap_share(frames: pd.DataFrame, cap_ft_s2: float | None = None) -> float:
    """Share of frames whose ``acc_A`` is at or below ``cap_ft_s2`` (default: 1.5 x the High
    Brake midpoint, i.e. about SUMO's passenger-car ``decel``)."""
    cap = 1.5 * float(ACTION_ACC_FT_S2[0]) if cap_ft_s2 is None else cap_ft_s2
    acc = frames["acc_A"].to_numpy(np.float64)
    return float(np.mean(acc <= cap)) if acc.size else float("nan")
