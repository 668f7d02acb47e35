"""analysis/evaluation/closed_loop_targets.py: the closed-loop target checks (which
``studies/closed_loop_target.py`` prints), on hand-made aggregates: the Wasserstein targets are
judged against the demonstrators' own driver, and a figure that could not be measured fails."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from sim.merges.rules import ENCOUNTER_RULES
from studies.support.closed_loop_targets import floor_driver, target_checks


def _agg(collisions=0, ll=float("nan"), speed=1.0, d_ac=10.0):
    return SimpleNamespace(a_collisions=collisions, n_controls=100, a_collision_ci95=(0.0, 0.037),
                           heldout_loglik_per_step=ll, w1_speed_A_ft_s=speed, w1_d_AC_ft=d_ac)


def test_the_floor_is_the_demonstrators_driver():
    assert floor_driver("in-lane") == "sumo-in-lane"  # A's lane held while observed, as in the demonstrations
    assert {floor_driver(r) for r in ENCOUNTER_RULES if r != "in-lane"} == {"sumo"}


@pytest.mark.parametrize("floor, met", [("sumo-in-lane", [True, True, True, True]),
                                        ("sumo", [True, True, True, False])])
def test_target_checks_against_the_floor(floor, met):
    # d_AC 30 ft: within 1.5x sumo-in-lane's 24 ft, not within 1.5x sumo's 12 ft
    aggs = {"cf-dagger": _agg(ll=-0.7, speed=3.0, d_ac=30.0), "sumo": _agg(speed=2.5, d_ac=12.0),
            "sumo-in-lane": _agg(speed=2.5, d_ac=24.0), "marginal": _agg(ll=-1.4), "bc": _agg(ll=-1.2)}
    checks = target_checks("cf-dagger", aggs, floor)
    assert [ok for _, ok in checks] == met
    assert all(floor in text for text, _ in checks[2:])
    aggs["cf-dagger"] = _agg(collisions=1, ll=-1.3, speed=4.0, d_ac=30.0)  # bc scores better held out
    assert [ok for _, ok in target_checks("cf-dagger", aggs, floor)] == [False, False, False, met[3]]


def test_a_figure_not_measured_fails_its_check():
    aggs = {"cf-dagger": _agg(ll=float("nan"), speed=float("nan"), d_ac=10.0), "sumo": _agg(),
            "marginal": _agg(ll=-1.4), "bc": _agg(ll=-1.2)}
    assert [ok for _, ok in target_checks("cf-dagger", aggs)] == [True, False, False, True]
    with pytest.raises(KeyError):
        target_checks("cf-dagger", {k: v for k, v in aggs.items() if k != "bc"})
