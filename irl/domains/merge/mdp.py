"""The freeway-merge MDP (paper section 4.2): transitions and tabular demonstrations.

The domain itself (state and action bins, encoding, encounter schema, the no-lead-car rule,
features) is :mod:`irl.domains` (``merge_actions``, ``merge_states``, ``merge_bins``,
``merge_encounters``, ``merge_features``); this module builds the MDP from it: tabular
demonstrations from an encounter table (:func:`discretize`), the kinematic fallback model
(:func:`kinematic_next_state`) and the estimated transition model, REIRL's padding, and
readers of the authors' files and of encounter tables.
"""

from __future__ import annotations

import math
import os
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import scipy.sparse as sp

from irl.demonstrations import Demonstrations
from irl.domains.merge.actions import ACTION_ACC_FT_S2, N_ACTIONS, ZERO_ACTION, actions_of
from irl.domains.merge.bins import MergeBins
from irl.domains.merge.encounters import validate_encounters
from irl.domains.merge.features import driver_encode_sequence, feature_set, features
from irl.domains.merge.states import N_STATES, VARIABLES, n_states, split_driver_state, state_index, state_parts
from irl.errors import ConfigError, DemonstrationError
from irl.io import load_text_trajectories
from irl.transitions import SuccessorModel, estimate_transitions
from merge_irl.tables import is_parquet_dataset, read_table
from merge_irl.units import FRAME_S

#: Default decision step (s) at which merge demonstrations are resampled: the controller's.
DEFAULT_DECISION_STEP_S = 0.3


@dataclass(frozen=True)
class Discretized:
    """What :func:`discretize` returns.

    Attributes:
        demos: the tabular demonstrations.
        action_acc_ft_s2: ``[5]`` mean acceleration (ft/s^2) of the decisions of each action;
            the bin midpoint (``ACTION_ACC_FT_S2``) for an action that never occurs.
        rows: ``[N]`` int64, the row position (``iloc``) in the encounter table of each
            decision, in the order of ``demos.flat()``: the frame whose continuous variables
            the decision's state encodes (e.g. for :mod:`irl.domains.merge.car_following`).
        gaps: gaps (missing frames within an encounter) at which encounters were split.
        gap_rows_dropped: rows left out in parts between gaps shorter than one decision step.
    """

    demos: Demonstrations
    action_acc_ft_s2: tuple[float, ...]
    rows: np.ndarray
    gaps: int = 0
    gap_rows_dropped: int = 0


def action_mean_acc(acc, actions) -> tuple[float, ...]:
    """``[5]`` conditional mean of ``acc`` (ft/s^2) per action; bin midpoint where absent."""
    acc = np.asarray(acc, dtype=np.float64)
    actions = np.asarray(actions, dtype=np.int64)
    out = []
    for a in range(N_ACTIONS):
        sel = acc[actions == a]
        out.append(float(sel.mean()) if sel.size else float(ACTION_ACC_FT_S2[a]))
    return tuple(out)


def frames_per_step(decision_step_s: float) -> int:
    """The number of 0.1 s frames in one decision step.

    Raises:
        ConfigError: ``decision_step_s`` is not a positive finite multiple of the frame (0.1 s).
    """
    ok = isinstance(decision_step_s, (int, float)) and not isinstance(decision_step_s, bool) \
        and math.isfinite(decision_step_s) and decision_step_s > 0
    k = int(round(decision_step_s / FRAME_S)) if ok else 0
    if k < 1 or abs(k * FRAME_S - decision_step_s) > 1e-9:
        raise ConfigError(f"decision_step_s must be a positive multiple of {FRAME_S} s, got {decision_step_s}")
    return k


def discretize(encounters_df, bins: MergeBins, *, where: str = "encounters", encoding: str = "paper",
               decision_step_s: float = DEFAULT_DECISION_STEP_S, features=None) -> Demonstrations:
    """The demonstrations of :func:`resample_encounters` (same arguments and errors)."""
    return resample_encounters(encounters_df, bins, where=where, encoding=encoding,
                               decision_step_s=decision_step_s, features=features).demos


