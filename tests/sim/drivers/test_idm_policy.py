"""The IDM reference driver (sim/drivers/idm.py): its acceleration against the IDM formula
worked by hand, the action it picks, and its parameters taken from a scenario."""

import math

import numpy as np
import pytest

from irl.domains.merge.car_following import GapNeed
from merge_irl.units import FT_PER_M
from scenarios.loader import load_scenario
from sim.drivers.idm import IdmPolicy
from sim.drivers.observe import MergeObservation


def _obs(speed, d_ac=math.nan, v_ac=math.nan):
    return MergeObservation(d_AC=d_ac, d_AB=-50.0, v_AC=v_ac, v_AB=0.0, b_is_truck=False, speed_A=speed)


def test_acceleration_is_the_idm_formula():
    need = GapNeed(min_gap_ft=6.0, time_headway_s=1.5, accel_ft_s2=4.0, decel_ft_s2=9.0, desired_speed_ft_s=100.0,
                   length_ft=15.0, clip=1000.0)
    idm = IdmPolicy(gap_need=need)
    assert idm.idm_acceleration(_obs(0.0)) == pytest.approx(4.0)  # free road from standstill: a_max
    assert idm.idm_acceleration(_obs(100.0)) == pytest.approx(0.0)  # at the desired speed
    # 50 ft/s, C 75 ft ahead front to front (60 ft bumper gap), closing at 10 ft/s:
    # s* = 6 + 50 x 1.5 + 50 x 10 / (2 sqrt(4 x 9)) = 6 + 75 + 500 / 12
    s_star = 6 + 75 + 500 / 12
    expected = 4.0 * (1 - 0.5 ** 4 - (s_star / 60.0) ** 2)
    assert idm.idm_acceleration(_obs(50.0, 75.0, 10.0)) == pytest.approx(expected)
    assert expected < -4.8  # so it brakes hard
    p = idm.probs(_obs(50.0, 75.0, 10.0))
    np.testing.assert_array_equal(p, [1, 0, 0, 0, 0])
    # far lead car, standstill: a_max, 4 ft/s^2, is in the Low Accel bin (0.6 to 4.8)
    np.testing.assert_array_equal(idm.probs(_obs(0.0, 2000.0, 0.0)), [0, 0, 0, 1, 0])
    # a 40-ft truck C observed with its length: the bumper gap is 35 ft, not 60
    truck = MergeObservation(d_AC=75.0, d_AB=-50.0, v_AC=10.0, v_AB=0.0, b_is_truck=False, speed_A=50.0, len_C=40.0)
    assert idm.idm_acceleration(truck) == pytest.approx(4.0 * (1 - 0.5 ** 4 - (s_star / 35.0) ** 2))


def test_from_scenario_takes_the_car_type():
    spec = load_scenario("synthetic")
    car = spec.drivers.car[0]
    g = IdmPolicy.from_scenario(spec, name="idm-syn").gap_need
    assert g.min_gap_ft == pytest.approx(car.min_gap_m * FT_PER_M) and g.time_headway_s == car.tau
    assert g.accel_ft_s2 == pytest.approx(car.accel * FT_PER_M) and g.decel_ft_s2 == pytest.approx(car.decel * FT_PER_M)
    assert g.desired_speed_ft_s == pytest.approx(min(car.max_speed_mps, spec.road.speed_limit_mps * car.speed_factor)
                                                 * FT_PER_M)
    assert IdmPolicy.from_scenario(spec, name="idm-syn").name == "idm-syn"


def test_b_is_the_leader_once_it_has_merged_ahead_and_nearer_than_c():
    idm = IdmPolicy.from_scenario(load_scenario("synthetic"))
    g = idm.gap_need

    def obs(d_ab, merged, d_ac=300.0):
        return MergeObservation(d_AC=d_ac, d_AB=d_ab, v_AC=0.0, v_AB=8.0, b_is_truck=False, speed_A=60.0,
                                b_merged=merged)

    free = 1 - (60.0 / g.desired_speed_ft_s) ** 4
    towards_c = g.accel_ft_s2 * (free - float(g.need(300.0, 60.0, 0.0)))
    towards_b = g.accel_ft_s2 * (free - float(g.need(60.0, 60.0, 8.0)))
    assert idm.idm_acceleration(obs(60.0, True)) == pytest.approx(towards_b) and towards_b < towards_c - 5
    assert idm.idm_acceleration(obs(60.0, False)) == pytest.approx(towards_c)  # B still on the ramp: not followed
    assert idm.idm_acceleration(obs(-20.0, True)) == pytest.approx(towards_c)  # merged behind A
    assert idm.idm_acceleration(obs(60.0, True, d_ac=40.0)) == pytest.approx(
        g.accel_ft_s2 * (free - float(g.need(40.0, 60.0, 0.0))))  # C nearer than B
    no_c = MergeObservation(d_AC=float("nan"), d_AB=60.0, v_AC=float("nan"), v_AB=8.0, b_is_truck=False,
                            speed_A=60.0, b_merged=True)
    assert idm.idm_acceleration(no_c) == pytest.approx(towards_b)
    # the leader's own length: B's once B leads, C's otherwise
    lengths = dict(d_AC=300.0, d_AB=60.0, v_AC=0.0, v_AB=8.0, b_is_truck=True, speed_A=60.0, len_C=14.0, len_B=39.0)
    assert idm.idm_acceleration(MergeObservation(**lengths, b_merged=True)) == pytest.approx(
        g.accel_ft_s2 * (free - float(g.need(60.0, 60.0, 8.0, 39.0))))
    assert idm.idm_acceleration(MergeObservation(**lengths, b_merged=False)) == pytest.approx(
        g.accel_ft_s2 * (free - float(g.need(300.0, 60.0, 0.0, 14.0))))
