"""How a simulated run becomes demonstrations: who drives A while it is observed, and which
encounters are cut from the run (every path that turns SUMO runs into demonstrations goes
through :func:`simulate_demonstrations`: ``merge-irl generate``, the demo's and the benchmarks'
data runs).

:data:`sim.merges.rules.ENCOUNTER_RULES` (docs/encounters.md):

``in-lane`` (default)
    The closed-loop controller observes SUMO's drivers as it observes the ``sumo-in-lane``
    baseline: from the take-over until the release, A's lane changes are off (lane-change mode 0,
    restored at release), the constraint of every driver the controller commands, whose actions
    are accelerations alone. The encounters are cut by the controller's own rule
    (:mod:`sim.merges.take_over`). The demonstrators are SUMO's drivers; only A's lane is held while it
    is observed.
``take-over``
    The traffic as the scenario makes it; encounters cut by the controller's rule, so each ends
    where A leaves lane 6 (SUMO's drivers often make room for B by changing lanes: the
    demonstrations then hold few of the states in which a driver that cannot change lanes
    must brake).
``merge-frame``
    The paper's definition on any table (:func:`sim.merges.encounters.extract`): A is B's lag car at
    B's merge frame, over ``window``. The closed loop cannot choose A so (it cannot know the
    future): on four held-out runs 37 of 94 of these As were not the controller's.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence

import pandas as pd

from scenarios.spec.model import ScenarioSpec
from sim.closed_loop.config import ControllerConfig
from sim.closed_loop.controller import Controller
from sim.drivers.policy import SumoPolicy
from sim.merges.encounters import Encounters, EncounterWindow, extract
from sim.merges.rules import ENCOUNTER_RULES, check_rule
from sim.merges.take_over import TakeOverRule
from sim.runtime.hooks import StepHook
from sim.runtime.run import run_scenario
from sim.runtime.run_result import SimulationResult
from sim.runtime.sites import site_of


def demonstrator_hooks(encounter_rule: str) -> list[StepHook]:
    """The step hooks a data run needs for ``encounter_rule`` (the observing controller for
    ``in-lane``; none otherwise). Fresh hooks per run.

    Raises:
        ValueError: an unknown rule.
    """
    check_rule(encounter_rule)
    return [Controller(SumoPolicy(keep_lane=True), ControllerConfig())] if encounter_rule == "in-lane" else []


def simulate_demonstrations(spec: ScenarioSpec, encounter_rule: str = ENCOUNTER_RULES[0], *,
                            seed: int | None = None, duration_s: float | None = None,
                            hooks: Sequence[StepHook] = (), progress: bool = False,
                            window: EncounterWindow = EncounterWindow()) -> tuple[SimulationResult, Encounters]:
    """Simulate ``spec`` (:func:`sim.runtime.run.run_scenario`, with ``seed`` / ``duration_s``
    overrides and the caller's ``hooks``) with the hooks ``encounter_rule`` needs, and cut its
    encounters by that rule: the one way a data run becomes demonstrations.

    Raises:
        ValueError: see :func:`encounters_of_run` (checked before simulating).
        SimulationError: SUMO fails to start or to step.
    """
    check_rule(encounter_rule, custom_window=window != EncounterWindow())
    result = run_scenario(spec, seed=seed, duration_s=duration_s,
                          hooks=[*demonstrator_hooks(encounter_rule), *hooks], progress=progress)
    return result, encounters_of_run(result, encounter_rule=encounter_rule, window=window)


def encounters_of_run(result: SimulationResult, *, encounter_rule: str = ENCOUNTER_RULES[0],
                      window: EncounterWindow = EncounterWindow()) -> Encounters:
    """The merge encounters of a simulated run by ``encounter_rule`` (merges of teleported Bs
    left out). A run made for ``in-lane`` must have run with fresh :func:`demonstrator_hooks`;
    a UserWarning says so when an encounter ends where A left the merge lane (lane 6 on I-80; an observed A
    cannot).

    Raises:
        ValueError: see :func:`sim.merges.rules.check_rule`; the run's auxiliary lane is
            unknown (NaN) for a rule other than ``merge-frame``.
    """
    check_rule(encounter_rule, custom_window=window != EncounterWindow())
    rule = (None if encounter_rule == "merge-frame"
            else TakeOverRule.of_controller(ControllerConfig(), result.aux_lane_start_ft))
    site = site_of(result.spec)
    enc = extract(result.table, window=window, site=site, teleported=result.teleported_vehicle_ids, take_over=rule)
    if encounter_rule == "in-lane":
        left = _left_merge_lane(result.table, enc.frames, site.merge_lane)
        if left:
            warnings.warn(f"encounter rule in-lane: {left} encounter(s) end where A left lane {site.merge_lane}, "
                          "which an observed A cannot do: was the run made with fresh "
                          "demonstrator_hooks('in-lane')?", stacklevel=2)
    return enc


def _left_merge_lane(table: pd.DataFrame, frames: pd.DataFrame, merge_lane: int) -> int:
    """How many encounters of ``frames`` end with A in another lane than ``merge_lane`` (the
    site's; I-80: 6) in the next frame."""
    if frames.empty:
        return 0
    last = frames.groupby("encounter_id")[["A_id", "Frame_ID"]].max()
    lane = table.set_index(["Vehicle_ID", "Frame_ID"])["Lane_ID"]
    nxt = lane.reindex(list(zip(last["A_id"], last["Frame_ID"] + 1)))
    return int((nxt.notna() & (nxt != merge_lane)).sum())