def resample_encounters(encounters_df, bins: MergeBins, *, where: str = "encounters", encoding: str = "paper",
                        decision_step_s: float = DEFAULT_DECISION_STEP_S, features=None) -> Discretized:
    """Resample each encounter at the decision step and encode it, as the closed-loop controller decides.

    Resampled by time: one trajectory per run of consecutive frames of an ``encounter_id``
    (:func:`encounter_runs`; rows in table order = frame order). Where frames are missing
    (a recording's gap: ``Frame_ID`` jumps within an encounter) the encounter is split into
    trajectories named ``encounter <id> from frame <f> (after <m> missing frames)``, so that
    no decision step and no transition spans the gap; the splits are counted in
    :class:`Discretized` and said in one :class:`FrameGapWarning`. A table without gaps gives
    exactly what row-by-row resampling gives. With ``k = decision_step_s / 0.1 s`` frames per
    decision, decision ``j`` of a run is its row ``j k`` (the state at that frame); its action
    is the forward difference of A's speed over the step, ``(v_A(t + k) - v_A(t)) / (k 0.1
    s)``, i.e. the mean of ``acc_A`` over rows ``t .. t+k-1`` (each row's ``acc_A`` is a
    one-frame forward difference). An incomplete last step is dropped. With the ``"driver"``
    encoding the first decision of a run is row ``k`` so that its previous action (the step
    over rows ``0 .. k-1``) comes from A's speed history; a run shorter than ``2k`` rows keeps
    row 0 with previous action Zero (unknown).

    Args:
        encounters_df: the encounter table of :mod:`irl.domains.merge.encounters`.
        bins: state bin edges.
        encoding: ``"paper"`` or ``"driver"`` (:data:`irl.domains.merge.states.STATE_ENCODINGS`).
        decision_step_s: seconds per decision, a multiple of 0.1 (0.1 keeps every frame).
        features: a :class:`~irl.domains.merge.features.FeatureSet` (``[S, A, K]``), a set name
            or None (the paper's three).

    Returns:
        :class:`Discretized`: demonstrations over ``n_states(encoding)`` states and 5 actions,
        trajectories in order of first appearance, named ``encounter <id>``; and the per-action
        mean acceleration of the decisions.

    Raises:
        DemonstrationError: the table breaks :func:`irl.domains.merge.encounters.validate_encounters`, or
            every encounter has fewer than ``k`` rows (no whole decision step). Shorter
            encounters among longer ones are left out with a :class:`ShortEncounterWarning`.
        ConfigError: a bad encoding or decision step.
    """
    validate_encounters(encounters_df, where)
    k = frames_per_step(decision_step_s)
    S = n_states(encoding)
    fs = feature_set(features or "paper", bins, encoding, decision_step_s=decision_step_s)
    if fs.array.shape[0] != S:
        raise ConfigError(f"features have {fs.array.shape[0]} states, the {encoding!r} encoding {S}")
    paper_states = bins.encode(encounters_df)
    acc = encounters_df["acc_A"].to_numpy(dtype=np.float64)
    ids = encounters_df["encounter_id"].to_numpy()
    runs = encounter_runs(encounters_df)
    order: dict = {}
    for i, (key, r) in enumerate(zip(ids, runs.run)):
        order.setdefault((key, r), []).append(i)
    gapped = {ids[i] for i in np.flatnonzero(runs.gap_start)}
    states, actions, all_acc, all_act, names, used = [], [], [], [], [], []
    short = []  # encounters shorter than one decision step: no decision to learn from
    gap_short = [0, 0]  # parts of gapped encounters shorter than one step: parts, rows
    for (key, _), rows in order.items():
        rows = np.asarray(rows)
        n = rows.size // k
        if n == 0:
            if key in gapped:
                gap_short[0] += 1
                gap_short[1] += rows.size
            else:
                short.append(f"{key} ({rows.size} rows)")
            continue
        first = rows[0]
        names.append(f"encounter {key}" if not runs.gap_start[first] else
                     f"encounter {key} from frame {runs.frame[first]} (after {runs.missing[first]} missing frames)")
        step_acc = acc[rows[: n * k]].reshape(n, k).mean(axis=1)  # [n]
        step_act = actions_of(step_acc)
        at = rows[: n * k: k]
        s = paper_states[at]
        if encoding == "driver":
            if n >= 2:
                s, prev, step_acc, step_act, at = s[1:], step_act[:-1], step_acc[1:], step_act[1:], at[1:]
            else:
                prev = np.array([ZERO_ACTION])
            s = s * N_ACTIONS + prev
        states.append(s.astype(np.int64))
        used.append(at)
        actions.append(step_act)
        all_acc.append(step_acc)
        all_act.append(step_act)
    if not states:
        raise DemonstrationError(f"{where}: every encounter (or part between missing frames) is shorter than one "
                                 f"decision step of {k} frames ({decision_step_s} s): {', '.join(short[:5])}")
    if short:
        warnings.warn(f"{where}: {len(short)} encounter(s) shorter than one decision step of {k} frames "
                      f"({decision_step_s} s) left out: {', '.join(short[:5])}", ShortEncounterWarning, stacklevel=2)
    n_gaps = int(runs.gap_start.sum())
    if n_gaps:
        warnings.warn(
            f"{where}: {len(gapped)} encounter(s) have missing frames ({n_gaps} gap(s), {int(runs.missing.sum())} "
            f"frames): each is split at its gaps, so that no {decision_step_s} s decision step spans missing frames"
            + (f"; {gap_short[0]} part(s) shorter than one step left out ({gap_short[1]} rows)" if gap_short[0] else ""),
            FrameGapWarning, stacklevel=2)
    demos = Demonstrations(states=tuple(states), actions=tuple(actions), features=fs.array, n_states=S,
                           n_actions=N_ACTIONS, source=where, names=tuple(names))
    return Discretized(demos, action_mean_acc(np.concatenate(all_acc), np.concatenate(all_act)),
                       np.concatenate(used).astype(np.int64), gaps=n_gaps, gap_rows_dropped=gap_short[1])


