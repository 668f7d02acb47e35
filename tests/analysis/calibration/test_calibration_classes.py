"""Driver classes of the initial time headway: fit_classes recovers two known driver types and
beats one vector on held-out pairs; [classes] TOML round trip and errors; ``calibrate fit
--classes`` / ``evaluate`` end to end."""

from __future__ import annotations

import json
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from shared_data import PAIRS_DIR

from analysis.calibration import CFParams, evaluate, fit_population, load_pairs, load_result, save_result
from analysis.calibration.class_fit import fit_classes
from analysis.calibration.classes import DriverClasses, initial_time_headway
from analysis.calibration.models import simulate_follower
from analysis.calibration.pairs import CarFollowingPair
from analysis.calibration.result import CalibrationResult
from scenarios.errors import SpecError

#: Two driver types: close followers (short tau) and distant ones (long tau), otherwise alike.
CLOSE = CFParams(accel=1.4, decel=2.2, tau=0.8, minGap=2.0, maxSpeed=22.0)
DISTANT = replace(CLOSE, tau=2.0)
STEPS = 200  # 20 s per pair keeps the fits fast


@pytest.fixture(scope="module")
def synthetic() -> tuple[list[CarFollowingPair], list[CarFollowingPair]]:
    """(train, test): the vendored real leaders (the first 16 with initial speed >= 3 m/s) each followed once by a
    CLOSE and once by a DISTANT replica driver, starting at its equilibrium gap minGap + v0 * tau;
    even leaders train, odd leaders test (no leader on both sides)."""
    leaders = [p for p in load_pairs(PAIRS_DIR) if p.v_leader[0] >= 3.0][:16]
    train: list[CarFollowingPair] = []
    test: list[CarFollowingPair] = []
    for i, p in enumerate(leaders):
        xl, vl = p.x_leader[:STEPS], p.v_leader[:STEPS]
        for kind, params in (("close", CLOSE), ("distant", DISTANT)):
            v0 = float(vl[0])
            x0 = float(xl[0]) - p.leader_length - (params.minGap + v0 * params.tau)
            x, v = simulate_follower("idm", xl, vl, p.leader_length, x0, v0, params.as_dict())
            pair = CarFollowingPair(name=f"{kind}{i}", group=f"{kind}{i}", t=np.arange(STEPS) * 0.1,
                                    x_follower=x, v_follower=v, x_leader=xl, v_leader=vl,
                                    leader_length=p.leader_length)
            (train if i % 2 == 0 else test).append(pair)
    return train, test


@pytest.fixture(scope="module")
def two_classes(synthetic) -> DriverClasses:
    return fit_classes(synthetic[0], 2, model="idm")


def test_class_key_is_initial_time_headway() -> None:
    p = CarFollowingPair(name="p", group="g", t=np.arange(2) * 0.1, x_follower=np.array([0.0, 1.0]),
                         v_follower=np.array([10.0, 10.0]), x_leader=np.array([25.0, 26.0]),
                         v_leader=np.array([10.0, 10.0]), leader_length=5.0)
    assert initial_time_headway(p) == pytest.approx(2.0)  # (25 - 5 - 0) m / 10 m/s
    stopped = replace(p, v_follower=np.array([0.0, 0.0]))
    assert initial_time_headway(stopped) == pytest.approx(40.0)  # speed floored at 0.5 m/s
    c = DriverClasses(edges_s=(1.0, 3.0), params=(CLOSE, CFParams(), DISTANT))
    assert c.class_of(p) == 1 and c.class_of(stopped) == 2
    assert c.params_for([stopped, p]) == [DISTANT, CFParams()]


def test_two_classes_recover_each_type_and_beat_one_vector(synthetic, two_classes) -> None:
    train, test = synthetic
    c = two_classes
    assert c.n_classes == 2 and len(c.edges_s) == 1
    close_keys = [initial_time_headway(p) for p in train if p.name.startswith("close")]
    distant_keys = [initial_time_headway(p) for p in train if p.name.startswith("distant")]
    assert max(close_keys) < c.edges_s[0] <= min(distant_keys)  # the classes are the two types
    assert c.params[0].tau == pytest.approx(CLOSE.tau, abs=0.15)
    assert c.params[1].tau == pytest.approx(DISTANT.tau, abs=0.15)
    assert all(c.params_for([p])[0] is c.params[p.name.startswith("distant")] for p in test)
    one, _ = fit_population(train, model="idm")
    ev1 = evaluate(one, test, model="idm")
    ev2 = evaluate(one, test, model="idm", classes=c)
    assert ev1.n_classes == 1 and ev2.n_classes == 2 and ev2.to_json_dict()["n_classes"] == 2
    assert ev2.median_rmse_m < 0.5 * ev1.median_rmse_m and ev2.mean_rmse_m < 0.5 * ev1.mean_rmse_m


