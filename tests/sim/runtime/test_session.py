"""The stepped SUMO session: frames and events from outside the loop, a second session in one
process through TraCI with the same frames and hooks, close idempotent and on error; importing
sim loads neither SUMO nor gymnasium."""

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


def test_a_second_session_runs_through_traci_alike_and_close_is_idempotent(tmp_path):
    spec = load_scenario("synthetic")
    with cache_env(tmp_path):
        a = SumoSession(spec, 1, duration_s=80.0)
        a.start()
        b = SumoSession(spec, 1, duration_s=80.0)  # while `a` holds libsumo
        ctx_b = b.start()
        assert (a.backend, b.backend) == ("libsumo", "traci")
        assert a.sumo is a.context.sumo and b.sumo is ctx_b.sumo and b.sumo is not a.sumo
        proc = b.sumo.process  # the TraCI session's SUMO, a child process
        assert proc.poll() is None
        n = 0
        while (sa := a.step()) is not None:
            sb = b.step()
            assert sb is not None and sa.frame.sumo_ids == sb.frame.sumo_ids and sa.events == sb.events
            np.testing.assert_array_equal(sa.frame.local_y, sb.frame.local_y)
            np.testing.assert_array_equal(sa.frame.speed, sb.frame.speed)
            n += 1
        assert b.step() is None and n == 201
        assert a.table().equals(b.table())
        assert b.sumo.vehicle.getIDCount() > 0  # the handle takes libsumo's calls
        with pytest.raises(b.sumo.TraCIException):
            b.sumo.vehicle.getSpeed("no-such-car")
        b.close()
        b.close()
        assert proc.poll() is not None  # closed with its session
        a.close()
        a.close()
        with pytest.raises(SimulationError, match="not running"):
            a.step()
        c = SumoSession(spec, 2, duration_s=70.0)
        c.close()  # before start: nothing to do
        with SumoSession(spec, 2, duration_s=70.0) as d:  # the first one's close freed libsumo
            d.start()
            assert d.backend == "libsumo" and d.step() is not None


def test_two_threads_starting_sessions_at_once_share_the_backends(tmp_path):
    import threading

    spec = load_scenario("synthetic")
    sessions = [SumoSession(spec, 1, duration_s=70.0) for _ in range(2)]
    with cache_env(tmp_path):
        build = threading.Barrier(2)

        def start(s):
            build.wait()
            s.start()

        threads = [threading.Thread(target=start, args=(s,)) for s in sessions]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        try:
            assert sorted(s.backend for s in sessions) == ["libsumo", "traci"]
            assert all(s.step() is not None for s in sessions)
        finally:
            for s in sessions:
                s.close()


def test_hooks_drive_a_traci_run_through_the_context_as_a_libsumo_run(tmp_path):
    """The controller (its take-overs, releases and accelerations) and the expert labels call SUMO
    through ``ctx.sumo``: a run started while another session is open is the libsumo run."""
    from sim.closed_loop.config import ControllerConfig
    from sim.closed_loop.controller import Controller
    from sim.drivers.policy import ConstantPolicy
    from sim.merges.expert_labels import ExpertLabels
    from sim.runtime.run import run_scenario

    spec = load_scenario("synthetic")

    def run():
        ctl = Controller(ConstantPolicy(0), ControllerConfig(decision_step_s=0.3))
        labels = ExpertLabels(ctl)
        res = run_scenario(spec, seed=4, duration_s=110.0, hooks=[ctl, labels])
        return res.table, ctl.control_table(), labels.table()

    with cache_env(tmp_path):
        alone = run()
        with SumoSession(spec, 1, duration_s=70.0) as holder:
            holder.start()
            beside = run()
    assert len(alone[1]) >= 2 and len(alone[2]) > 0
    for x, y in zip(alone, beside, strict=True):
        assert x.equals(y)


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


def test_importing_sim_loads_neither_sumo_nor_gymnasium():
    code = ("import sys, sim, sim.runtime.session, sim.runtime.run, sim.closed_loop.controller, sim.drivers.observe; "
            "print(sorted(m for m in ('libsumo', 'traci', 'gymnasium') if m in sys.modules))")
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
