"""The evaluation report reads right: A collisions never above all collisions,
a legend generated from the columns shown, and what a few episodes can bound."""

from __future__ import annotations

import re

import numpy as np
import pandas as pd
import pytest

from analysis.evaluation.aggregate import aggregate, rate_ci95
from analysis.evaluation.metrics import EpisodeMetrics, MetricsConfig, episode_metrics
from analysis.evaluation.report import COLUMNS, collision_bound_line, collision_count_lines, column_legend, report_table


def _controls(rows):
    cols = ("a_id", "b_id", "a_sumo", "start_frame", "end_frame", "reason", "merge_frame", "b_ahead", "commanded",
            "gap_AB_start_ft", "n_decisions", "n_interventions", "n_need_brakes", "collision_kind", "collision_pair")
    return pd.DataFrame([dict(zip(cols, r)) for r in rows], columns=list(cols))


def _table():
    return pd.DataFrame({"Vehicle_ID": [1, 1, 2, 2], "Frame_ID": [10, 11, 10, 11], "v_Acc": 0.0, "v_Vel": 30.0,
                         "Local_Y": [100.0, 103.0, 50.0, 53.0], "Following": 0, "Preceding": 0, "v_Length": 15.0,
                         "Lane_ID": 6})


def test_a_pair_that_ends_two_take_overs_of_the_same_a_counts_once():
    # A (SUMO id "m.7") collides with "r.3"; SUMO (collision action warn) keeps them overlapping, a later
    # take-over of the same A ends at once on the same pair: one collision in the run, one of A
    controls = _controls([
        (1, 5, "m.7", 10, 11, "collision", -1, None, True, 40.0, 2, 0, 0, "A into other", "m.7>r.3"),
        (1, 6, "m.7", 11, 11, "collision", -1, None, True, 35.0, 0, 0, 0, "A into other", "m.7>r.3"),
        (2, 8, "m.9", 10, 11, "collision", -1, None, True, 30.0, 1, 0, 0, "other into A", "r.4>m.9"),
        (2, 9, "m.9", 11, 11, "merge_done", 11, True, True, 30.0, 1, 0, 0, "", ""),
    ])
    decisions = pd.DataFrame({"action": [2, 2, 1, 3]})
    m = episode_metrics(_table(), controls, decisions, policy="p", seed=1, section_length_ft=2000.0,
                        collisions=2, config=MetricsConfig())
    assert m.a_collisions == 2 <= m.collisions
    assert m.release_reasons["collision"] == 3  # the control episodes themselves are all kept
    agg = aggregate([m, m])
    assert (agg.collisions, agg.a_collisions) == (4, 4)
    assert "| 4 / 4 |" in report_table({"p": agg})


def test_the_legend_describes_exactly_the_columns_of_the_table():
    ep = EpisodeMetrics("qavg", 1, 12, 4, 0, 0, 0, 0, 0, 5.0, 1.0, 20.0, 60.0, (1, 0, 0, 0, 0), 0.1)
    table = report_table({"qavg": aggregate([ep])})
    headers = [h.strip() for h in table.splitlines()[0].strip("|").split("|")]
    legend = column_legend(emergency_decel_m_s2=4.5)
    entries = [e.split(" = ", 1)[0] for e in legend.removeprefix("Columns: ").rstrip(".").split("; ")]
    assert entries == headers == [c.header for c in COLUMNS]
    assert "JS divergence" not in legend and "4.5 m/s^2" in legend
    # a table of fewer columns has the legend of those columns
    assert column_legend(COLUMNS[:2]).count(" = ") == 2


