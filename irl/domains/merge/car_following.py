"""Car-following features of the continuous merge observation with A's own speed.

The binned merge state (:mod:`irl.domains.merge.states`) has no speed of A and five bins per
gap and closing speed; a driver that does not run into a stopping lead car needs both (see
docs/closed-loop.md). These features are functions of one decision's continuous observation
``x = (d_AC, v_AC, d_AB, v_AB, v_A, len_C, len_B)`` (ft, ft/s; the conventions of
:mod:`irl.domains.merge.encounters`), A's previous action and an action ``a`` with
acceleration ``acc_a`` (ft/s^2), shaped after the Intelligent Driver Model (IDM; Treiber,
Hennecke & Helbing 2000, Phys. Rev. E 62, 1805), whose acceleration is
``a_max (1 - (v/v0)^4 - (s*/s)^2)`` with the desired gap ``s* = s0 + v T + v dv / (2 sqrt(a_max b))``:

* ``bias_<action>``: one-hot action (4 of them, Zero is the reference), as in the driver set;
* ``acc_x_gap_need_C``: ``acc_a / 8 x min((s*/s)^2, clip)`` with ``s`` the bumper gap to C
  (``d_AC - len_C``; a car's length when ``len_C`` is NaN) and ``dv = v_AC``; 0 without C. A
  negative weight makes braking likelier as the gap falls short of the desired one, without
  bound up to ``clip``;
* ``acc_x_gap_need_B``: the same towards B (``d_AB - len_B``) while B is ahead of A
  (``d_AB > 0``), else 0;
* ``acc_x_free_road``: ``acc_a / 8 x (v_A / v0)^4`` (the free-road term);
* ``keep_action``: 1 when ``a`` repeats the previous action; ``jerk``: ``|acc_a - acc_prev| / 8``.

The nominal IDM parameters (:class:`GapNeed`) only shape the features; the weights are
learned. Features are ``[N, 5, K]`` over decisions ``N`` (:func:`car_following_features`);
:func:`car_following_decisions` takes the decisions of an encounter table exactly as
:func:`irl.domains.merge.mdp.resample_encounters` does with the driver encoding.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
import pandas as pd

from irl.domains.merge.actions import N_ACTIONS, ZERO_ACTION
from irl.domains.merge.bins import MergeBins
from irl.domains.merge.features import ACC_SCALE_FT_S2, BIAS_FEATURES, bias_columns, persistence_columns
from irl.domains.merge.mdp import DEFAULT_DECISION_STEP_S, resample_encounters
from irl.domains.merge.states import split_driver_state
from irl.errors import ConfigError, DemonstrationError
from merge_irl.units import FT_PER_M

#: The car-following feature names, in the order of the feature axis.
CF_FEATURES = BIAS_FEATURES + ("acc_x_gap_need_C", "acc_x_gap_need_B", "acc_x_free_road", "keep_action", "jerk")
#: Observation columns, in the order of :attr:`CFDecisions.obs`.
OBS_COLUMNS = ("d_AC", "v_AC", "d_AB", "v_AB", "v_A", "len_C", "len_B")
#: Observation columns an encounter table may lack: NaN, the vehicle taken as a car of
#: :attr:`GapNeed.length_ft` (tables written before 2026-12-02, or without ``v_Length``).
OPTIONAL_OBS_COLUMNS = ("len_C", "len_B")


def is_vehicle_length(x: np.ndarray) -> np.ndarray:
    """bool, shape of ``x``: which values are vehicle lengths, finite numbers > 0 (ft). What is
    not one is refused where a table or an observation gives it, except NaN (unknown)."""
    return np.isfinite(x) & (x > 0)


@dataclass(frozen=True)
class GapNeed:
    """Nominal IDM parameters that shape the gap-need features (ft, s, ft/s^2, ft/s).

    Defaults: SUMO's passenger-car defaults (minGap 2.5 m, tau 1 s, accel 2.6 m/s^2, decel
    4.5 m/s^2, desired speed 29 m/s, length 4.5 m), close to the synthetic preset's IDM cars
    (whose minGap is 2.0 m). ``clip`` bounds ``(s*/s)^2`` (a gap near zero would otherwise
    dominate every weight). ``length_ft`` is the length of a leader whose length is not known
    (NaN in the observation).
    """

    min_gap_ft: float = 2.5 * FT_PER_M
    time_headway_s: float = 1.0
    accel_ft_s2: float = 2.6 * FT_PER_M
    decel_ft_s2: float = 4.5 * FT_PER_M
    desired_speed_ft_s: float = 29.0 * FT_PER_M
    length_ft: float = 4.5 * FT_PER_M
    clip: float = 25.0

    def __post_init__(self) -> None:
        bad = {k: v for k, v in asdict(self).items()
               if isinstance(v, bool) or not (isinstance(v, (int, float)) and np.isfinite(v)
                                              and (v > 0 or (k == "min_gap_ft" and v == 0)))}
        if bad:
            raise ConfigError(f"GapNeed: parameters must be finite and positive, got {bad}")

    def need(self, gap_ft, v_ft_s, dv_ft_s, leader_length_ft=np.nan) -> np.ndarray:
        """``min((s*/s)^2, clip)`` for front-to-front gaps ``gap_ft``, A's speed and closing
        speed ``dv`` (arrays of one shape, or broadcastable; ft, ft/s). ``s`` is the gap minus
        the leader's length ``leader_length_ft`` (``length_ft`` where it is not finite: unknown),
        at least 1 ft;
        ``s*`` is at least ``min_gap_ft``."""
        ln = np.asarray(leader_length_ft, dtype=np.float64)
        ln = np.where(np.isfinite(ln), ln, self.length_ft)
        s = np.maximum(np.asarray(gap_ft, dtype=np.float64) - ln, 1.0)
        v = np.asarray(v_ft_s, dtype=np.float64)
        dyn = v * self.time_headway_s + v * np.asarray(dv_ft_s, dtype=np.float64) / (
            2.0 * np.sqrt(self.accel_ft_s2 * self.decel_ft_s2))
        s_star = self.min_gap_ft + np.maximum(dyn, 0.0)
        return np.minimum((s_star / s) ** 2, self.clip)


@dataclass(frozen=True)
class CFDecisions:
    """Decisions of an encounter table with their continuous observations.

    Attributes:
        obs: ``[N, 7]`` float64, columns :data:`OBS_COLUMNS` (``d_AC``/``v_AC``/``len_C`` NaN
            without C; a length NaN when unknown).
        prev: ``[N]`` int64, A's previous action (-1: unknown, featured as Zero).
        actions: ``[N]`` int64, the action taken (forward difference of A's speed over the step).
        action_acc_ft_s2: ``[5]`` mean acceleration of each action's decisions (ft/s^2).
        decision_step_s: seconds per decision.
    """

    obs: np.ndarray
    prev: np.ndarray
    actions: np.ndarray
    action_acc_ft_s2: tuple[float, ...]
    decision_step_s: float

    @property
    def n(self) -> int:
        """The number of decisions ``N``."""
        return int(self.actions.size)


def car_following_decisions(encounters_df: pd.DataFrame, *, decision_step_s: float = DEFAULT_DECISION_STEP_S,
                            where: str = "encounters") -> CFDecisions:
    """The decisions of ``encounters_df`` resampled at ``decision_step_s`` (the rule of
    :func:`irl.domains.merge.mdp.resample_encounters` with the driver encoding) and their observations
    (a missing ``len_C`` or ``len_B`` column: NaN, :data:`OPTIONAL_OBS_COLUMNS`).

    Raises:
        DemonstrationError: the table has no ``v_A`` column (A's speed, ft/s; the pipeline
            writes it), a row whose speed is not a finite number >= 0 or whose ``len_C`` /
            ``len_B`` is neither empty (unknown) nor a finite number > 0 ft (every row is
            checked, not only the decisions'; the message names the row, counted from 0, and
            the column), or the table breaks the encounter table's checks.
        ConfigError: a bad decision step.
    """
    if "v_A" not in encounters_df.columns:
        raise DemonstrationError(f"{where}: the car-following features need A's speed, a 'v_A' column (ft/s); "
                                 f"columns are {list(encounters_df.columns)}")
    for c in ("v_A", *OPTIONAL_OBS_COLUMNS):
        if c not in encounters_df.columns:
            continue
        col = encounters_df[c]
        x = pd.to_numeric(col, errors="coerce").to_numpy(dtype=np.float64)
        ok = (np.isfinite(x) & (x >= 0)) if c == "v_A" else (is_vehicle_length(x) | col.isna().to_numpy())
        if not ok.all():
            i = int(np.argmax(~ok))
            got = col.iloc[i]
            got = got.item() if isinstance(got, np.generic) else got
            need = ("A's speed must be a finite number >= 0 ft/s" if c == "v_A" else
                    "a vehicle length must be a finite number > 0 ft, or empty (unknown)")
            raise DemonstrationError(f"{where}: row {i}, column {c!r}: {need}, got {got!r}")
    d = resample_encounters(encounters_df, MergeBins.assumed_authors(), where=where, encoding="driver",
                            decision_step_s=decision_step_s)
    states, actions, _ = d.demos.flat()
    _, prev = split_driver_state(states)
    picked = encounters_df.iloc[d.rows]
    obs = np.column_stack([np.full(len(picked), np.nan) if c in OPTIONAL_OBS_COLUMNS and c not in picked.columns
                           else pd.to_numeric(picked[c], errors="coerce").to_numpy(dtype=np.float64)
                           for c in OBS_COLUMNS]).reshape(-1, len(OBS_COLUMNS))
    return CFDecisions(obs, prev.astype(np.int64), np.asarray(actions, dtype=np.int64),
                       tuple(float(x) for x in d.action_acc_ft_s2), float(decision_step_s))


def car_following_features(obs: np.ndarray, prev: np.ndarray, action_acc_ft_s2,
                           gap_need: GapNeed = GapNeed()) -> np.ndarray:
    """``[N, 5, len(CF_FEATURES)]`` features (module docstring) of decisions ``obs [N, 7]``
    (:data:`OBS_COLUMNS`) with previous actions ``prev [N]`` (-1: unknown, taken as Zero);
    ``action_acc_ft_s2 [5]`` the acceleration of each action (ft/s^2).

    Raises:
        ConfigError: ``obs`` is not ``[N, 7]``, a length in it neither NaN (unknown) nor a finite
            number > 0, ``prev`` not ``[N]`` whole actions or -1, or ``action_acc`` not 5 finite
            numbers.
    """
    obs = np.asarray(obs, dtype=np.float64)
    prev_in = np.asarray(prev)
    acc = np.asarray(action_acc_ft_s2, dtype=np.float64)
    if obs.ndim != 2 or obs.shape[1] != len(OBS_COLUMNS) or prev_in.shape != (obs.shape[0],):
        raise ConfigError(f"obs must be [N, {len(OBS_COLUMNS)}] (columns {', '.join(OBS_COLUMNS)}) and prev [N]; "
                          f"got {obs.shape} and {prev_in.shape}")
    if prev_in.size and not (np.issubdtype(prev_in.dtype, np.integer)
                             or np.all(np.isfinite(prev_in) & (prev_in == np.round(prev_in)))):
        raise ConfigError(f"prev must hold whole actions (or -1), got {prev_in[:5]}")
    prev = prev_in.astype(np.int64)
    lengths = obs[:, 5:7]
    bad = ~np.isnan(lengths) & ~is_vehicle_length(lengths)
    if bad.any():
        i, j = (int(k) for k in np.argwhere(bad)[0])
        raise ConfigError(f"obs row {i}, {OBS_COLUMNS[5 + j]}: a length must be NaN (unknown) or a finite number "
                          f"> 0 ft, got {lengths[i, j]}")
    if acc.shape != (N_ACTIONS,) or not np.all(np.isfinite(acc)):
        raise ConfigError(f"action_acc_ft_s2 must be {N_ACTIONS} finite numbers, got {acc}")
    if prev.size and (prev.min() < -1 or prev.max() >= N_ACTIONS):
        raise ConfigError(f"prev must hold actions 0..{N_ACTIONS - 1} or -1 (unknown), got {prev.min()}..{prev.max()}")
    prev = np.where(prev >= 0, prev, ZERO_ACTION)
    d_ac, v_ac, d_ab, v_ab, v_a, len_c, len_b = (obs[:, j] for j in range(len(OBS_COLUMNS)))
    has_c = np.isfinite(d_ac) & np.isfinite(v_ac)
    need_c = np.where(has_c, gap_need.need(np.where(has_c, d_ac, 1e6), v_a, np.where(has_c, v_ac, 0.0), len_c), 0.0)
    b_ahead = d_ab > 0
    need_b = np.where(b_ahead, gap_need.need(np.where(b_ahead, d_ab, 1e6), v_a, v_ab, len_b), 0.0)
    free = (v_a / gap_need.desired_speed_ft_s) ** 4
    n = obs.shape[0]
    accn = acc[None, :] / ACC_SCALE_FT_S2  # [1, A]
    cols = [*bias_columns(n), accn * need_c[:, None], accn * need_b[:, None], accn * free[:, None],
            *persistence_columns(prev, acc)]
    return np.stack([np.broadcast_to(c, (n, N_ACTIONS)) for c in cols], axis=-1)