def test_fit_classes_refuses_bad_counts(synthetic) -> None:
    train = synthetic[0]
    for bad in (0, -1, 1.5, True):
        with pytest.raises(SpecError, match="classes: expected a whole number >= 1"):
            fit_classes(train, bad)  # type: ignore[arg-type]
    with pytest.raises(SpecError, match="at least 5 per class|at least 25 training pairs"):
        fit_classes(train[:12], 5)
    with pytest.raises(SpecError, match="numpy replica"):
        fit_classes(train, 2, model="eidm")
    with pytest.raises(SpecError, match="edges"):
        DriverClasses(edges_s=(2.0, 1.0), params=(CLOSE, CLOSE, CLOSE))


def test_classes_toml_round_trip_and_errors(two_classes, tmp_path: Path) -> None:
    r = CalibrationResult(model="idm", fitted=("tau",), population=CLOSE, population_median_rmse_m=1.0,
                          per_pair=(), spread=(), n_pairs=10, seconds_population=1.0, seconds_per_pair=0.0)
    save_result(r, tmp_path / "one.toml")
    assert load_result(tmp_path / "one.toml").classes is None and "classes" not in (tmp_path / "one.toml").read_text()
    save_result(replace(r, classes=two_classes), tmp_path / "two.toml")
    assert load_result(tmp_path / "two.toml") == replace(r, classes=two_classes)
    head = 'model = "idm"\n[population]\ntau = 1.0\n'
    bad = {
        "[classes]\nedges_s = [1.0]\n": r"classes\.member: missing",
        '[classes]\nedges_s = ["x"]\n[[classes.member]]\ntau = 1.0\n[[classes.member]]\ntau = 1.0\n': r"classes\.edges_s\[0\]: must be a number, got 'x'",
        "[classes]\nedges_s = [1.0]\n[[classes.member]]\ntau = 1.0\n": r"classes\.member: 1 edges_s need 2 \[\[classes\.member\]\] tables, got 1",
        "[classes]\nedges_s = [1.0]\n[[classes.member]]\ntau = 1.0\n[[classes.member]]\ntau = -1.0\n":
            r"classes\.member\[1\]\.tau: must be greater than 0",
        "[classes]\nedges_s = [2.0, 1.0]\n" + "[[classes.member]]\ntau = 1.0\n" * 3: r"classes: .*expected increasing",
    }
    for text, msg in bad.items():
        (tmp_path / "bad.toml").write_text(head + text)
        with pytest.raises(SpecError, match=msg):
            load_result(tmp_path / "bad.toml")


def _cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "analysis", *args], capture_output=True, text=True, timeout=300)


def test_cli_classes_end_to_end(tmp_path: Path) -> None:
    out = tmp_path / "c2.toml"
    r = _cli("calibrate", "fit", "--pairs", str(PAIRS_DIR), "--out", str(out), "--limit", "10", "--no-per-pair",
             "--classes", "2")
    assert r.returncode == 0, r.stderr
    classes = load_result(out).classes
    assert classes is not None and classes.n_classes == 2
    r = _cli("calibrate", "evaluate", "--params", str(out), "--pairs", str(PAIRS_DIR), "--json")
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    assert d["n_classes"] == 2 and d["n_pairs"] == 36
    r = _cli("calibrate", "evaluate", "--params", str(out), "--pairs", str(PAIRS_DIR))
    assert r.returncode == 0 and "(2 driver classes of the initial time headway)" in r.stdout.splitlines()[0]


def test_cli_classes_errors_exit_2(tmp_path: Path) -> None:
    out = str(tmp_path / "x.toml")
    r = _cli("calibrate", "fit", "--pairs", str(PAIRS_DIR), "--out", out, "--cf-model-name", "eidm", "--classes", "2")
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert "--classes: driver classes need a model with a numpy replica" in r.stderr
    r = _cli("calibrate", "fit", "--pairs", str(PAIRS_DIR), "--out", out, "--limit", "6", "--no-per-pair",
             "--classes", "2")
    assert r.returncode == 2 and "2 classes need at least 10 training pairs" in r.stderr, r.stderr
