"""Demonstrations out: encounters and closed-loop rollouts as the transition arrays that
imitation-learning libraries read (observations, actions, next observations, dones).

One row per decision of car A, at the decision step (``decision_step_s``, 0.3 s by default):

* ``obs``: ``[N, 7]`` float64, the continuous observation the closed-loop controller gives a
  policy (:meth:`sim.drivers.observe.MergeObservation.continuous`; columns
  :data:`sim.drivers.observe.CONTINUOUS_NAMES`, units :data:`sim.drivers.observe.CONTINUOUS_UNITS`: ft and ft/s;
  ``d_AC``, ``v_AC`` and ``len_C`` NaN without a lead car C, a length NaN when unknown).
* ``acts``: ``[N]`` int64, the merge action ``0..4`` (High Brake .. High Accel,
  :mod:`irl.domains.merge.actions`); ``acc_mps2``: ``[N]`` float64, the acceleration behind it
  (m/s^2), for learners with a continuous action.
* ``next_obs``: ``[N, 7]``, the observation one decision later; ``dones``: ``[N]`` bool, the last
  decision of its episode; ``episode``: ``[N]`` int64, ``0, 1, ...`` in order, each episode's
  rows consecutive.

Sources:

* **Encounter tables** (:func:`from_encounters`; simulated, or cut from NGSIM files by
  :func:`from_trajectories` through :func:`sim.merges.encounters.extract`): the decisions learning
  takes (:func:`irl.domains.merge.mdp.resample_encounters`, paper encoding: decision ``j`` of an
  encounter is its row ``j k`` with ``k`` frames per decision, its action the bin of A's mean
  acceleration over the next ``k`` rows, an incomplete last step dropped). One episode per
  encounter, or per run of consecutive frames where a recording has missing frames (split
  there, as learning does). The last decision's ``next_obs`` is the row ``k`` frames later when the table has
  it, else the encounter's last row (the latest observation there is, fewer than ``k`` frames
  later).
* **Closed-loop rollouts** (:func:`from_decisions` of the controller's decision log,
  :meth:`sim.closed_loop.controller.Controller.decision_table`; :func:`rollout_transitions` runs one
  episode): one episode per control of A (until its release), the commanded action and
  acceleration (for a driver that is only observed, SUMO's, the action of A's measured
  acceleration). Nothing is observed after the release: the last decision's ``next_obs`` is its
  own ``obs``.

:func:`save` / :func:`load` keep them as ``.npz``; :func:`to_imitation_trajectories` makes
``imitation.data.types.Trajectory`` objects where the ``imitation`` library is installed (it is
not a dependency of this project).
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from irl.domains.merge.actions import N_ACTIONS, actions_of
from irl.domains.merge.bins import MergeBins
from irl.domains.merge.car_following import OPTIONAL_OBS_COLUMNS
from irl.domains.merge.mdp import DEFAULT_DECISION_STEP_S, encounter_runs, frames_per_step, resample_encounters
from irl.errors import ConfigError
from merge_irl.atomic import write_atomic
from merge_irl.units import FRAME_S, M_PER_FT
from sim.drivers.observe import CONTINUOUS_NAMES, policy_rows
from sim.errors import SimError

#: The ``format`` entry of a transitions ``.npz`` file.
TRANSITIONS_FORMAT = "merge-irl-transitions/1"
_ARRAYS = ("obs", "acts", "next_obs", "dones", "episode", "acc_mps2")


class TransitionsError(SimError, ValueError):
    """Transitions that cannot be built, read or converted (the message names the input)."""


@dataclass(frozen=True)
class Transitions:
    """Decisions as transition arrays (see the module docstring for what each holds).

    Attributes:
        obs: ``[N, D]`` float64 (ft, ft/s; columns ``obs_names``).
        acts: ``[N]`` int64 merge actions ``0..4``.
        next_obs: ``[N, D]`` float64.
        dones: ``[N]`` bool, True at each episode's last row.
        episode: ``[N]`` int64, ``0 .. E-1``, non-decreasing, each episode's rows consecutive.
        obs_names: ``D`` column names (:data:`sim.drivers.observe.CONTINUOUS_NAMES`).
        acc_mps2: ``[N]`` float64, the acceleration behind each action (m/s^2).
        decision_step_s: seconds per decision.

    Raises:
        TransitionsError: shapes, dtypes or episode boundaries that disagree (named).
    """

    obs: np.ndarray
    acts: np.ndarray
    next_obs: np.ndarray
    dones: np.ndarray
    episode: np.ndarray
    obs_names: tuple[str, ...] = CONTINUOUS_NAMES
    acc_mps2: np.ndarray = field(default_factory=lambda: np.zeros(0))
    decision_step_s: float = DEFAULT_DECISION_STEP_S

    def __post_init__(self) -> None:
        names = tuple(str(n) for n in self.obs_names)
        object.__setattr__(self, "obs_names", names)
        obs = np.asarray(self.obs, dtype=np.float64)
        n = obs.shape[0] if obs.ndim == 2 else -1
        if obs.ndim != 2 or obs.shape[1] != len(names):
            raise TransitionsError(f"transitions: obs must be [N, {len(names)}] ({', '.join(names)}), got {obs.shape}")
        nxt = np.asarray(self.next_obs, dtype=np.float64)
        if nxt.shape != obs.shape:
            raise TransitionsError(f"transitions: next_obs must be {obs.shape} like obs, got {nxt.shape}")
        acc = np.asarray(self.acc_mps2, dtype=np.float64)
        if acc.size == 0 and n > 0:
            acc = np.full(n, np.nan)
        arrays = {"acts": np.asarray(self.acts), "dones": np.asarray(self.dones), "episode": np.asarray(self.episode),
                  "acc_mps2": acc}
        for k, a in arrays.items():
            if a.shape != (n,):
                raise TransitionsError(f"transitions: {k} must be [{n}] (one per row of obs), got {a.shape}")
        acts, dones, ep = arrays["acts"], arrays["dones"], arrays["episode"]
        if n and (acts.dtype.kind not in "iu" or acts.min() < 0 or acts.max() >= N_ACTIONS):
            raise TransitionsError(f"transitions: acts must be action indices 0..{N_ACTIONS - 1}")
        if n and (ep.dtype.kind not in "iu" or dones.dtype.kind != "b"):
            raise TransitionsError("transitions: episode must be integers and dones booleans")
        last = np.ones(n, dtype=bool)
        last[:-1] = ep[1:] != ep[:-1]
        if n and (ep[0] != 0 or np.any(np.diff(ep) < 0) or np.any(np.diff(ep) > 1)):
            raise TransitionsError("transitions: episode must number the episodes 0, 1, ... in order, each episode's "
                                   "rows consecutive")
        if not np.array_equal(dones.astype(bool), last):
            raise TransitionsError("transitions: dones must be True exactly at each episode's last row")
        if not (isinstance(self.decision_step_s, (int, float)) and math.isfinite(self.decision_step_s)
                and self.decision_step_s > 0):
            raise TransitionsError(f"transitions: decision_step_s must be a positive number, got {self.decision_step_s}")
        for k, v in (("obs", obs), ("next_obs", nxt), ("acts", acts.astype(np.int64)), ("dones", dones.astype(bool)),
                     ("episode", ep.astype(np.int64)), ("acc_mps2", acc)):
            object.__setattr__(self, k, v)
        object.__setattr__(self, "decision_step_s", float(self.decision_step_s))

    @property
    def n(self) -> int:
        """The number of transitions ``N``."""
        return int(self.acts.size)

    @property
    def n_episodes(self) -> int:
        """The number of episodes."""
        return int(self.episode[-1]) + 1 if self.n else 0

    def episodes(self) -> list[np.ndarray]:
        """The row indices of each episode, in order (``[n_e]`` int64 each)."""
        if not self.n:
            return []
        starts = np.flatnonzero(np.r_[True, self.episode[1:] != self.episode[:-1]])
        return [np.arange(a, b) for a, b in zip(starts, np.r_[starts[1:], self.n])]

    def policy_obs(self) -> np.ndarray:
        """``[N, 7]``: ``obs`` as a policy sees it (:func:`sim.drivers.observe.policy_rows`: no NaN, the
        Gymnasium environment's and ``evaluate --policy``'s observation)."""
        return policy_rows(self.obs)

    def policy_next_obs(self) -> np.ndarray:
        """``[N, 7]``: ``next_obs`` as a policy sees it (see :meth:`policy_obs`)."""
        return policy_rows(self.next_obs)


def concatenate(parts: Sequence[Transitions]) -> Transitions:
    """The transitions of ``parts`` one after the other, episodes renumbered.

    Raises:
        TransitionsError: no parts, or parts with other observation columns or decision steps.
    """
    if not parts:
        raise TransitionsError("transitions: nothing to concatenate")
    first = parts[0]
    for p in parts[1:]:
        if p.obs_names != first.obs_names or not math.isclose(p.decision_step_s, first.decision_step_s):
            raise TransitionsError(f"transitions: cannot concatenate decisions every {p.decision_step_s} s of "
                                   f"{p.obs_names} with decisions every {first.decision_step_s} s of {first.obs_names}")
    offsets = np.cumsum([0] + [p.n_episodes for p in parts[:-1]])
    return Transitions(
        np.concatenate([p.obs for p in parts]), np.concatenate([p.acts for p in parts]),
        np.concatenate([p.next_obs for p in parts]), np.concatenate([p.dones for p in parts]),
        np.concatenate([p.episode + o for p, o in zip(parts, offsets)]), first.obs_names,
        np.concatenate([p.acc_mps2 for p in parts]), first.decision_step_s)


def _obs_columns(df: pd.DataFrame, rename: dict[str, str] | None = None) -> np.ndarray:
    """``[len(df), 7]`` the continuous observation columns of ``df`` (a missing optional length: NaN)."""
    rename = rename or {}
    cols = []
    for c in CONTINUOUS_NAMES:
        src = rename.get(c, c)
        if src in df.columns:
            cols.append(pd.to_numeric(df[src], errors="coerce").to_numpy(dtype=np.float64))
        elif c in OPTIONAL_OBS_COLUMNS:
            cols.append(np.full(len(df), np.nan))
        else:
            raise TransitionsError(f"missing column {src!r}")
    return np.column_stack(cols).reshape(-1, len(CONTINUOUS_NAMES))


def from_encounters(encounters: pd.DataFrame, *, decision_step_s: float = DEFAULT_DECISION_STEP_S,
                    where: str = "encounters") -> Transitions:
    """The transitions of an encounter table (:data:`irl.domains.merge.encounters.ENCOUNTER_SCHEMA`
    with ``v_A``; ``len_C``/``len_B`` NaN when absent), one episode per encounter (see the module
    docstring for the decisions taken).

    Raises:
        TransitionsError: no ``v_A`` column; ``decision_step_s`` not a multiple of 0.1 s.
        DemonstrationError: the table breaks the encounter table's checks, or every encounter is
            shorter than one decision step.
    """
    if "v_A" not in encounters.columns:
        raise TransitionsError(f"{where}: the observation needs A's speed, a 'v_A' column (ft/s); columns are "
                               f"{list(encounters.columns)}")
    try:
        k = frames_per_step(decision_step_s)
    except ConfigError as e:
        raise TransitionsError(f"{where}: {e}") from None
    d = resample_encounters(encounters, MergeBins.assumed_authors(), where=where, encoding="paper",
                            decision_step_s=decision_step_s)
    at = d.rows
    lengths = np.array([len(a) for a in d.demos.actions], dtype=np.int64)
    episode = np.repeat(np.arange(lengths.size, dtype=np.int64), lengths)
    dones = np.zeros(at.size, dtype=bool)
    dones[np.cumsum(lengths) - 1] = True
    # each encounter is a block of consecutive rows (resample_encounters' runs): where it ends
    run = encounter_runs(encounters).run - 1  # consecutive frames: a next_obs never lies across a gap
    brk = np.r_[True, run[1:] != run[:-1]]
    run_end = np.r_[np.flatnonzero(brk)[1:], len(run)] - 1  # last row of each run
    nxt = np.minimum(at + k, run_end[run[at]])
    obs_all = _obs_columns(encounters)
    acc_ft = encounters["acc_A"].to_numpy(dtype=np.float64)
    step_acc = acc_ft[at[:, None] + np.arange(k)[None, :]].mean(axis=1)
    acts = np.concatenate([np.asarray(a, dtype=np.int64) for a in d.demos.actions])
    if not np.array_equal(acts, actions_of(step_acc)):  # the same rule, taken twice: a guard
        raise TransitionsError(f"{where}: the decisions' actions disagree with their accelerations")
    return Transitions(obs_all[at], acts, obs_all[nxt], dones, episode, CONTINUOUS_NAMES, step_acc * M_PER_FT,
                       decision_step_s)


def from_trajectories(table: pd.DataFrame, *, decision_step_s: float = DEFAULT_DECISION_STEP_S,
                      site=None, where: str = "trajectories") -> Transitions:
    """The transitions of the merges in an NGSIM-schema trajectory table (a real NGSIM file read by
    :func:`sim.ngsim.read.read_ngsim`, or a simulated run's table): encounters cut by the
    merge-frame rule (:func:`sim.merges.encounters.extract`, as ``merge-irl encounters``), then
    :func:`from_encounters`. ``site``: the lane coding (:mod:`sim.runtime.sites`; I-80's by default).

    Raises:
        TransitionsError: the table has no merge with a lag car A.
        TrajectoryFormatError: see :func:`sim.merges.encounters.extract`.
    """
    from sim.merges.encounters import extract
    from sim.runtime.sites import I80

    enc = extract(table, site=site if site is not None else I80).frames
    if enc.empty:
        raise TransitionsError(f"{where}: no merge with a lag car A (no encounter to export)")
    return from_encounters(enc, decision_step_s=decision_step_s, where=where)


#: Columns of the controller's decision log that :func:`from_decisions` reads.
DECISION_COLUMNS = ("frame", "a_id", "b_id", "action", "acc_cmd", "speed_A", "d_AC", "d_AB", "v_AC", "v_AB",
                    "len_C", "len_B")


def from_decisions(decisions: pd.DataFrame, *, decision_step_s: float | None = None,
                   where: str = "decisions") -> Transitions:
    """The transitions of a closed-loop decision log (:meth:`sim.closed_loop.controller.Controller.decision_table`,
    columns :data:`DECISION_COLUMNS` among others), one episode per control (A, B), episodes in
    order of their first decision, decisions in frame order.

    ``decision_step_s``: the log's step (None: the smallest frame difference between two decisions
    of one control x 0.1 s; :data:`~irl.domains.merge.mdp.DEFAULT_DECISION_STEP_S` when no control
    decided twice).

    Raises:
        TransitionsError: a missing column, an empty log, or actions outside 0..4.
    """
    missing = [c for c in DECISION_COLUMNS if c not in decisions.columns]
    if missing:
        raise TransitionsError(f"{where}: not a decision log: missing column(s) {', '.join(missing)}")
    if decisions.empty:
        raise TransitionsError(f"{where}: no decisions to export")
    df = decisions.reset_index(drop=True)
    key = list(zip(df["a_id"].astype(np.int64), df["b_id"].astype(np.int64)))
    first: dict[tuple[int, int], int] = {}
    for i, kk in enumerate(key):
        first.setdefault(kk, i)
    order = np.array([first[kk] for kk in key], dtype=np.int64)
    df = df.assign(_ep=order).sort_values(["_ep", "frame"], kind="stable").reset_index(drop=True)
    ep_first = df["_ep"].to_numpy()
    starts = np.r_[True, ep_first[1:] != ep_first[:-1]]
    episode = np.cumsum(starts).astype(np.int64) - 1
    dones = np.r_[starts[1:], True]
    if decision_step_s is None:
        diffs = np.diff(df["frame"].to_numpy(dtype=np.int64))[~starts[1:]]
        diffs = diffs[diffs > 0]
        decision_step_s = round(float(diffs.min()) * FRAME_S, 6) if diffs.size else DEFAULT_DECISION_STEP_S
    obs = _obs_columns(df, {"v_A": "speed_A"})
    nxt = obs.copy()
    nxt[~dones] = obs[1:][~dones[:-1]]
    acts = pd.to_numeric(df["action"], errors="coerce").to_numpy()
    if not (np.isfinite(acts).all() and np.isin(acts, np.arange(N_ACTIONS)).all()):
        raise TransitionsError(f"{where}: column 'action' must hold action indices 0..{N_ACTIONS - 1}")
    acc = pd.to_numeric(df["acc_cmd"], errors="coerce").to_numpy(dtype=np.float64) * M_PER_FT
    return Transitions(obs, acts.astype(np.int64), nxt, dones, episode, CONTINUOUS_NAMES, acc, decision_step_s)


def rollout_transitions(scenario: Any, policy: Any, seed: int, *, duration_s: float | None = None,
                        controller: Any = None) -> Transitions:
    """Run one closed-loop episode (``scenario``: preset name, TOML path or ScenarioSpec;
    ``policy`` a :class:`sim.drivers.policy.Policy`, e.g. :class:`sim.drivers.callables.CallablePolicy`)
    and return its decisions as transitions (:func:`from_decisions`).

    Raises:
        TransitionsError: the policy took no decision (no take-over in the run).
        SimulationError: SUMO fails to start or to step.
    """
    from scenarios.loader import load_scenario
    from sim.closed_loop.config import ControllerConfig
    from sim.closed_loop.controller import Controller
    from sim.runtime.run import run_scenario

    spec = load_scenario(scenario) if isinstance(scenario, (str, Path)) else scenario
    ctl = Controller(policy, controller if controller is not None else ControllerConfig())
    run_scenario(spec, seed=seed, duration_s=duration_s, hooks=[ctl])
    return from_decisions(ctl.decision_table(), decision_step_s=ctl.decision_step_s,
                          where=f"rollout of {policy.name} (seed {seed})")


def save(t: Transitions, path: str | os.PathLike) -> Path:
    """Write ``t`` to ``path`` (``.npz``: the arrays, ``obs_names``, ``decision_step_s`` and
    ``format`` :data:`TRANSITIONS_FORMAT`), atomically.

    Raises:
        OSError: the file cannot be written.
    """
    def write(tmp: Path) -> None:
        with open(tmp, "wb") as f:
            np.savez_compressed(f, format=np.array(TRANSITIONS_FORMAT), obs_names=np.array(t.obs_names),
                                decision_step_s=np.array(t.decision_step_s),
                                **{k: getattr(t, k) for k in _ARRAYS})
    return write_atomic(path, write)


def load(path: str | os.PathLike) -> Transitions:
    """Read transitions written by :func:`save`.

    Raises:
        TransitionsError: a missing or unreadable file, another format, a missing array, or arrays
            that disagree (named with the file).
    """
    path = Path(path)
    if not path.is_file():
        raise TransitionsError(f"{path}: no such transitions file")
    try:
        with np.load(path, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
    except Exception as e:  # numpy raises several types for a file that is not an .npz
        raise TransitionsError(f"{path}: cannot read transitions ({type(e).__name__}: {' '.join(str(e).split())})") \
            from None
    fmt = str(data.get("format", ""))
    if fmt != TRANSITIONS_FORMAT:
        raise TransitionsError(f"{path}: format {fmt!r} is not {TRANSITIONS_FORMAT!r}")
    missing = [k for k in (*_ARRAYS, "obs_names", "decision_step_s") if k not in data]
    if missing:
        raise TransitionsError(f"{path}: missing array(s) {', '.join(missing)}")
    try:
        return Transitions(data["obs"], data["acts"], data["next_obs"], data["dones"], data["episode"],
                           tuple(str(s) for s in data["obs_names"].tolist()), data["acc_mps2"],
                           float(data["decision_step_s"]))
    except TransitionsError as e:
        raise TransitionsError(f"{path}: {e}") from None


def to_imitation_trajectories(t: Transitions, *, action: str = "discrete") -> list[Any]:
    """``imitation.data.types.Trajectory`` objects, one per episode: ``obs`` ``[n_e + 1, D]`` (the
    episode's observations and its last ``next_obs``), ``acts`` ``[n_e]`` (int64 action indices, or
    with ``action="continuous"`` ``[n_e, 1]`` float32 accelerations in m/s^2), ``infos`` None,
    ``terminal`` True. Observations as a policy sees them (:meth:`Transitions.policy_obs`: no NaN,
    the Gymnasium environment's), so a policy learned from them runs in the environment and in
    ``evaluate --policy``.

    Raises:
        TransitionsError: ``imitation`` is not installed (``pip install imitation``), or an
            unknown ``action``.
    """
    if action not in ("discrete", "continuous"):
        raise TransitionsError(f"to_imitation_trajectories: action must be 'discrete' or 'continuous', got {action!r}")
    try:
        from imitation.data.types import Trajectory
    except ImportError:
        raise TransitionsError("to_imitation_trajectories needs the 'imitation' library (pip install imitation); "
                               "the arrays themselves are Transitions' obs, acts, next_obs, dones") from None
    out = []
    pobs, pnext = t.policy_obs(), t.policy_next_obs()
    for rows in t.episodes():
        obs = np.concatenate([pobs[rows], pnext[rows[-1:]]])
        acts = t.acts[rows] if action == "discrete" else t.acc_mps2[rows].astype(np.float32)[:, None]
        out.append(Trajectory(obs=obs, acts=acts, infos=None, terminal=True))
    return out