class ShortEncounterWarning(UserWarning):
    """Encounters left out because they are shorter than one decision step."""


class FrameGapWarning(UserWarning):
    """Encounters split where frames are missing (a recording's gaps), counted."""


@dataclass(frozen=True)
class EncounterRuns:
    """The runs of an encounter table: rows of one encounter over consecutive frames.

    Attributes:
        run: ``[N]`` int64, a label per row, increasing; a new run starts where the
            ``encounter_id`` changes, where ``Frame_ID`` does not increase (tables concatenated
            from several files or runs that reuse ids) and where it jumps by more than one frame
            within one encounter (missing frames: a gap).
        gap_start: ``[N]`` bool, the row starts a run after a gap.
        missing: ``[N]`` int64, the frames missing before a ``gap_start`` row (0 elsewhere).
        frame: ``[N]`` int64 ``Frame_ID`` (-1 when the table has none).
    """

    run: np.ndarray
    gap_start: np.ndarray
    missing: np.ndarray
    frame: np.ndarray


def encounter_runs(encounters_df: pd.DataFrame) -> EncounterRuns:
    """Cut an encounter table into :class:`EncounterRuns` (rows in table order). Without a
    ``Frame_ID`` column rows are taken as consecutive frames (nothing tells a gap)."""
    ids = encounters_df["encounter_id"].to_numpy()
    n = len(ids)
    brk = np.ones(n, dtype=bool)
    brk[1:] = ids[1:] != ids[:-1]
    gap = np.zeros(n, dtype=bool)
    missing = np.zeros(n, dtype=np.int64)
    frame = np.full(n, -1, dtype=np.int64)
    if "Frame_ID" in encounters_df.columns and n > 1:
        fr = pd.to_numeric(encounters_df["Frame_ID"], errors="coerce").to_numpy(dtype=np.float64)
        frame = np.where(np.isfinite(fr), fr, -1).astype(np.int64)
        step = fr[1:] - fr[:-1]
        brk[1:] |= step <= 0
        gap[1:] = ~brk[1:] & (step > 1)
        missing[1:] = np.where(gap[1:], step - 1, 0).astype(np.int64)
        brk |= gap
    return EncounterRuns(np.cumsum(brk), gap, missing, frame)


