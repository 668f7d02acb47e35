"""``merge-irl learn-driver``: a planning driver learned from demonstrations alone.

Demonstrations are merge encounter tables (``merge-irl generate`` / ``merge-irl encounters``
output, with ``v_A`` and the vehicle lengths) or folders of real car-following pair CSVs (the
layout of ``analysis.calibration.pairs``: C the recorded leader, no B). Several sources are
learned from together, their encounters and pairs kept apart as groups. The planner's settings
are chosen by held-out likelihood on a split of the groups, then its reward weights are fitted
by maximum likelihood on all of them (:func:`irl.domains.merge.planning.driver.learn_planning_driver`).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from pathlib import Path

import pandas as pd

from irl.domains.merge.mdp import DEFAULT_DECISION_STEP_S, read_encounters
from irl.domains.merge.planning.decisions import PlanningDecisions, encounter_decisions, pair_decisions
from irl.domains.merge.planning.driver import PlanningDriver, learn_planning_driver
from irl.domains.merge.planning.model import PlannerConfig
from irl.errors import DemonstrationError
from merge_irl.provenance import provenance
from merge_irl.units import FT_PER_M


def pair_frames(pairs) -> tuple[list[pd.DataFrame], list[str]]:
    """Car-following pairs (:class:`analysis.calibration.pairs.CarFollowingPair`, SI units) as
    the planning driver's pair tables (ft, ft/s; :data:`irl.domains.merge.planning.decisions.PAIR_COLUMNS`)
    and their followers (the groups)."""
    frames = [pd.DataFrame({"t": p.t, "x_follower": p.x_follower * FT_PER_M, "v_follower": p.v_follower * FT_PER_M,
                            "x_leader": p.x_leader * FT_PER_M, "v_leader": p.v_leader * FT_PER_M,
                            "leader_length": p.leader_length * FT_PER_M}) for p in pairs]
    return frames, [p.group for p in pairs]


def load_driver_demos(paths: Sequence[str | os.PathLike], *,
                      decision_step_s: float = DEFAULT_DECISION_STEP_S) -> PlanningDecisions:
    """The decisions of every source in ``paths``: an encounter table (``.parquet``/``.csv``) or
    a folder of pair CSVs (a ``train/`` subfolder is read as ``analysis.calibration`` reads it).

    Raises:
        DemonstrationError: no source, a missing path, or a source without decisions (named).
        SpecError: a malformed pair file (file, line and column named).
    """
    from analysis.calibration.pairs import load_pairs

    if not paths:
        raise DemonstrationError("learn-driver: no demonstrations given (--demos PATH)")
    parts = []
    for p in map(Path, paths):
        if not p.exists():
            raise DemonstrationError(f"{p}: no such file or directory")
        if p.is_dir():
            frames, groups = pair_frames(load_pairs(p))
            parts.append(pair_decisions(frames, decision_step_s, groups=groups, where=str(p)))
        else:
            parts.append(encounter_decisions(read_encounters(p), decision_step_s, where=str(p)))
    return PlanningDecisions.concat(parts)


def learn_driver(paths: Sequence[str | os.PathLike], out: str | os.PathLike | None = None, *, seed: int = 0,
                 decision_step_s: float = DEFAULT_DECISION_STEP_S, select: bool = True,
                 log: Callable[[str], None] = lambda s: None) -> PlanningDriver:
    """Learn a planning driver on the demonstrations of ``paths`` (:func:`load_driver_demos`)
    and, with ``out``, write it (format ``merge-irl-planner/1``) with the provenance of its inputs
    in ``info["provenance"]``. ``select``: choose the planner's settings by held-out likelihood
    (else :class:`~irl.domains.merge.planning.model.PlannerConfig`'s defaults). ``log`` receives
    one line per selection trial.

    Raises:
        DemonstrationError, SpecError: bad demonstrations (see :func:`load_driver_demos`).
        OSError: ``out`` cannot be written.
    """
    decisions = load_driver_demos(paths, decision_step_s=decision_step_s)
    log(f"{decisions.n} decisions in {len(set(decisions.groups.tolist()))} encounters/pairs")
    selection = "heldout" if select else PlannerConfig(decision_step_s=decisions.decision_step_s)
    driver = learn_planning_driver(decisions, seed=seed, selection=selection, log=log)
    inputs = {("demos" if len(paths) == 1 else f"demos{i}"): p for i, p in enumerate(paths, start=1)}
    driver.info["provenance"] = provenance(inputs)
    driver.info["demos"] = [str(p) for p in paths]
    if out is not None:
        driver.save(out)
    return driver
