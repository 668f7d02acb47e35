"""Closed loop with real SUMO: controlled lag cars follow the policy's commands exactly."""

from __future__ import annotations

from dataclasses import dataclass, field

import libsumo
import numpy as np
import pytest

from analysis.evaluation.distances import js_divergence
from analysis.evaluation.episode import run_episode
from irl.domains.merge.actions import ACTION_ACC_FT_S2
from scenarios.loader import load_scenario
from sim.closed_loop.config import ControllerConfig
from sim.closed_loop.controller import Controller
from sim.closed_loop.records import COLLISION_KINDS, RELEASE_REASONS
from sim.drivers.policy import ConstantPolicy, PolicyDefaults, SumoPolicy, UniformPolicy

pytestmark = pytest.mark.sumo

DURATION = 150.0  # s; 60 s warm-up, then merges
SEED = 3


@pytest.fixture(scope="module")
def spec():
    return load_scenario("synthetic")


@pytest.fixture(scope="module")
def uniform_run(spec):
    return run_episode(spec, UniformPolicy(), SEED, duration_s=DURATION, keep_table=True)


@pytest.fixture(scope="module")
def sumo_run(spec):
    return run_episode(spec, SumoPolicy(), SEED, duration_s=DURATION, keep_table=True)


@pytest.fixture(scope="module")
def brake_run(spec):
    return run_episode(spec, ConstantPolicy(0), SEED, duration_s=DURATION, keep_table=True,
                       demo_action_counts=np.ones(5), controller=ControllerConfig(high_brake="mean"))


@dataclass(frozen=True)
class Tailgater(PolicyDefaults):
    """High Accel until A's TTC to C falls below 2 s (or C is within 40 ft), then High Brake: a
    driver that brakes late and needs to brake hard."""

    name: str = "tailgater"
    controls: bool = True
    decision_step_s: float | None = None

    def probs(self, obs):
        late = obs.v_AC > 0 and obs.d_AC / obs.v_AC < 2.0
        return np.eye(5)[0 if late or obs.d_AC < 40.0 else 4]


def test_measured_acceleration_equals_commanded(uniform_run):
    table = uniform_run.table.set_index(["Vehicle_ID", "Frame_ID"]).sort_index()
    dec = uniform_run.decisions
    controls = uniform_run.controls
    assert len(controls) >= 3 and len(dec) >= 30
    checked = 0
    every = 3  # 0.3 s decision step / 0.1 s frames
    for c in controls.itertuples():
        d = dec[dec.a_id == c.a_id]
        d = d[(d.frame >= c.start_frame) & (d.frame < c.end_frame)]
        for r in d.itertuples():
            assert r.acc_cmd == ACTION_ACC_FT_S2[r.action]
            for f in range(r.frame + 1, min(r.frame + every, c.end_frame) + 1):
                row = table.loc[(c.a_id, f)]
                prev = table.loc[(c.a_id, f - 1)]
                if row.v_Vel < 0.5 or prev.v_Vel < 0.5:  # SUMO never drives backwards
                    continue
                assert row.v_Acc == pytest.approx(r.acc_cmd, abs=1e-6)
                assert row.v_Vel - prev.v_Vel == pytest.approx(0.1 * r.acc_cmd, abs=1e-6)
                checked += 1
    assert checked >= 60


def test_sumo_never_moves_a_controlled_car_on_its_own(uniform_run):
    """No lane change while controlled, and every speed change is the commanded one."""
    t = uniform_run.table
    for c in uniform_run.controls.itertuples():
        rows = t[(t.Vehicle_ID == c.a_id) & (t.Frame_ID >= c.start_frame) & (t.Frame_ID <= c.end_frame)]
        assert rows.Lane_ID.nunique() == 1 and rows.Lane_ID.iloc[0] == 6
        # the speed path is exactly the integral of the commanded accelerations
        d = uniform_run.decisions[uniform_run.decisions.a_id == c.a_id].set_index("frame")
        v = rows.set_index("Frame_ID").v_Vel
        cmd = d.acc_cmd.reindex(range(c.start_frame, c.end_frame + 1)).ffill()
        pred = v.iloc[0] + 0.1 * np.cumsum(cmd.shift(1).fillna(0.0).to_numpy())
        ok = (v.to_numpy() > 0.5)
        n = int(np.argmin(ok)) if not ok.all() else len(ok)  # until the car first stands still
        assert np.allclose(v.to_numpy()[:n], pred[:n], atol=1e-6)