def driver_encoded(demos: Demonstrations, features: np.ndarray) -> Demonstrations:
    """Paper-encoded demonstrations (e.g. the authors' files) in the ``"driver"`` encoding: the
    previous action of step t is action t-1 of the trajectory; of step 0, Zero (unknown).

    Args:
        demos: over the 1250 paper states.
        features: ``[6250, 5, K]``.
    """
    if demos.n_states != N_STATES:
        raise DemonstrationError(f"{demos.source}: expected {N_STATES} paper states, got {demos.n_states}")
    states = tuple(driver_encode_sequence(s, a) for s, a in zip(demos.states, demos.actions))
    return Demonstrations(states=states, actions=demos.actions, features=features, n_states=n_states("driver"),
                          n_actions=N_ACTIONS, source=demos.source, names=demos.names)


def kinematic_next_state(states, actions, bins: MergeBins, decision_step_s: float = FRAME_S, *, encoding: str = "paper",
                         action_acc=ACTION_ACC_FT_S2) -> np.ndarray:
    """Next state predicted by constant-acceleration kinematics (the paper's fallback model).

    Takes each state's bin representatives (``MergeBins.representatives``) and the action's
    representative acceleration ``a`` (``ACTION_ACC_FT_S2``), holds them over one decision step ``decision_step_s``
    seconds and re-bins. Only A accelerates; B and C keep their speeds, and B's truck flag is
    unchanged:

        v_AC' = v_AC + a decision_step_s            v_AB' = v_AB + a decision_step_s
        d_AC' = d_AC - v_AC decision_step_s - a decision_step_s^2 / 2
        d_AB' = d_AB - v_AB decision_step_s - a decision_step_s^2 / 2

    (``d_AX`` is the gap from A forward to X, so it shrinks when A is faster than X.)

    With the ``"driver"`` encoding the next state's previous action is ``actions``.

    Args:
        states, actions: integer arrays of equal shape.
        action_acc: ``[5]`` acceleration per action (ft/s^2).

    Returns:
        next states, same shape.

    Raises:
        ConfigError: ``decision_step_s`` is not positive.
    """
    if not decision_step_s > 0:
        raise ConfigError(f"decision step decision_step_s must be positive, got {decision_step_s}")
    if encoding == "driver":
        s_paper, _ = split_driver_state(states)
        nxt = kinematic_next_state(s_paper, actions, bins, decision_step_s, action_acc=action_acc)
        return (nxt * N_ACTIONS + np.asarray(actions, dtype=np.int64)).astype(np.int64)
    parts = state_parts(states)
    acc = np.asarray(action_acc, dtype=np.float64)[np.asarray(actions, dtype=np.int64)]
    rep = {name: bins.representatives(name)[parts[..., i + 1]] for i, name in enumerate(VARIABLES)}
    v_ac = rep["v_AC"] + acc * decision_step_s
    v_ab = rep["v_AB"] + acc * decision_step_s
    d_ac = rep["d_AC"] - rep["v_AC"] * decision_step_s - 0.5 * acc * decision_step_s * decision_step_s
    d_ab = rep["d_AB"] - rep["v_AB"] * decision_step_s - 0.5 * acc * decision_step_s * decision_step_s
    new = [bins.bin_index("d_AC", d_ac), bins.bin_index("d_AB", d_ab),
           bins.bin_index("v_AC", v_ac), bins.bin_index("v_AB", v_ab)]
    return state_index(parts[..., 0], *new).astype(np.int64)