def test_what_a_few_episodes_can_bound_is_computed_from_the_count():
    def agg(n_controls, episodes=3):
        eps = [EpisodeMetrics("p", s, n_controls // episodes, 0, 0, 0, 0, 0, 0, 5.0, np.nan, np.nan, np.nan,
                              (0,) * 5, np.nan) for s in range(episodes)]
        return aggregate(eps)

    line = collision_bound_line({"a": agg(33), "b": agg(60)})
    high = rate_ci95(0, 33)[2]
    assert f"below {high:.1%}" in line and "3 episode(s)" in line and "0 A collisions in 33 As" in line
    assert "3/33 = 9.1%" in line
    assert re.search(r"below 10\.\d%", line)  # Wilson's bound for 0/33 is 10.4 %
    assert collision_bound_line({"a": agg(0)}) == ""
    assert rate_ci95(0, 300)[2] == pytest.approx(0.0126, abs=5e-4)  # more As bound it tighter


def test_the_collision_counts_are_one_count_with_the_others_reconciled():
    controls = _controls([
        (1, 5, "m.7", 10, 11, "collision", -1, None, True, 40.0, 2, 0, 0, "A into C", "m.7>r.3"),
        (1, 6, "m.7", 11, 11, "collision", -1, None, True, 35.0, 0, 0, 0, "A into C", "m.7>r.3"),
        (2, 8, "m.9", 10, 11, "collision", -1, None, True, 30.0, 1, 0, 0, "A into B", "m.9>b.4"),
        (2, 9, "m.9", 11, 11, "collision", -1, None, True, 30.0, 1, 0, 0, "other into A", "r.5>m.9"),
    ])
    m = episode_metrics(_table(), controls, pd.DataFrame({"action": [2, 2, 1, 3]}), policy="p", seed=1,
                        section_length_ft=2000.0, collisions=5, config=MetricsConfig())
    assert m.a_collision_kinds == {"A into B": 1, "A into C": 1, "other into A": 1}
    assert sum(m.a_collision_kinds.values()) == m.a_collisions == 3
    agg = aggregate([m, m])  # two seeds: the counts add
    assert agg.a_collision_kinds == {"A into B": 2, "A into C": 2, "other into A": 2}
    (line,) = collision_count_lines({"p": agg, "calm": aggregate([EpisodeMetrics(
        "calm", 1, 12, 4, 0, 0, 0, 0, 0, 5.0, 1.0, 20.0, 60.0, (1, 0, 0, 0, 0), 0.1)])})
    assert line == ("- p: 6 A collision(s) (distinct colliding pairs with A; the tables' count) = 2 A into C + 2 A into "
                    "B + 2 other into A; they ended 8 control episode(s) (release reason collision) = 6 + 2 later "
                    "take-over(s) of the same A that ended at once on a pair already counted (SUMO keeps colliding "
                    "cars overlapping); the whole run: 10 distinct colliding pair(s) = 6 with a controlled A + 4 "
                    "without.")
    assert agg.release_reasons["collision"] == 8 and agg.collisions == 10


def test_the_zero_collision_bound_is_a_hypothetical_never_beside_collisions_unqualified():
    def agg(name, n_controls, a_coll):
        return aggregate([EpisodeMetrics(name, 1, n_controls, 0, a_coll, a_coll, 0, 0, 0, 5.0, np.nan, np.nan,
                                         np.nan, (0,) * 5, np.nan)])

    line = collision_bound_line({"qavg": agg("qavg", 136, 11), "sumo": agg("sumo", 140, 0)})
    assert line.startswith("What 1 episode(s) can show at best (a hypothetical, no policy's result): a policy with 0 "
                           "A collisions in 136 As")
    assert f"would bound its A collision rate only below {rate_ci95(0, 136)[2]:.1%}" in line
    assert f"With 0 A collisions here: sumo 0/140 (below {rate_ci95(0, 140)[2]:.1%})." in line
    assert ("With A collisions (qavg 11/136) a policy is bounded by its own interval in column 'A collisions / As "
            "[95 % CI]', not by this.") in line
    only_some = collision_bound_line({"qavg": agg("qavg", 136, 11)})
    assert "With 0 A collisions here" not in only_some and "qavg 11/136" in only_some
