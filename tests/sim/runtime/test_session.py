"""The stepped SUMO session: frames and events from outside the loop, one session per process,
close idempotent and on error; importing sim loads neither SUMO nor gymnasium."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from sim_testutil import cache_env

from scenarios.loader import load_scenario
from sim.errors import SimulationError
from sim.runtime.session import SumoSession

pytestmark = pytest.mark.sumo


def test_session_steps_frame_by_frame_and_reports_events(tmp_path):
    spec = load_scenario("synthetic")
    with cache_env(tmp_path), SumoSession(spec, 3, duration_s=75.0) as s:
        ctx = s.start()
        assert ctx.site.merge_lane == 6 and ctx.main_lanes == (4, 5, 6)
        frames = []
        while (st := s.step()) is not None:
            frames.append(st)
        assert s.done and s.step() is None
        table = s.table()
        events = s.events()
    ids = [f.frame.frame for f in frames]
    assert ids[0] == round(spec.simulation.warmup_s / 0.1) and ids == list(range(ids[0], ids[0] + len(ids)))
    assert len(frames) == 151  # frames 600 .. 750, both ends
    # the frames handed out are what the table holds
    assert len(table) == sum(len(f.frame.sumo_ids) for f in frames)
    last = frames[-1].frame
    np.testing.assert_array_equal(table[table.Frame_ID == last.frame].sort_values("Vehicle_ID")["v_Vel"].to_numpy(),
                                  last.speed[np.argsort(last.vehicle_id)])
    # the step events add up to the run's (warm-up collisions, if any, come with the first frame)
    assert sum(len(f.events.collisions) for f in frames) == len(events.collisions)
    assert frames[-1].events.departed == events.departed > 0 and frames[-1].events.backlog >= 0


def test_one_session_per_process_and_close_is_idempotent(tmp_path):
    spec = load_scenario("synthetic")
    with cache_env(tmp_path):
        a = SumoSession(spec, 1, duration_s=70.0)
        a.start()
        with pytest.raises(SimulationError, match="another SUMO session is open"):
            SumoSession(spec, 2, duration_s=70.0).start()
        assert a.step() is not None
        a.close()
        a.close()
        with pytest.raises(SimulationError, match="not running"):
            a.step()
        b = SumoSession(spec, 2, duration_s=70.0)
        b.close()  # before start: nothing to do
        with SumoSession(spec, 2, duration_s=70.0) as c:  # the first one's close freed libsumo
            c.start()
            assert c.step() is not None


def test_an_error_inside_the_with_block_closes_sumo(tmp_path):
    spec = load_scenario("synthetic")
    with cache_env(tmp_path):
        with pytest.raises(RuntimeError, match="user code"):
            with SumoSession(spec, 1, duration_s=70.0) as s:
                s.start()
                s.step()
                raise RuntimeError("user code failed")
        assert s.done
        with SumoSession(spec, 1, duration_s=70.0) as again:
            again.start()
            assert again.step() is not None


def test_importing_sim_loads_neither_libsumo_nor_gymnasium():
    code = ("import sys, sim, sim.runtime.session, sim.runtime.run, sim.closed_loop.controller, sim.drivers.observe; "
            "print(sorted(m for m in ('libsumo', 'gymnasium') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip().splitlines()[-1] == "[]"


def test_a_scenario_declares_its_lane_coding_through_its_site_profile(tmp_path):
    """The synthetic road coded as US-101 (main lanes ..5, ramp 7): the table, the context and the
    controller follow the profile, with no edit in sim; the default stays I-80's."""
    from dataclasses import replace

    from scenarios.spec.parse import spec_from_toml
    from sim.closed_loop.config import ControllerConfig
    from sim.closed_loop.controller import Controller
    from sim.drivers.policy import ConstantPolicy
    from sim.runtime.run import run_scenario

    base = load_scenario("synthetic")
    assert base.site == "i-80" and "site" not in base.to_dict()  # presets' text (and hashes) unchanged
    spec = replace(base, site="us-101")
    assert spec_from_toml(spec.to_toml()).site == "us-101"
    ctl = Controller(ConstantPolicy(2), ControllerConfig(decision_step_s=0.3))
    with cache_env(tmp_path):
        res = run_scenario(spec, seed=2, duration_s=110.0, hooks=[ctl])
    assert set(res.table["Lane_ID"].unique()) == {3, 4, 5, 7}
    table = ctl.control_table()
    assert len(table) >= 2 and (table["reason"] == "merge_done").any()
    assert not (table["reason"] == "left_lane").any()  # A is watched in lane 5, the profile's merge lane
    with pytest.raises(Exception, match="no-such-site"):
        with cache_env(tmp_path):
            run_scenario(replace(base, site="no-such-site"), seed=2, duration_s=70.0)
