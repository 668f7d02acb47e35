"""The freeway-merge MDP (paper section 4.2): transitions and tabular demonstrations.

The domain itself (state and action bins, encoding, encounter schema, the no-lead-car rule,
features) is :mod:`irl.domains.merge`; this module builds the MDP from it: tabular
demonstrations from an encounter table (:func:`discretize`), the kinematic fallback model
(:func:`kinematic_next_state`) and the estimated transition model, REIRL's padding, and
readers of the authors' files and of encounter tables.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from irl.demonstrations import Demonstrations
from irl.domains.merge import (
    ACTION_ACC_FT_S2,
    N_ACTIONS,
    N_STATES,
    VARIABLES,
    ZERO_ACTION,
    MergeBins,
    actions_of,
    features,
    state_index,
    state_parts,
    validate_encounters,
)
from irl.errors import ConfigError, DemonstrationError
from irl.io import load_railusm
from irl.transitions import estimate_transitions


def discretize(encounters_df, bins: MergeBins, *, where: str = "encounters") -> Demonstrations:
    """One trajectory per run of rows with one ``encounter_id`` (rows in table order = frame order;
    a new trajectory also starts where ``Frame_ID``, when present, does not increase), so tables
    concatenated from several files keep same-numbered encounters apart.

    Args:
        encounters_df: the encounter table of :mod:`irl.domains.merge` (columns
            ``REQUIRED_COLUMNS``, others ignored); frames without car C follow the domain's
            no-lead-car rule.
        bins: state bin edges.

    Returns:
        Demonstrations over 1250 states and 5 actions with the merge features; trajectories in
        order of first appearance of their encounter id, named ``encounter <id>``.

    Raises:
        DemonstrationError: the table breaks :func:`irl.domains.merge.validate_encounters`.
        EncodingError: (a DemonstrationError) a value the domain cannot encode.
    """
    validate_encounters(encounters_df, where)
    states = bins.encode(encounters_df)
    actions = actions_of(encounters_df["acc_A"].to_numpy(dtype=np.float64))
    ids = encounters_df["encounter_id"].to_numpy()
    # a trajectory is a run of rows with one id (and increasing Frame_ID when present): tables
    # concatenated from several files or runs may reuse ids, and must not be glued together
    brk = np.ones(len(ids), dtype=bool)
    brk[1:] = ids[1:] != ids[:-1]
    if "Frame_ID" in encounters_df.columns and len(ids) > 1:
        fr = encounters_df["Frame_ID"].to_numpy()
        brk[1:] |= fr[1:] <= fr[:-1]
    run = np.cumsum(brk)
    order: dict = {}
    for i, (k, r) in enumerate(zip(ids, run)):
        order.setdefault((k, r), []).append(i)
    return Demonstrations(
        states=tuple(states[idx] for idx in order.values()),
        actions=tuple(actions[idx] for idx in order.values()),
        features=features(),
        n_states=N_STATES,
        n_actions=N_ACTIONS,
        source=where,
        names=tuple(f"encounter {k}" for k, _ in order),
    )


def kinematic_next_state(states, actions, bins: MergeBins, dt: float = 0.1) -> np.ndarray:
    """Next state predicted by constant-acceleration kinematics (the paper's fallback model).

    Takes each state's bin representatives (``MergeBins.representatives``) and the action's
    representative acceleration ``a`` (``ACTION_ACC_FT_S2``), holds them over one decision step ``dt``
    seconds and re-bins. Only A accelerates; B and C keep their speeds, and B's truck flag is
    unchanged:

        v_AC' = v_AC + a dt            v_AB' = v_AB + a dt
        d_AC' = d_AC - v_AC dt - a dt^2 / 2
        d_AB' = d_AB - v_AB dt - a dt^2 / 2

    (``d_AX`` is the gap from A forward to X, so it shrinks when A is faster than X.)

    Args:
        states, actions: integer arrays of equal shape.

    Returns:
        next states, same shape.

    Raises:
        ConfigError: ``dt`` is not positive.
    """
    if not dt > 0:
        raise ConfigError(f"decision step dt must be positive, got {dt}")
    parts = state_parts(states)
    acc = np.asarray(ACTION_ACC_FT_S2)[np.asarray(actions, dtype=np.int64)]
    rep = {name: bins.representatives(name)[parts[..., i + 1]] for i, name in enumerate(VARIABLES)}
    v_ac = rep["v_AC"] + acc * dt
    v_ab = rep["v_AB"] + acc * dt
    d_ac = rep["d_AC"] - rep["v_AC"] * dt - 0.5 * acc * dt * dt
    d_ab = rep["d_AB"] - rep["v_AB"] * dt - 0.5 * acc * dt * dt
    new = [bins.bin_index("d_AC", d_ac), bins.bin_index("d_AB", d_ab),
           bins.bin_index("v_AC", v_ac), bins.bin_index("v_AB", v_ab)]
    return state_index(parts[..., 0], *new).astype(np.int64)


def kinematic_model(bins: MergeBins, dt: float = 0.1) -> np.ndarray:
    """``[1250, 5, 1250]`` deterministic transition model of ``kinematic_next_state``."""
    s = np.repeat(np.arange(N_STATES), N_ACTIONS)
    a = np.tile(np.arange(N_ACTIONS), N_STATES)
    nxt = kinematic_next_state(s, a, bins, dt)
    t = np.zeros((N_STATES, N_ACTIONS, N_STATES))
    t[s, a, nxt] = 1.0
    return t


def estimated_transitions(demos: Demonstrations, bins: MergeBins, dt: float = 0.1) -> np.ndarray:
    """``[1250, 5, 1250]`` relative transition counts of ``demos``, with the kinematic model for
    every (s, a) never observed (the paper's MLIRL model for the merge domain)."""
    return estimate_transitions(demos, fallback=kinematic_model(bins, dt))


@dataclass(frozen=True)
class ConstantVelocityPad:
    """REIRL padding for the merge domain (paper section 4.2): beyond its last frame a trajectory
    continues with A, B and C at constant velocity, i.e. the Zero-acceleration action under the
    kinematic model. Callable ``state -> (next_state, action)``; picklable."""

    bins: MergeBins
    dt: float = 0.1

    def __call__(self, state: int) -> tuple[int, int]:
        return int(kinematic_next_state(np.array([state]), np.array([ZERO_ACTION]), self.bins, self.dt)[0]), ZERO_ACTION


def load(path) -> Demonstrations:
    """Merge trajectories in the authors' text format (their state layout), with the features."""
    return load_railusm(path, n_states=N_STATES, n_actions=N_ACTIONS, features=features())


def read_encounters(path: str | os.PathLike):
    """An encounter table from Parquet (``.parquet``/``.pq``) or CSV (anything else).

    Raises:
        DemonstrationError: the file is missing or unreadable.
    """
    path = Path(path)
    if not path.is_file():
        raise DemonstrationError(f"{path}: no such encounter file")
    try:
        if path.suffix.lower() in (".parquet", ".pq"):
            return pd.read_parquet(path)
        return pd.read_csv(path)
    except Exception as e:  # pandas/pyarrow raise many types for unreadable files
        raise DemonstrationError(f"{path}: cannot read encounter table ({type(e).__name__}: {e})") from None
