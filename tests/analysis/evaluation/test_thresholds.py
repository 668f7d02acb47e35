"""``--fail-if`` thresholds: parsing, checking, and the ``check-metrics`` CI gate."""

from __future__ import annotations

import json
import math

import pytest

from analysis.cli.main import main
from analysis.evaluation.thresholds import (
    Threshold,
    ThresholdError,
    check_file,
    check_thresholds,
    parse_threshold,
    parse_thresholds,
)

METRICS = {
    "qavg": {"policy": "qavg", "collisions": 0, "min_ttc_s": 2.5, "travel_time_s": [12.0, 1.0],
             "heldout_loglik": float("nan"), "release_reasons": {"merged": 3}},
    "sumo": {"policy": "sumo", "collisions": 2, "min_ttc_s": 0.8, "travel_time_s": [10.0, 0.5],
             "heldout_loglik": -3.0, "release_reasons": {}},
}


def test_parse_every_operator_and_spacing():
    assert parse_threshold("collisions>0") == Threshold("collisions", ">", 0.0)
    assert parse_threshold(" min_ttc_s <= 1.5 ") == Threshold("min_ttc_s", "<=", 1.5)
    assert parse_threshold("qavg.b_ahead_rate>=-2e-1") == Threshold("b_ahead_rate", ">=", -0.2, "qavg")
    for op in (">", ">=", "<", "<=", "==", "!="):
        assert parse_threshold(f"x{op}3").op == op
    assert [str(t) for t in parse_thresholds(["collisions>0, min_ttc_s<1", "qavg.x==2"])] == [
        "collisions>0", "min_ttc_s<1", "qavg.x==2"]


@pytest.mark.parametrize("bad", ["", "collisions", "collisions>", ">0", "collisions=>0", "collisions>abc",
                                 "collisions>0 1", "collisions=0", "collisions>nan", "1x>0", ".x>0", "a..x>0x"])
def test_parse_errors_explain_the_syntax(bad):
    with pytest.raises(ThresholdError, match="threshold"):
        parse_threshold(bad)


def test_a_dotted_policy_name_can_be_gated():
    """Policy names may hold dots (``--policy rules.py:cth:cth-1.5s``, ``--driver planner.v2.json``);
    before, ``cth-1.5s.a_collisions>0`` was refused as malformed, so such a policy could not be gated."""
    assert parse_threshold("cth-1.5s.a_collisions>0") == Threshold("a_collisions", ">", 0.0, "cth-1.5s")
    metrics = {"cth-1.5s": dict(METRICS["qavg"], policy="cth-1.5s", collisions=1)}
    assert [(b.policy, b.value) for b in check_thresholds(parse_thresholds("cth-1.5s.collisions>0"), metrics)] == [
        ("cth-1.5s", 1.0)]
    with pytest.raises(ThresholdError, match="unknown policy 'a.b'"):
        check_thresholds(parse_thresholds("a.b.collisions>0"), METRICS)


def test_check_semantics():
    def breaches(text):
        return [(b.policy, b.value) for b in check_thresholds(parse_thresholds(text), METRICS)]

    assert breaches("collisions>0") == [("sumo", 2.0)]
    assert breaches("collisions>=0") == [("qavg", 0.0), ("sumo", 2.0)]
    assert breaches("qavg.collisions>0") == []
    assert breaches("min_ttc_s<1") == [("sumo", 0.8)]
    assert breaches("travel_time_s>11") == [("qavg", 12.0)]  # (mean, std): the mean
    assert breaches("collisions==2,min_ttc_s!=2.5") == [("sumo", 2.0), ("sumo", 0.8)]
    got = breaches("sumo.heldout_loglik<-10, qavg.heldout_loglik<-10")
    assert len(got) == 1 and got[0][0] == "qavg" and math.isnan(got[0][1])  # NaN counts as a breach