def test_hard_brake_policy_metrics(brake_run, sumo_run):
    m, base = brake_run.metrics, sumo_run.metrics
    n_dec = len(brake_run.decisions)
    assert n_dec > 0
    assert m.action_counts == (n_dec, 0, 0, 0, 0)
    # A's measured acceleration is High Brake's -8 ft/s^2 until it stands still
    t = brake_run.table
    for c in brake_run.controls.itertuples():
        rows = t[(t.Vehicle_ID == c.a_id) & (t.Frame_ID > c.start_frame) & (t.Frame_ID <= c.end_frame)]
        # SUMO spreads the last deceleration to a stop over the final 3 frames (e.g. 2.27 ft/s
        # -> 0 at -7.58 ft/s^2): frames that start below three steps of -8 ft/s^2 are the stop
        moving = rows[rows.v_Vel.shift(1, fill_value=rows.v_Vel.iloc[0]) > 3 * 0.8]
        assert np.allclose(moving.v_Acc, -8.0, atol=1e-6)
    # expected consequences against SUMO's own driver on the same traffic
    assert m.mean_speed_A_ft_s < base.mean_speed_A_ft_s - 10.0
    assert m.b_ahead_rate >= base.b_ahead_rate
    assert m.min_ttc_s < base.min_ttc_s
    # JS divergence of a one-hot distribution against uniform demonstrations, by hand
    # (the midpoint of one-hot [1,0,0,0,0] and uniform is [0.6, 0.1, 0.1, 0.1, 0.1])
    p = np.array([1, 0, 0, 0, 0.0])
    expected = 0.5 * np.log2(1 / 0.6) + 0.5 * (0.2 * np.log2(0.2 / 0.6) + 0.8 * np.log2(0.2 / 0.1))
    assert m.js_divergence == pytest.approx(expected, abs=1e-12)
    assert js_divergence(p, np.ones(5)) == pytest.approx(expected)
    assert set(m.release_reasons) <= set(RELEASE_REASONS)


def test_high_brake_by_need_brakes_harder_only_where_the_leader_requires_it(spec):
    """``high_brake="need"``: a High Brake decision is applied at the action's acceleration or
    harder, by the kinematic need recomputed here from the table (lane-6 leader, its speed and
    SUMO's backward-difference acceleration, A's minGap of 2.0 m), never beyond A's decel."""
    from merge_irl.units import FT_PER_M
    from sim.closed_loop.actuation import high_brake_need

    ep = run_episode(spec, Tailgater(), SEED, duration_s=DURATION, keep_table=True,
                     controller=ControllerConfig(high_brake="need"))
    mean = ep.decisions[ep.decisions.action == 0]
    assert len(mean) >= 5
    t = ep.table
    decel = 4.5 * FT_PER_M
    harder = 0
    for r in mean.itertuples():
        assert -decel - 1e-9 <= r.acc_cmd <= ACTION_ACC_FT_S2[0] + 1e-12
        now = t[t.Frame_ID == r.frame]
        a = now[now.Vehicle_ID == r.a_id].iloc[0]
        ahead = now[(now.Lane_ID == 6) & (now.Local_Y > a.Local_Y)].sort_values(["Local_Y", "Vehicle_ID"])
        if ahead.empty:
            assert r.acc_cmd == ACTION_ACC_FT_S2[0]
            continue
        lead = ahead.iloc[0]
        gap = max(lead.Local_Y - a.Local_Y - lead.v_Length - 2.0 * FT_PER_M, 1.0)
        need = high_brake_need(a.v_Vel, lead.v_Vel, lead.v_Acc, gap)
        assert r.acc_cmd == pytest.approx(min(ACTION_ACC_FT_S2[0], max(-need, -decel)), abs=1e-6)
        harder += r.acc_cmd < ACTION_ACC_FT_S2[0] - 1e-9
    assert harder >= 3  # the tailgater needs it
    assert int(ep.decisions.need_brake.sum()) == harder and ep.metrics.need_brakes == harder  # counted
    # the same driver under the default, physical actuation: every High Brake at the action's acceleration
    assert ControllerConfig().high_brake == "mean"
    ep_mean = run_episode(spec, Tailgater(), SEED, duration_s=DURATION)
    assert (ep_mean.decisions.loc[ep_mean.decisions.action == 0, "acc_cmd"] == ACTION_ACC_FT_S2[0]).all()
    assert not ep_mean.decisions.need_brake.any() and ep_mean.metrics.need_brakes == 0
    with pytest.raises(ValueError, match="high_brake"):
        ControllerConfig(high_brake="max")


