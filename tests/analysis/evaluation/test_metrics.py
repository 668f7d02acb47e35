"""Closed-loop metrics on hand-made tables (no SUMO)."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from analysis.evaluation.aggregate import aggregate
from analysis.evaluation.distances import js_divergence
from analysis.evaluation.metrics import EpisodeMetrics, MetricsConfig, episode_metrics
from irl.boltzmann import heldout_loglik
from merge_irl.units import FT_PER_M
from sim.runtime.schema import COLUMNS


def _table(rows):
    """rows: dicts with Vehicle_ID, Frame_ID, Local_Y, v_Vel, v_Acc, Lane_ID, Preceding, Following, v_Length."""
    df = pd.DataFrame(rows)
    for c in COLUMNS:
        if c not in df:
            df[c] = 0
    df["Global_X"] = df["Local_Y"]
    return df[list(COLUMNS)].astype(COLUMNS)


def _controls(rows):
    cols = ["a_id", "b_id", "a_sumo", "start_frame", "end_frame", "reason", "merge_frame", "b_ahead",
            "commanded", "gap_AB_start_ft", "n_decisions"]
    return pd.DataFrame(rows, columns=cols)


def _decisions(actions, a_id=1):
    return pd.DataFrame({"frame": np.arange(len(actions)), "a_id": a_id, "action": actions})


def _scene(v_follow=60.0, v_a=50.0, v_lead=55.0, acc_a=-2.0, n=20, section=400.0):
    """Follower 3 behind A (1) behind leader 2, all in lane 6; A crosses the whole section."""
    rows = []
    for f in range(n):
        rows.append(dict(Vehicle_ID=1, Frame_ID=f, Local_Y=f * section / (n - 1), v_Vel=v_a, v_Acc=acc_a,
                         Lane_ID=6, Preceding=2, Following=3, v_Length=15.0))
        rows.append(dict(Vehicle_ID=2, Frame_ID=f, Local_Y=f * section / (n - 1) + 65.0, v_Vel=v_lead, v_Acc=0.0,
                         Lane_ID=6, Preceding=0, Following=1, v_Length=15.0))
        rows.append(dict(Vehicle_ID=3, Frame_ID=f, Local_Y=f * section / (n - 1) - 40.0, v_Vel=v_follow, v_Acc=0.0,
                         Lane_ID=6, Preceding=1, Following=0, v_Length=15.0))
        rows.append(dict(Vehicle_ID=4, Frame_ID=f, Local_Y=f * section / (n - 1) + 30.0, v_Vel=v_a, v_Acc=0.0,
                         Lane_ID=7 if f < 10 else 6, Preceding=0, Following=0, v_Length=15.0))
    return _table(rows)


def test_js_divergence_properties():
    p = np.array([3, 1, 0, 0, 0])
    assert js_divergence(p, p) == 0.0
    assert js_divergence(p, 2 * p) == pytest.approx(0.0)
    assert js_divergence([1, 0, 0, 0, 0], [0, 0, 0, 0, 1]) == pytest.approx(1.0)
    a, b = np.array([1.0, 2, 3, 4, 5]), np.array([5.0, 1, 1, 1, 1])
    assert js_divergence(a, b) == pytest.approx(js_divergence(b, a))
    assert 0 < js_divergence(a, b) < 1
    assert math.isnan(js_divergence(np.zeros(5), a))


def test_heldout_loglik_is_a_sum_of_log_probabilities():
    rng = np.random.default_rng(0)
    lp = np.log(rng.dirichlet(np.ones(5), size=7))
    s, a = rng.integers(0, 7, 30), rng.integers(0, 5, 30)
    total, per = heldout_loglik(lp, s, a)
    assert total == pytest.approx(sum(lp[i, j] for i, j in zip(s, a)))
    assert per == pytest.approx(total / 30)


def test_episode_metrics_on_a_hand_made_scene():
    t = _scene()
    controls = _controls([(1, 4, "a", 0, 19, "merge_done", 10, True, True, 30.0, 7)])
    m = episode_metrics(t, controls, _decisions([0, 1, 1, 2, 2, 2, 4]), policy="p", seed=1,
                        section_length_ft=400.0, collisions=2, teleports=0,
                        demo_action_counts=np.array([1, 2, 3, 0, 1]))
    assert m.action_counts == (1, 2, 3, 0, 1)
    assert m.js_divergence == pytest.approx(0.0)
    assert m.n_controls == 1 and m.n_merges == 1 and m.b_ahead_rate == 1.0
    assert m.collisions == 2 and m.a_collisions == 0
    # TTC: A (50 ft/s) is not closing on its leader (55); follower 3 closes on A at 10 ft/s,
    # gap = 40 - 15 = 25 ft -> 2.5 s
    assert m.min_ttc_s == pytest.approx(2.5)
    # travel time: A spans 0..400 ft over 19 frames
    assert m.travel_time_s == pytest.approx(1.9)
    assert m.emergency_brakings == 0 and m.emergency_brakings_all == 0
    assert m.release_reasons == {"merge_done": 1}


def test_emergency_braking_counts_runs_near_a_only_while_controlled():
    t = _scene(acc_a=-2.0)
    thr = -4.5 * FT_PER_M
    # A brakes hard on frames 3-5 (one event) and 8 (another); the follower on frame 12;
    # a far vehicle (4 after its merge) brakes hard too, and A again after the window
    t.loc[(t.Vehicle_ID == 1) & t.Frame_ID.isin([3, 4, 5, 8, 18]), "v_Acc"] = thr - 1
    t.loc[(t.Vehicle_ID == 3) & (t.Frame_ID == 12), "v_Acc"] = thr - 0.5
    t.loc[(t.Vehicle_ID == 4) & (t.Frame_ID == 15), "v_Acc"] = -40.0  # beyond 9 m/s^2 too
    controls = _controls([(1, 2, "a", 0, 14, "timeout", -1, None, True, 30.0, 3)])
    m = episode_metrics(t, controls, _decisions([0, 0, 0]), policy="p", seed=0, section_length_ft=400.0)
    assert m.emergency_brakings == 3  # A twice in the window + the follower; B=2 never
    assert (m.emergency_brakings_A, m.emergency_brakings_B, m.emergency_brakings_follower) == (2, 0, 1)
    assert m.emergency_brakings_all == 5
    assert m.n_merges == 0 and math.isnan(m.b_ahead_rate)
    # a stricter threshold counts nothing
    m2 = episode_metrics(t, controls, _decisions([0]), policy="p", seed=0, section_length_ft=400.0,
                         config=MetricsConfig(emergency_decel_m_s2=9.0))
    assert m2.emergency_brakings == 0 and m2.emergency_brakings_all == 1


def test_aggregate_over_seeds():
    def ep(seed, ahead, n_merges, tt, counts):
        return EpisodeMetrics("p", seed, 3, n_merges, 1, 0, 0, 2, 5, 1.5 + seed, ahead, tt, 50.0, counts, 0.1)

    eps = [ep(0, 1.0, 2, 20.0, (1, 0, 0, 0, 1)), ep(1, 0.0, 2, float("nan"), (0, 2, 0, 0, 0)),
           ep(2, 0.5, 4, 30.0, (0, 0, 0, 3, 0))]
    a = aggregate(eps, demo_action_counts=np.array([1, 2, 0, 3, 1]), heldout=(-10.0, -0.5))
    assert a.n_episodes == 3 and a.n_merges == 8 and a.collisions == 3 and a.emergency_brakings == 6
    assert a.b_ahead_rate[0] == pytest.approx((2 * 1.0 + 0 + 4 * 0.5) / 8)
    assert a.travel_time_s[0] == pytest.approx(25.0)  # NaN episode skipped
    assert a.min_ttc_s == 1.5
    assert a.action_counts == (1, 2, 0, 3, 1)
    assert a.js_divergence == pytest.approx(0.0)
    assert a.heldout_loglik_per_step == -0.5
    with pytest.raises(ValueError):
        aggregate([ep(0, 1.0, 1, 1.0, (1, 0, 0, 0, 0)), EpisodeMetrics(
            "q", 0, 0, 0, 0, 0, 0, 0, 0, 1.0, 0.0, 0.0, 0.0, (0,) * 5, 0.0)])


def test_episode_metrics_round_trip_dict():
    m = EpisodeMetrics("p", 1, 2, 1, 0, 0, 0, 0, 0, float("inf"), 1.0, float("nan"), 3.0, (1, 2, 3, 4, 5), 0.2,
                       {"merge_done": 2})
    back = EpisodeMetrics.from_dict(m.to_dict())
    assert back.action_counts == m.action_counts and back.release_reasons == m.release_reasons
    assert math.isnan(back.travel_time_s)


def test_a_collisions_are_counted_apart_by_who_ran_into_whom():
    import pandas as pd

    from analysis.evaluation.metrics import _a_collisions

    controls = pd.DataFrame({
        "reason": ["collision", "collision", "collision", "timeout", "collision"],
        "collision_kind": ["A into C", "A into B", "A into C", "", "B into A"],
        "collision_pair": ["1>2", "1>3", "1>2", "", "3>1"],  # the same pair seen again counts once
    })
    assert _a_collisions(controls) == 3
    assert _a_collisions(controls, "A into C") == 1 and _a_collisions(controls, "A into B") == 1
    assert _a_collisions(controls.drop(columns="collision_kind"), "A into C") == 0


@pytest.mark.parametrize("decel_m_s2,counted", [(4.5, False), (4.52, False), (4.6, True)])
@pytest.mark.parametrize("role", ["A", "B", "follower"])
def test_braking_at_exactly_the_threshold_is_not_an_emergency_beyond_it_is_under_its_role(role, decel_m_s2,
                                                                                        counted):
    """SUMO's normal maximum, 4.5 m/s^2, goes through ft/s^2 and lands a hair below -4.5: not
    counted (nor within the 0.05 m/s^2 tolerance); 4.6 m/s^2 is, under the braking car's role."""
    t = _scene(acc_a=0.0)
    car = {"A": 1, "B": 4, "follower": 3}[role]
    acc_ft = -decel_m_s2 * FT_PER_M * (1 + 1e-12)  # a hair below, as SUMO's table has it
    t.loc[(t.Vehicle_ID == car) & t.Frame_ID.isin([5, 6]), "v_Acc"] = acc_ft
    controls = _controls([(1, 4, "a", 0, 19, "merge_done", 10, True, True, 30.0, 7)])
    m = episode_metrics(t, controls, _decisions([2]), policy="p", seed=0, section_length_ft=400.0)
    by_role = {"A": m.emergency_brakings_A, "B": m.emergency_brakings_B, "follower": m.emergency_brakings_follower}
    assert by_role == {r: int(counted and r == role) for r in by_role}
    assert m.emergency_brakings == sum(by_role.values()) == m.emergency_brakings_all == int(counted)
    # without a tolerance the hair below -4.5 counts again (what the tolerance is for)
    loose = episode_metrics(t, controls, _decisions([2]), policy="p", seed=0, section_length_ft=400.0,
                            config=MetricsConfig(emergency_tolerance_m_s2=0.0))
    assert loose.emergency_brakings == 1


def test_the_emergency_tolerance_is_checked():
    with pytest.raises(ValueError, match="emergency_tolerance_m_s2"):
        MetricsConfig(emergency_tolerance_m_s2=-0.1)