def test_unknown_metric_or_policy_is_a_clear_error():
    with pytest.raises(ThresholdError, match="unknown metric 'colisions'.*collisions"):
        check_thresholds(parse_thresholds("colisions>0"), METRICS)
    with pytest.raises(ThresholdError, match="unknown metric 'release_reasons'"):
        check_thresholds(parse_thresholds("release_reasons>0"), METRICS)
    with pytest.raises(ThresholdError, match="unknown policy 'mlirl'"):
        check_thresholds(parse_thresholds("mlirl.collisions>0"), METRICS)


def _metrics_file(tmp_path):
    p = tmp_path / "metrics.json"
    p.write_text(json.dumps({"format": "merge-irl-evaluation/1",
                             "policies": {k: {"aggregate": v, "episodes": []} for k, v in METRICS.items()}}))
    return p


def test_check_file_and_cli_exit_status(tmp_path, capsys):
    p = _metrics_file(tmp_path)
    assert [b.policy for b in check_file(p, "collisions>0")] == ["sumo"]
    assert main(["check-metrics", str(p), "--fail-if", "qavg.collisions>0"]) == 0
    assert main(["check-metrics", str(p), "--fail-if", "qavg.collisions>0", "--fail-if", "collisions>1"]) == 1
    assert "FAIL sumo: collisions = 2 (fail if collisions>1)" in capsys.readouterr().err
    assert main(["check-metrics", str(p), "--fail-if", "crashes>0"]) == 2
    assert "unknown metric 'crashes'" in capsys.readouterr().err
    (tmp_path / "bad.json").write_text("{not json")
    assert main(["check-metrics", str(tmp_path / "bad.json"), "--fail-if", "collisions>0"]) == 2
    assert main(["check-metrics", str(tmp_path / "none.json"), "--fail-if", "collisions>0"]) == 2


def test_teleports_threshold_sums_the_episodes(tmp_path, capsys):
    p = tmp_path / "metrics.json"
    p.write_text(json.dumps({"format": "merge-irl-evaluation/1", "policies": {
        k: {"aggregate": v, "episodes": [{"teleports": n}, {"teleports": 0}]}
        for (k, v), n in zip(METRICS.items(), (0, 3))}}))
    names = list(METRICS)
    assert [(b.policy, b.value) for b in check_file(p, "teleports>0")] == [(names[1], 3.0)]
    assert main(["check-metrics", str(p), "--fail-if", "teleports>0"]) == 1
    assert f"FAIL {names[1]}: teleports = 3 (fail if teleports>0)" in capsys.readouterr().err


def test_a_gate_not_triggered_says_the_value_then_that_the_gate_held_off(tmp_path, capsys):
    """``ok ... (teleports>0)`` read as if teleports had occurred: the line now gives the value found
    and says the gate was not triggered."""
    p = tmp_path / "metrics.json"
    p.write_text(json.dumps({"format": "merge-irl-evaluation/1", "policies": {
        k: {"aggregate": v, "episodes": [{"teleports": 0}]} for k, v in METRICS.items()}}))
    assert main(["check-metrics", str(p), "--fail-if", "teleports>0"]) == 0
    err = capsys.readouterr().err
    assert err.strip() == "ok: teleports = 0 (every policy); gate teleports>0 not triggered"
    assert "(teleports>0)" not in err
    # one policy named; several values; a breach beside a gate that held off
    assert main(["check-metrics", str(p), "--fail-if", "qavg.min_ttc_s<1", "--fail-if", "min_ttc_s<0.5"]) == 0
    assert capsys.readouterr().err.splitlines() == [
        "ok: qavg.min_ttc_s = 2.5; gate qavg.min_ttc_s<1 not triggered",
        "ok: min_ttc_s = 2.5 (qavg), 0.8 (sumo); gate min_ttc_s<0.5 not triggered"]
    assert main(["check-metrics", str(p), "--fail-if", "collisions>1", "--fail-if", "qavg.collisions>0"]) == 1
    assert capsys.readouterr().err.splitlines() == [
        "FAIL sumo: collisions = 2 (fail if collisions>1)",
        "ok: qavg.collisions = 0; gate qavg.collisions>0 not triggered"]