def _min_gap(v_a, v_l, acc_l, gap, b):
    """Smallest gap (ft) over time when A brakes at ``b`` and the leader at ``-acc_l`` (both
    until they stop), on a fine time grid."""
    t_end = max(v_a / b if b > 0 else 60.0, v_l / -acc_l if acc_l < 0 else 0.0) + 1.0
    t = np.linspace(0.0, t_end, 200_001)

    def pos(v, dec):
        if dec <= 0:
            return v * t
        ts = np.minimum(t, v / dec)
        return v * ts - 0.5 * dec * ts * ts

    return float(np.min(gap + pos(v_l, -acc_l) - pos(v_a, b)))


def test_high_brake_need_by_hand_and_by_simulation():
    from sim.closed_loop.actuation import high_brake_need

    assert high_brake_need(30.0, 20.0, 0.0, 50.0) == pytest.approx(1.0)  # 10^2 / 100: match the speed
    assert high_brake_need(20.0, 30.0, 0.0, 50.0) == 0.0  # opening, leader not braking
    # leader braking at 10 ft/s^2 from 20 ft/s stops in 20 ft: A at 30 ft/s stops within 50 + 20
    assert high_brake_need(30.0, 20.0, -10.0, 50.0) == pytest.approx(900.0 / 140.0)
    # A reaches the braking leader's speed before it stops: the leader's deceleration + matching
    assert high_brake_need(50.0, 30.0, -5.0, 20.0) == pytest.approx(5.0 + 400.0 / 40.0)
    assert high_brake_need(35.0, 13.8, -6.8, 39.0) > 8.97  # the stop of a cf-dagger collision (docs)
    # the need is the smallest constant deceleration that keeps the gap >= 0: at it the gap stays
    # (numerically) non-negative, 0.3 ft/s^2 less and A hits the leader
    rng = np.random.default_rng(7)
    for _ in range(60):
        v_a, v_l = rng.uniform(5.0, 70.0), rng.uniform(0.0, 60.0)
        acc_l = rng.choice([0.0, -rng.uniform(0.5, 15.0)])
        gap = rng.uniform(2.0, 150.0)
        need = high_brake_need(v_a, v_l, acc_l, gap)
        assert need >= 0.0
        assert _min_gap(v_a, v_l, acc_l, gap, need) >= -1e-3 * max(gap, 1.0)
        if need > 0.5:
            assert _min_gap(v_a, v_l, acc_l, gap, need - 0.3) < 0.0


def test_sumo_baseline_is_observed_not_commanded(sumo_run):
    assert len(sumo_run.controls) > 0
    assert not sumo_run.controls.commanded.any()
    # its actions are the bins of the measured accelerations: not all one bin
    assert sum(1 for x in sumo_run.metrics.action_counts if x > 0) >= 2


def test_observations_say_when_b_has_merged(spec):
    """b_merged is False before the controller's merge frame of that A's B and True from it on."""
    from sim.runtime.run import run_scenario

    class Recorder(PolicyDefaults):
        name, controls, decision_step_s = "recorder", True, None

        def __init__(self):
            self.seen = []

        def probs(self, obs):
            self.seen.append(obs)
            return np.full(5, 0.2)

    pol = Recorder()
    ctl = Controller(pol, ControllerConfig())
    run_scenario(spec, seed=SEED, duration_s=DURATION, hooks=[ctl])
    dec = ctl.decision_table()
    merge = ctl.control_table().set_index(["a_id", "b_id"])["merge_frame"]
    expected = [0 <= merge[(a, b)] <= f for a, b, f in zip(dec.a_id, dec.b_id, dec.frame)]
    assert [o.b_merged for o in pol.seen] == expected and any(expected) and not all(expected)


