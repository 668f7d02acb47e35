"""The SUMO expert's labels (sim/merges/expert_labels.py), which studies/expert_in_learner_states.py and
analysis/experiments/dagger.py ask in the learner's states."""

from __future__ import annotations

import numpy as np
import pytest

from irl.domains.merge.actions import N_ACTIONS, action_of
from irl.domains.merge.bins import MergeBins
from irl.domains.merge.states import n_states
from merge_irl.units import M_PER_FT
from scenarios.loader import load_scenario
from sim.closed_loop.config import ControllerConfig
from sim.closed_loop.controller import Controller
from sim.drivers.learned import LearnedPolicy
from sim.merges.expert_labels import ExpertLabels
from sim.runtime.run import run_scenario


@pytest.mark.sumo
def test_expert_labels_every_decision_and_brakes_for_a_driver_that_only_accelerates():
    """A driver that always takes High Accel closes in on its lead car: the expert (SUMO's car
    following of A's type) labels every decision, and asks for braking in some of them."""
    bins = MergeBins.assumed_authors()
    log_pi = np.full((n_states("driver"), N_ACTIONS), -50.0)
    log_pi[:, 4] = 0.0  # High Accel
    pol = LearnedPolicy(log_pi=log_pi, encoder=bins, name="gas", decision_step_s=0.3, state_encoding="driver")
    ctl = Controller(pol, ControllerConfig(decision_step_s=0.3))
    hook = ExpertLabels(ctl)
    sumo_view: list[tuple[int, int]] = []  # (action, leader) asked with SUMO's own leader and gap

    class SumoLeader:
        def on_start(self, ctx):
            pass

        def on_step(self, ctx, frame):
            import libsumo

            veh = libsumo.vehicle
            latest = {c.a_id: c for c in ctl.controls if c.a_id in ctl.decided}
            for a_id in latest:
                sid = ctx.sumo_id_of(a_id)
                v = veh.getSpeed(sid)
                lead = veh.getLeader(sid, 1000.0)  # (id, bumper gap minus minGap in m) or ("", -1)
                leader = (ctx.vehicle_id_of(lead[0]) or 0) if lead and lead[0] else 0
                if leader:
                    v_next = veh.getFollowSpeed(sid, v, lead[1], veh.getSpeed(lead[0]), veh.getDecel(lead[0]))
                else:
                    v_next = veh.getFollowSpeed(sid, v, 1e4, v, 4.5)
                acc = min(max((v_next - v) / ctx.step_length_s, -veh.getEmergencyDecel(sid)), veh.getAccel(sid))
                sumo_view.append((action_of(acc / M_PER_FT), leader))

        def on_end(self, ctx):
            pass

    run_scenario(load_scenario("synthetic"), seed=3, duration_s=120, hooks=[ctl, hook, SumoLeader()])
    dec = ctl.decision_table()
    assert len(dec) > 50
    assert len(hook.labels) == len(dec)
    states, actions = np.array(hook.labels).T
    np.testing.assert_array_equal(states, dec["state"].to_numpy())  # each label with its own decision
    brake, accel = actions <= action_of(-6.0), actions == 4
    assert brake.any(), "the expert never brakes behind a car A runs into"
    assert accel.any(), "the expert never accelerates"
    # ExpertLabels reads C, the gap and C's speed from the frame; where SUMO's own leader query
    # finds C too (elsewhere SUMO sees the merging car or nothing), both give the same action
    sumo_action, sumo_leader = np.array(sumo_view).T
    same = sumo_leader == dec["c_id"].to_numpy()
    assert same.sum() > 30
    np.testing.assert_array_equal(actions[same], sumo_action[same])
    d_ac = dec["d_AC"].fillna(1000.0).to_numpy()
    assert np.median(d_ac[brake]) < 0.5 * np.median(d_ac[accel]), "the expert brakes where C is far"


@pytest.mark.sumo
def test_expert_gap_is_bumper_gap_minus_min_gap():
    """What ExpertLabels hands SUMO as the gap is the bumper gap minus A's minGap (m): at a gap of
    minGap + s* SUMO's IDM is in equilibrium with its leader (only the free-road term brakes), as
    the IDM formula with the preset's car parameters says."""
    import libsumo

    spec = load_scenario("synthetic")
    car = spec.drivers.car[0]
    got: dict[str, float] = {}

    class Probe:
        def on_start(self, ctx):
            pass

        def on_step(self, ctx, frame):
            cars = [s for s, c in zip(frame.sumo_ids, frame.v_class) if c == 2]
            if got or not cars:
                return
            v = 15.0
            gap = v * car.tau  # s* - s0 at zero closing speed
            got["v_next"] = libsumo.vehicle.getFollowSpeed(cars[0], v, gap, v, car.decel)
            got["v0"] = libsumo.vehicle.getAllowedSpeed(cars[0])
            got["min_gap"] = libsumo.vehicle.getMinGap(cars[0])

        def on_end(self, ctx):
            pass

    run_scenario(spec, seed=1, duration_s=spec.simulation.warmup_s + 5.0, hooks=[Probe()])
    v = 15.0
    s_star = car.min_gap_m + v * car.tau
    # the gap SUMO gets (v tau) plus its minGap is the bumper gap s = s*: the interaction term is 1
    expected = car.accel * (1 - (v / got["v0"]) ** 4 - (s_star / (v * car.tau + got["min_gap"])) ** 2)
    assert got["min_gap"] == pytest.approx(car.min_gap_m)
    assert (got["v_next"] - v) / 0.1 == pytest.approx(expected, abs=0.05)
