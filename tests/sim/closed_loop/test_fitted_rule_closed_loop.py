"""In SUMO, a planning driver drives A by its fitted rule: every applied acceleration is
:meth:`irl.planning.driver.PlanningDriver.act` of the logged observation, and the command changes
sign less often than when a bin is drawn from its likelihood model on the same seed."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
import pandas as pd
import pytest
from irl_testdata import planning_encounters

from analysis.evaluation.episode import run_episode
from irl.domains.merge.actions import action_of
from irl.planning.decisions import encounter_decisions
from irl.planning.driver import learn_planning_driver
from irl.planning.model import PlannerConfig
from scenarios.loader import load_scenario
from sim.closed_loop.config import ControllerConfig
from sim.drivers.planning import PlanningDriverPolicy

pytestmark = pytest.mark.sumo

DURATION = 150.0
SEED = 3


@dataclass(frozen=True)
class Recorded(PlanningDriverPolicy):
    """The planning driver, keeping every observation it was asked to decide on."""

    seen: list = field(default_factory=list, compare=False, repr=False)

    def probs(self, obs):
        self.seen.append(obs)
        return super().probs(obs)


def _sign_changes_per_100(dec: pd.DataFrame) -> float:
    changes = n = 0
    for _, g in dec.groupby("a_id", sort=False):
        s = np.sign(g.acc_cmd.to_numpy())
        changes += int((s[1:] * s[:-1] < 0).sum())
        n += max(len(s) - 1, 0)
    return 100.0 * changes / n


@pytest.fixture(scope="module")
def driver():
    d = encounter_decisions(planning_encounters(n=6))
    fitted = learn_planning_driver(d, selection=PlannerConfig(grid="g13", horizon_s=0.9))
    return replace(fitted, info={**fitted.info, "fit": "replay"})  # a replay-fitted driver's rule: act


def test_a_planning_driver_applies_act_of_its_observations_and_flips_less(driver):
    spec = load_scenario("synthetic")
    pol = Recorded(driver, name="planner")
    ep = run_episode(spec, pol, SEED, duration_s=DURATION)
    dec = ep.decisions
    assert len(dec) == len(pol.seen) >= 30
    checked = 0
    for obs, row in zip(pol.seen, dec.itertuples()):
        prev = obs.acc_prev if math.isfinite(obs.acc_prev) else 0.0
        acc_c = obs.acc_C if math.isfinite(obs.acc_C) else 0.0
        want = float(driver.act(obs.continuous(), np.array([prev]), np.array([acc_c]), np.array([obs.b_merged]))[0])
        assert row.action == action_of(want)
        if want > -29.0:  # A's physical limit (9 m/s^2 cars, 7 trucks) not reached: applied as decided
            assert row.acc_cmd == pytest.approx(want, abs=1e-9)
            checked += 1
    assert checked >= 30
    drawn = run_episode(spec, PlanningDriverPolicy(driver, name="planner"), SEED, duration_s=DURATION,
                        controller=ControllerConfig(rule="likelihood-draw"))
    assert _sign_changes_per_100(dec) < _sign_changes_per_100(drawn.decisions)