def test_sumo_in_lane_keeps_a_in_lane_6_and_restores_its_lane_changes(spec, sumo_run):
    """SUMO's driver with keep_lane: never leaves lane 6 while observed (the free SUMO driver
    does, on the same traffic, and is released there: ``left_lane``), not commanded, its
    lane-change mode restored at release."""
    from sim.runtime.run import run_scenario

    def out_of_lane(run_table, dec):
        lane = run_table.set_index(["Vehicle_ID", "Frame_ID"])["Lane_ID"]
        return int((lane.reindex(list(zip(dec.a_id, dec.frame))).to_numpy() != 6).sum())

    # the free driver leaves lane 6 (so the check below can fail); it is released there
    assert (sumo_run.controls.reason == "left_lane").any()
    assert out_of_lane(sumo_run.table, sumo_run.decisions) == 0
    kept = run_episode(spec, SumoPolicy("sumo-in-lane", keep_lane=True), SEED, duration_s=DURATION, keep_table=True)
    assert len(kept.decisions) > 20 and out_of_lane(kept.table, kept.decisions) == 0
    assert not (kept.controls.reason == "left_lane").any()
    assert not kept.controls.commanded.any()
    ctl = Controller(SumoPolicy("sumo-in-lane", keep_lane=True), ControllerConfig())
    probe = _Probe(ctl, remove_after=10**9)
    run_scenario(spec, seed=SEED, duration_s=DURATION, hooks=[ctl, probe])
    assert probe.modes, "no A was released while still in the simulation"
    for _reason, speed_now, lc_now, speed_saved, lc_before in probe.modes.values():
        assert lc_before >= 0 and lc_now == lc_before  # lane changes were off, and are back
        assert speed_saved == -1 and speed_now == 31  # the speed mode was never touched (SUMO's default)


class _Probe:
    """Runs after the controller: removes one controlled car, records the released cars' modes."""

    def __init__(self, ctl: Controller, remove_after: int = 5):
        self.ctl, self.remove_after = ctl, remove_after
        self.removed: str | None = None
        self.modes: dict[int, tuple] = {}
        self.steps_after_removal = 0

    def on_start(self, ctx):
        pass

    def on_step(self, ctx, frame):
        for c in self.ctl.controls:
            # (an A released and taken over again for the next B in the same frame is not released)
            again = any(o.active and o.a_id == c.a_id for o in self.ctl.controls)
            if not c.active and not again and c.a_id not in self.modes and c.a_sumo in frame.sumo_ids:
                self.modes[c.a_id] = (c.reason, libsumo.vehicle.getSpeedMode(c.a_sumo),
                                      libsumo.vehicle.getLaneChangeMode(c.a_sumo), c.speed_mode, c.lane_change_mode)
        if self.removed is None:
            for c in self.ctl.controls:
                if c.active and frame.frame - c.start_frame == self.remove_after:
                    # a plain remove: the runner holds no subscription that would break the next step
                    libsumo.vehicle.remove(c.a_sumo)
                    self.removed = c.a_sumo
                    break
        elif self.removed:
            self.steps_after_removal += 1

    def on_end(self, ctx):
        pass


def test_lead_car_c_is_a_s_lead_in_lane_6_other_than_b(uniform_run):
    """At every decision, C is ahead of A in lane 6 and no lane-6 car other than B is between them
    (as in every demonstration, where C leads the gap A-C that B merges into). The As are
    commanded, so they stay in lane 6."""
    table, dec = uniform_run.table, uniform_run.decisions
    assert len(dec) > 50 and (dec.c_id > 0).mean() > 0.9
    by_frame = {f: g for f, g in table[table.Lane_ID == 6].groupby("Frame_ID")}
    for r in dec[dec.c_id > 0].itertuples(index=False):
        lane6 = by_frame[r.frame].set_index("Vehicle_ID")["Local_Y"]
        y_a = lane6[r.a_id]
        assert r.d_AC > 0 and lane6[r.c_id] > y_a
        between = lane6[(lane6 > y_a) & (lane6 < lane6[r.c_id])].drop([r.b_id], errors="ignore")
        assert between.empty, (r.frame, r.a_id, r.c_id, between.to_dict())


