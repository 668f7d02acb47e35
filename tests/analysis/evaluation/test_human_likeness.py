"""Human likeness in every report, on hand-made tables (no SUMO): emergency
brakings per controlled A with a Poisson interval, the As within 2 m of C (closed loop and
demonstrations), and W1 of A's per-frame acceleration and jerk."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from analysis.evaluation.aggregate import aggregate
from analysis.evaluation.human_likeness import (
    demo_acc_jerk,
    demo_close_to_c,
    frame_acc_jerk,
    min_gaps_to_c,
    w1_acc_jerk,
)
from analysis.evaluation.intervals import poisson_rate_ci95, rate_ci95
from analysis.evaluation.metrics import EpisodeMetrics, MetricsConfig, episode_metrics
from analysis.evaluation.report import HUMAN_COLUMNS, column_legend, human_table
from analysis.evaluation.thresholds import check_thresholds, parse_thresholds
from merge_irl.units import FT_PER_M
from sim.runtime.schema import COLUMNS

LEN = 15.0  # ft, every car's length


def _table(rows):
    df = pd.DataFrame(rows)
    for c in COLUMNS:
        if c not in df:
            df[c] = 0
    return df[list(COLUMNS)].astype(COLUMNS)


def _controls(rows):
    cols = ["a_id", "b_id", "a_sumo", "start_frame", "end_frame", "reason", "merge_frame", "b_ahead",
            "commanded", "gap_AB_start_ft", "n_decisions"]
    return pd.DataFrame(rows, columns=cols)


def _car(vid, frames, y, lane=6, v=40.0):
    return [dict(Vehicle_ID=vid, Frame_ID=f, Local_Y=yy, Lane_ID=ln, v_Vel=v, v_Length=LEN)
            for f, yy, ln in zip(frames, np.broadcast_to(y, len(frames)), np.broadcast_to(lane, len(frames)))]


def _scene():
    """Frames 0-9. A1 (controlled 0-5) behind C2: front-to-front 21 ft, bumper gap 6 ft = 1.83 m
    in frame 4 only (a front-to-front rule would never call that close; 20 ft elsewhere). A11
    (controlled 0-9) behind C12 at 21.9 ft front to front: bumper gap 6.9 ft = 2.10 m, not close;
    its B 13 is 3 ft ahead of it (B is not C), a car in lane 5 is 1 ft ahead (another lane), and C12
    comes within 1 ft in frame 9 only while A11 is in lane 5. A21 (controlled 0-3) comes within
    1 ft of its C in frame 7, after its control episode ended."""
    f = np.arange(10)
    rows = _car(1, f, 100.0)
    rows += _car(2, f, np.where(f == 4, 100.0 + LEN + 6.0, 100.0 + LEN + 20.0))
    rows += _car(11, f, 500.0, lane=np.where(f == 9, 5, 6))
    rows += _car(12, f, np.where(f == 9, 500.0 + LEN + 1.0, 500.0 + LEN + 6.9))
    rows += _car(13, f, 500.0 + LEN + 3.0 - 0.5, lane=np.where(f < 2, 7, 6))  # B: behind C12, 3 ft ahead of A11
    rows += _car(14, f, 500.0 + LEN + 1.0, lane=5)
    rows += _car(21, f, 900.0)
    rows += _car(22, f, np.where(f == 7, 900.0 + LEN + 1.0, 900.0 + LEN + 30.0))
    return _table(rows)


def test_poisson_interval_is_garwoods_exact_interval():
    # the textbook exact 95 % limits: 0 events -> [0, 3.689]; 5 -> [1.623, 11.668]; 1 -> [0.0253, 5.572]
    assert poisson_rate_ci95(0, 10) == pytest.approx((0.0, 0.0, 0.3689), abs=1e-4)
    assert poisson_rate_ci95(5, 1) == pytest.approx((5.0, 1.6235, 11.6683), abs=1e-4)
    assert poisson_rate_ci95(1, 2) == pytest.approx((0.5, 0.02532 / 2, 5.5716 / 2), abs=1e-4)
    # more events than units: a rate above 1 (a share's interval would stop at 1)
    rate, lo, hi = poisson_rate_ci95(30, 10)
    assert rate == 3.0 and 2.0 < lo < 3.0 < hi < 4.5
    assert all(math.isnan(x) for x in poisson_rate_ci95(0, 0))
    with pytest.raises(ValueError):
        poisson_rate_ci95(-1, 5)


def test_min_gap_to_c_is_bumper_to_bumper_to_c_in_the_merge_lane_while_controlled():
    t = _scene()
    wins = [(1, 99, 0, 5), (11, 13, 0, 9), (21, 98, 0, 3)]
    gaps = min_gaps_to_c(t, wins, merge_lane=6)
    assert gaps == pytest.approx([6.0, 6.9, 30.0])
    assert min_gaps_to_c(t, [(1, 99, 5, 9)], merge_lane=6) == pytest.approx([20.0])  # frame 4 outside
    # another merge lane: A1 is never in it, so it has no C there
    assert np.isinf(min_gaps_to_c(t, [(1, 99, 0, 9)], merge_lane=5)).all()
    assert min_gaps_to_c(t, [], merge_lane=6).shape == (0,)


def test_episode_counts_the_controlled_as_within_2_m_of_c():
    t = _scene()
    controls = _controls([(1, 99, "a", 0, 5, "timeout", -1, None, True, 30.0, 2),
                          (11, 13, "b", 0, 9, "timeout", -1, None, True, 30.0, 2),
                          (21, 98, "c", 0, 3, "timeout", -1, None, True, 30.0, 2)])
    decisions = pd.DataFrame({"frame": [0], "a_id": [1], "action": [2]})
    m = episode_metrics(t, controls, decisions, policy="p", seed=0, section_length_ft=2000.0)
    assert m.close_to_c == 1  # A1 only: 1.83 m
    # 2.2 m: A11's 2.10 m counts too; 1.5 m: none
    wide = episode_metrics(t, controls, decisions, policy="p", seed=0, section_length_ft=2000.0,
                           config=MetricsConfig(close_gap_m=2.2))
    narrow = episode_metrics(t, controls, decisions, policy="p", seed=0, section_length_ft=2000.0,
                             config=MetricsConfig(close_gap_m=1.5))
    assert (wide.close_to_c, narrow.close_to_c) == (2, 0)
    # a stored episode without the field reads as 0
    d = m.to_dict()
    del d["close_to_c"]
    assert EpisodeMetrics.from_dict(d).close_to_c == 0


def test_demonstrations_within_2_m_of_c_share_by_encounter():
    enc = pd.DataFrame({
        "encounter_id": [1, 1, 2, 2, 3, 4, 5, 5],
        "d_AC": [40.0, 21.0, 22.0, 22.0, np.nan, 3.0, 30.0, 6.0],
        # 1: 21 - 15 = 6 ft = 1.83 m (close; front to front 6.4 m); 2: 7 ft = 2.13 m (not);
        # 3: no C; 4: no length, not counted; 5: 6 - 15 < 0 ft, A into C (close)
        "len_C": [15.0, 15.0, 15.0, 15.0, np.nan, np.nan, 15.0, 15.0],
    })
    d = demo_close_to_c(enc)
    assert (d.n_close, d.n_encounters) == (2, 5)
    assert (d.rate, *d.ci95) == pytest.approx(rate_ci95(2, 5))
    assert d.to_dict()["close_to_c"] == 2 and d.to_dict()["close_gap_m"] == 2.0
    assert demo_close_to_c(enc, gap_m=2.2).n_close == 3
    no_len = demo_close_to_c(enc.drop(columns="len_C"))
    assert no_len.n_encounters == 5 and math.isnan(no_len.rate)


def test_per_frame_acceleration_and_jerk_of_the_speed_profiles():
    # v(t) = 50 + 3 t - 2 t^2 ft/s: forward differences over 0.1 s give acc 3 - 4 (t + 0.05) ft/s^2
    # and jerk -4 ft/s^3 exactly; two take-overs of the same A (t_s restarts) and a missing frame
    t = np.round(np.arange(6) * 0.1, 10)
    v = 50 + 3 * t - 2 * t ** 2
    sp = pd.DataFrame({"a_id": [7] * 6 + [7] * 4 + [8] * 3,
                       "t_s": [*t, 0.0, 0.1, 0.3, 0.4, 0.0, 0.1, 0.2],
                       "v_ft_s": [*v, 10.0, 11.0, 30.0, 31.0, 20.0, 20.0, 20.0]})
    acc, jerk = frame_acc_jerk([sp, sp.iloc[:0]])
    # 5 + 1 + 1 + 2 accelerations (not across the restart, the gap or the next A); 4 + 0 + 0 + 1 jerks
    assert acc.size == 9 and jerk.size == 5
    assert acc[:5] == pytest.approx((3 - 4 * (t[:5] + 0.05)) / FT_PER_M)
    assert acc[5:] == pytest.approx(np.array([10.0, 10.0, 0.0, 0.0]) / FT_PER_M)
    assert jerk == pytest.approx(np.array([-4.0, -4.0, -4.0, -4.0, 0.0]) / FT_PER_M)
    empty = frame_acc_jerk([])
    assert empty[0].size == 0 and empty[1].size == 0


def test_demonstration_jerk_is_per_consecutive_frame_within_an_encounter():
    enc = pd.DataFrame({"encounter_id": [2, 1, 1, 1, 1, 2], "Frame_ID": [51, 13, 10, 11, 12, 50],
                        "acc_A": [5.0, 1.3, 1.0, 1.1, 1.0, 3.0]})
    acc, jerk = demo_acc_jerk(enc)
    assert sorted(acc) == pytest.approx(sorted(enc["acc_A"] / FT_PER_M))
    # encounter 1 by frame: 1.0, 1.1, 1.0, 1.3 -> +1, -1, +3 ft/s^3; encounter 2: +20; none across
    assert jerk == pytest.approx(np.array([1.0, -1.0, 3.0, 20.0]) / FT_PER_M)
    enc_gap = enc.assign(Frame_ID=[51, 14, 10, 11, 12, 50])  # frame 13 -> 14: one jerk fewer
    assert demo_acc_jerk(enc_gap)[1].size == 3
    assert demo_acc_jerk(enc.drop(columns="Frame_ID"))[1].size == 0


def test_w1_of_acceleration_and_jerk_against_the_demonstrations():
    t = np.round(np.arange(30) * 0.1, 10)
    sp = pd.DataFrame({"a_id": 1, "t_s": t, "v_ft_s": 40 + 2 * t})  # 2 ft/s^2, jerk 0
    same = pd.DataFrame({"encounter_id": 1, "Frame_ID": np.arange(29), "acc_A": 2.0})
    w = w1_acc_jerk([sp], same)
    assert w == pytest.approx({"w1_acc_A_m_s2": 0.0, "w1_jerk_A_m_s3": 0.0}, abs=1e-9)
    # demonstrations alternating 1 and 3 ft/s^2: acc W1 = 1 ft/s^2, jerk +-20 ft/s^3 -> W1 20 ft/s^3
    alt = same.assign(acc_A=np.where(np.arange(29) % 2, 3.0, 1.0))
    w = w1_acc_jerk([sp], alt)
    assert w["w1_acc_A_m_s2"] == pytest.approx(1.0 / FT_PER_M, rel=1e-6)
    assert w["w1_jerk_A_m_s3"] == pytest.approx(20.0 / FT_PER_M, rel=1e-6)
    assert all(math.isnan(x) for x in w1_acc_jerk([], alt).values())


def _ep(seed, n_controls, brakings, close):
    return EpisodeMetrics("p", seed, n_controls, 0, 0, 0, 0, brakings, brakings, 5.0, float("nan"), float("nan"),
                          float("nan"), (1, 0, 0, 0, 0), float("nan"), close_to_c=close)


def test_aggregate_rates_per_controlled_a_and_the_human_table():
    agg = aggregate([_ep(1, 10, 7, 1), _ep(2, 30, 5, 2)],
                    w1={"w1_acc_A_m_s2": 0.25, "w1_jerk_A_m_s3": 3.5, "w1_ttc_s": 1.0})
    assert agg.emergency_brakings == 12 and agg.n_controls == 40
    assert (agg.emergency_braking_rate, *agg.emergency_braking_ci95) == pytest.approx(poisson_rate_ci95(12, 40))
    assert (agg.close_to_c, agg.close_to_c_rate) == (3, 3 / 40)
    assert agg.close_to_c_ci95 == pytest.approx(rate_ci95(3, 40)[1:])
    assert (agg.w1_acc_A_m_s2, agg.w1_jerk_A_m_s3, agg.w1_ttc_s) == (0.25, 3.5, 1.0)
    none = aggregate([_ep(1, 0, 0, 0)])
    assert math.isnan(none.emergency_braking_rate) and math.isnan(none.close_to_c_rate)
    assert math.isnan(none.w1_jerk_A_m_s3)
    d = agg.to_dict()
    for k in ("emergency_braking_rate", "emergency_braking_ci95", "close_to_c", "close_to_c_rate",
              "close_to_c_ci95", "w1_acc_A_m_s2", "w1_jerk_A_m_s3"):
        assert k in d
    # the new names are gate metrics
    breaches = check_thresholds(parse_thresholds("close_to_c_rate>0.05, w1_jerk_A_m_s3>=3.5, "
                                                 "emergency_braking_rate>1"), {"p": d})
    assert [b.threshold.metric for b in breaches] == ["close_to_c_rate", "w1_jerk_A_m_s3"]

    demos = demo_close_to_c(pd.DataFrame({"encounter_id": [1, 2], "d_AC": [20.0, 50.0], "len_C": [15.0, 15.0]}))
    table = human_table({"p": agg}, demos, close_gap_m=2.0)
    lines = table.splitlines()
    headers = [h.strip() for h in lines[0].strip("|").split("|")]
    assert headers == ["policy", "As controlled", "emergency brakings near A per A [95 % CI]",
                       "emergency brakings by A / B / A's follower", "A into C / A into B",
                       "As within 2 m of C [95 % CI]", "W1 acc (m/s^2)", "W1 jerk (m/s^3)"]
    lo, hi = poisson_rate_ci95(12, 40)[1:]
    assert lines[2].startswith("| demonstrations | 2 | - | - | - | 1/2 = 0.500 [")
    assert lines[3] == (f"| p | 40 | 12/40 = 0.300 [{lo:.3f}, {hi:.3f}] | 0 / 0 / 0 | 0 / 0 | 3/40 = 0.075 "
                        f"[{agg.close_to_c_ci95[0]:.3f}, {agg.close_to_c_ci95[1]:.3f}] | 0.25 | 3.50 |")
    assert "demonstrations" not in human_table({"p": agg})
    legend = column_legend(HUMAN_COLUMNS, emergency_decel_m_s2=4.5, close_gap_m=1.5)
    entries = [e.split(" = ", 1)[0] for e in legend.removeprefix("Columns: ").rstrip(".").split("; ")]
    assert entries[5] == "As within 1.5 m of C [95 % CI]" and "{" not in legend and "4.5 m/s^2" in legend