def kinematic_successors(bins: MergeBins, decision_step_s: float = FRAME_S, encoding: str = "paper",
                         action_acc=ACTION_ACC_FT_S2) -> np.ndarray:
    """``[S, 5]`` int: :func:`kinematic_next_state` of every (state, action) pair (``S`` of the
    encoding), the ``fallback_next`` of Q-Avg/Q-SM's ``unobserved="kinematic"`` (:mod:`irl.unobserved_successors`).

    Raises:
        ConfigError: ``decision_step_s`` is not positive.
    """
    S = n_states(encoding)
    s = np.repeat(np.arange(S), N_ACTIONS)
    a = np.tile(np.arange(N_ACTIONS), S)
    return kinematic_next_state(s, a, bins, decision_step_s, encoding=encoding, action_acc=action_acc).reshape(S, N_ACTIONS)


def kinematic_model(bins: MergeBins, decision_step_s: float = FRAME_S, encoding: str = "paper") -> SuccessorModel:
    """The deterministic transition model of ``kinematic_next_state``: ``[S, 5, S]`` (``S`` of the
    encoding: 1250 or 6250), stored sparse (one entry per (s, a) row; ``.to_dense()`` for the array).

    Raises:
        ConfigError: ``decision_step_s`` is not positive.
    """
    S = n_states(encoding)
    nxt = kinematic_successors(bins, decision_step_s, encoding).ravel()
    p = sp.csr_matrix((np.ones(S * N_ACTIONS), nxt, np.arange(S * N_ACTIONS + 1)), shape=(S * N_ACTIONS, S))
    return SuccessorModel(p=p, terminal=np.zeros(S * N_ACTIONS, dtype=bool), n_states=S, n_actions=N_ACTIONS)


def estimated_transitions(demos: Demonstrations, bins: MergeBins, decision_step_s: float = FRAME_S) -> SuccessorModel:
    """``[S, 5, S]`` relative transition counts of ``demos``, with the kinematic model at the
    decision step ``decision_step_s`` for every (s, a) never observed (the paper's MLIRL model for the merge
    domain); the encoding follows ``demos.n_states``. Sparse (:func:`irl.transitions.estimate_transitions`):
    about 1 MB for the driver encoding's 6250 states, where the dense array is 1.5 GB."""
    encoding = "driver" if demos.n_states == n_states("driver") else "paper"
    return estimate_transitions(demos, fallback=kinematic_model(bins, decision_step_s, encoding))


@dataclass(frozen=True)
class ConstantVelocityPad:
    """REIRL padding for the merge domain (paper section 4.2): beyond its last frame a trajectory
    continues with A, B and C at constant velocity, i.e. the Zero-acceleration action under the
    kinematic model. Callable ``state -> (next_state, action)``; picklable."""

    bins: MergeBins
    decision_step_s: float = FRAME_S
    encoding: str = "paper"

    def __call__(self, state: int) -> tuple[int, int]:
        nxt = kinematic_next_state(np.array([state]), np.array([ZERO_ACTION]), self.bins, self.decision_step_s, encoding=self.encoding)
        return int(nxt[0]), ZERO_ACTION


def load(path) -> Demonstrations:
    """Merge trajectories in the authors' text format (their state layout), with the features."""
    return load_text_trajectories(path, n_states=N_STATES, n_actions=N_ACTIONS, features=features())


def read_encounters(path: str | os.PathLike):
    """An encounter table from Parquet (a ``.parquet``/``.pq`` file or a Parquet dataset folder of
    part files, :func:`merge_irl.tables.read_table`) or CSV (anything else).

    Raises:
        DemonstrationError: the file is missing or unreadable, or a folder holds no Parquet part files.
    """
    path = Path(path)
    if path.is_dir() and not is_parquet_dataset(path):
        raise DemonstrationError(f"{path}: a folder, not an encounter table (.parquet/.csv or a Parquet dataset "
                                 "folder of part files); real car-following pairs (a folder "
                                 "of pair CSVs) go to --pairs")
    if not path.exists():
        raise DemonstrationError(f"{path}: no such encounter file")
    try:
        return read_table(path, error=DemonstrationError)
    except Exception as e:  # pandas/pyarrow raise many types for unreadable files
        reason = " ".join(str(e).split())  # pandas' messages may end in a newline: one line
        raise DemonstrationError(f"{path}: cannot read encounter table ({type(e).__name__}: {reason})") from None