def test_collision_and_removal_release_and_report(spec):
    """High Accel makes A run into its leader; one A is removed by hand; the run goes on."""
    from sim.runtime.run import run_scenario

    ctl = Controller(ConstantPolicy(4), ControllerConfig())
    probe = _Probe(ctl)
    # seed 5: the synthetic preset's IDM traffic has High-Accel As hitting their leaders early
    run_scenario(spec, seed=5, duration_s=DURATION, hooks=[ctl, probe])
    ct = ctl.control_table()
    reasons = ct.set_index("a_sumo").reason
    assert probe.removed is not None and reasons[probe.removed] == "removed"
    assert (ct.reason == "collision").sum() >= 1
    assert ctl.n_collisions >= 1
    # who hit whom: A accelerating at the cap runs into its lead car (C, or B once B merged ahead)
    kinds = ct.loc[ct.reason == "collision", "collision_kind"]
    assert set(kinds) <= set(COLLISION_KINDS) and kinds.isin(("A into C", "A into B")).any()
    assert (ct.loc[ct.reason != "collision", "collision_kind"] == "").all()
    # each collision that ended a control names its pair, one of the run's distinct pairs: A collisions,
    # counted by distinct pair, never exceed the run's
    pairs = ct.loc[ct.reason == "collision", "collision_pair"]
    assert all(p.count(">") == 1 and ct.a_sumo[i] in p.split(">") for i, p in pairs.items())
    assert {tuple(p.split(">")) for p in pairs} <= ctl.hand_over.collision_pairs
    assert (ct.loc[ct.reason != "collision", "collision_pair"] == "").all()
    # control went on after the removal: later take-overs happened
    removed_row = ct[ct.a_sumo == probe.removed].iloc[0]
    assert (ct.start_frame > removed_row.end_frame).any()
    assert probe.steps_after_removal > 100
    # released cars (collided ones included) got SUMO's own speed and lane-change modes back
    collided = [v for v in probe.modes.values() if v[0] == "collision"]
    assert collided
    for _reason, sm, lcm, sm0, lcm0 in probe.modes.values():
        assert (sm, lcm) == (sm0, lcm0)
        assert sm0 != 0 and lcm0 != 0
    assert all(r in RELEASE_REASONS for r in ct.reason)


def test_teleported_car_is_released_with_its_modes_back(spec):
    """High Brake with a long hold stops A on the main road; SUMO teleports it after 5 s."""
    from dataclasses import replace

    from sim.runtime.run import run_scenario

    quick = replace(spec, simulation=replace(spec.simulation, time_to_teleport_s=5.0))
    ctl = Controller(ConstantPolicy(0), ControllerConfig(hold_after_merge_s=120.0, max_control_s=120.0))
    probe = _Probe(ctl, remove_after=10**9)  # never removes: only records released cars' modes
    res = run_scenario(quick, seed=SEED, duration_s=DURATION, hooks=[ctl, probe])
    ct = ctl.control_table()
    tele = ct[ct.reason == "teleported"]
    assert len(tele) >= 1 and ctl.n_teleports >= len(tele)
    # the teleported car is back under SUMO's own modes (not left in speed mode 0)
    back = [probe.modes[a] for a in tele.a_id if a in probe.modes]
    assert back
    for reason, sm, lcm, sm0, lcm0 in back:
        assert reason == "teleported" and (sm, lcm) == (sm0, lcm0) and sm != 0
    # the run went on after the first teleport: recorded frames and later take-overs
    first = int(tele.end_frame.min())
    assert res.table.Frame_ID.max() > first + 100
    assert (ct.start_frame > first).any()


def test_same_seed_same_metrics_across_processes(spec):
    from analysis.evaluation.run import run_episodes

    kw = dict(duration_s=120.0)
    a, b, c = run_episodes([(spec, UniformPolicy(), 5, kw), (spec, UniformPolicy(), 5, kw),
                            (spec, UniformPolicy(), 6, kw)], workers=2, progress=False)
    from analysis.evaluation.report import metrics_to_json

    assert metrics_to_json(a.metrics.to_dict()) == metrics_to_json(b.metrics.to_dict())  # NaN-safe
    assert a.decisions.equals(b.decisions)
    assert a.metrics.n_controls > 0
    assert not a.decisions.equals(c.decisions)


def test_episodes_through_the_sweep_match_in_process_runs(spec, uniform_run):
    """Episodes run by the sweep runner (spawned worker, results through JSON) equal the same
    episodes run here; one worker runs two simulations one after the other."""
    from analysis.evaluation.episode import EpisodeResult
    from analysis.evaluation.report import metrics_to_json
    from analysis.evaluation.run import run_episodes

    back = EpisodeResult.from_dict(uniform_run.to_dict())  # JSON form keeps values and dtypes
    for name in ("controls", "decisions", "speed_profiles", "table"):
        pd_a, pd_b = getattr(back, name), getattr(uniform_run, name)
        assert list(pd_a.dtypes) == list(pd_b.dtypes) and pd_a.equals(pd_b), name
    kw = dict(duration_s=DURATION)
    a, b = run_episodes([(spec, UniformPolicy(), SEED, kw), (spec, ConstantPolicy(0), SEED, kw)],
                        executor="process:1", progress=False)
    assert metrics_to_json(a.metrics.to_dict()) == metrics_to_json(uniform_run.metrics.to_dict())
    assert a.decisions.equals(uniform_run.decisions) and a.controls.equals(uniform_run.controls)
    assert a.speed_profiles.equals(uniform_run.speed_profiles)
    assert b.metrics.policy != a.metrics.policy and b.metrics.n_controls > 0


@dataclass(frozen=True)
class HardBraker(PolicyDefaults):
    """High Brake at an acceleration no car has (-100 ft/s^2) every fourth decision, High Accel
    (+9 ft/s^2) otherwise; records what it saw."""

    name: str = "hard-braker"
    controls: bool = True
    decision_step_s: float | None = None
    seen: list = field(default_factory=list, compare=False)

    def probs(self, obs):
        self.seen.append(obs)
        return np.eye(5)[0 if len(self.seen) % 4 == 0 else 4]

    def acceleration(self, obs, action):
        return -100.0 if action == 0 else 9.0


def test_the_physical_actuation_caps_at_as_emergency_deceleration_and_the_observation_carries_acc_prev(spec):
    """The default actuation applies the driver's own acceleration, capped at A's emergencyDecel
    (SUMO's, of A's type: 9 m/s^2 cars, 7 trucks in this preset); the next observation's
    ``acc_prev`` is what was applied."""
    from merge_irl.units import FT_PER_M

    pol = HardBraker()
    ep = run_episode(spec, pol, SEED, duration_s=DURATION)
    dec = ep.decisions
    braked = dec[dec.action == 0]
    assert len(braked) >= 3
    limits = sorted({-t.emergency_decel * FT_PER_M for t in (*spec.drivers.car, *spec.drivers.truck)})
    assert all(min(abs(a - lim) for lim in limits) < 1e-6 for a in braked.acc_cmd)
    assert (dec.acc_cmd[dec.action == 4] == 9.0).all()
    # acc_prev of each A's next decision is the acceleration applied at its previous one
    prev: dict[int, float] = {}
    checked = 0
    for obs, row in zip(pol.seen, dec.itertuples()):
        if row.a_id in prev:
            assert obs.acc_prev == pytest.approx(prev[row.a_id])
            checked += 1
        prev[row.a_id] = row.acc_cmd
    assert checked >= 10


def test_the_take_over_is_an_object_the_controller_holds():
    from sim.closed_loop.controller import Controller
    from sim.closed_loop.handover import HandOver
    from sim.drivers.policy import UniformPolicy

    ctl = Controller(UniformPolicy())
    assert not issubclass(Controller, HandOver) and isinstance(ctl.hand_over, HandOver)
    assert ctl.controls is ctl.hand_over.controls and ctl.n_collisions == 0 == len(ctl.hand_over.active)
