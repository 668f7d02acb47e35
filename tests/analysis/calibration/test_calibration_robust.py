"""Calibration objective: bounds respected, one bad pair does not dominate the population fit,
RMSPE / Theil's U scale free, bootstrap intervals of the held-out evaluation bracket the value."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from shared_data import PAIRS_DIR

from analysis.calibration import (
    BOUNDS,
    FITTED,
    CFParams,
    evaluate,
    fit_per_pair,
    fit_population,
    load_pairs,
    simulate_follower,
)
from analysis.calibration.objective import OBJECTIVES, spacing_rmse, spacing_rmspe, theil_u
from analysis.calibration.pairs import CarFollowingPair, PairBatch
from scenarios.errors import SpecError

TRUE = CFParams(accel=1.4, decel=2.2, tau=1.3, minGap=2.0, maxSpeed=22.0)


@pytest.fixture(scope="module")
def real_pairs() -> tuple[CarFollowingPair, ...]:
    return load_pairs(PAIRS_DIR)


def _replica_pairs(real, params: CFParams, n: int = 16, steps: int = 400) -> list[CarFollowingPair]:
    """Real leaders followed by the numpy SUMO replica with ``params`` (the replica matches SUMO:
    tests/test_calibration_replica.py)."""
    out = []
    for i, p in enumerate(real[:n]):
        k = min(steps, len(p))
        x, v = simulate_follower("idm", p.x_leader[:k], p.v_leader[:k], p.leader_length,
                                 p.x_follower[0], p.v_follower[0], params.as_dict())
        out.append(CarFollowingPair(name=f"syn{i}", group=f"g{i}", t=p.t[:k], x_follower=x, v_follower=v,
                                    x_leader=p.x_leader[:k], v_leader=p.v_leader[:k],
                                    leader_length=p.leader_length))
    return out


def test_one_bad_pair_does_not_dominate(real_pairs) -> None:
    pairs = _replica_pairs(real_pairs, TRUE)
    clean, _ = fit_population(pairs, model="idm", max_nfev=30)
    # one follower that the model cannot follow at all: 40 m further back and drifting away
    b = pairs[0]
    drift = 40.0 + 0.5 * b.t
    pairs[0] = replace(b, x_follower=b.x_follower - drift)
    bad, med = fit_population(pairs, model="idm", max_nfev=30)
    for name in FITTED:
        assert getattr(bad, name) == pytest.approx(getattr(TRUE, name), rel=0.1), name
        assert getattr(bad, name) == pytest.approx(getattr(clean, name), rel=0.1), name
    assert med < 0.05  # metres: the other 15 pairs are still followed exactly


def test_fitted_values_respect_bounds(real_pairs) -> None:
    # a driver whose true comfortable deceleration (0.4 m/s^2) lies below the physical bound
    pairs = _replica_pairs(real_pairs, replace(TRUE, decel=0.4, tau=0.2), n=8, steps=300)
    pop, _ = fit_population(pairs, model="idm", max_nfev=20)
    for name in FITTED:
        lo, hi = BOUNDS[name]
        assert lo <= getattr(pop, name) <= hi, name
    assert pop.decel == pytest.approx(BOUNDS["decel"][0], abs=0.2)  # pushed to the bound


def test_rmspe_and_theil_are_scale_free(real_pairs) -> None:
    batch = PairBatch.from_pairs(real_pairs[:6])
    p = TRUE.as_dict()
    rmspe, u, rmse = spacing_rmspe("idm", batch, p), theil_u("idm", batch, p), spacing_rmse("idm", batch, p)
    assert rmspe.shape == u.shape == (6,)
    assert np.all((u >= 0) & (u <= 1))
    # the replica's own output scores 0 on both
    syn = PairBatch.from_pairs(_replica_pairs(real_pairs, TRUE, n=6))
    assert np.max(theil_u("idm", syn, p)) < 1e-9 and np.max(spacing_rmspe("idm", syn, p)) < 1e-9
    # relative error: the same RMSE weighs less at a larger observed gap
    big = np.argmax(np.where(batch.mask, batch.spacing_obs, 0).sum(1) / batch.mask.sum(1))
    assert rmspe[big] < rmse[big] / 5.0


def test_evaluate_bootstrap_intervals_bracket_values(real_pairs) -> None:
    ev = evaluate(TRUE, real_pairs, model="idm", seed=3)
    names = {k for k, _ in ev.intervals}
    assert {"median_rmse_m", "mean_rmse_m", "win_fraction", "median_ratio", "mean_ratio"} <= names
    for _, iv in ev.intervals:
        assert iv.low <= iv.value <= iv.high
        assert iv.high > iv.low  # 36 pairs differ: a real interval
    assert ev.interval("mean_rmse_m").value == pytest.approx(ev.mean_rmse_m)
    again = evaluate(TRUE, real_pairs, model="idm", seed=3)
    assert again.intervals == ev.intervals  # deterministic per seed
    assert "intervals" in ev.to_json_dict()


def test_per_pair_fits_recover_each_drivers_parameters(real_pairs) -> None:
    """Six drivers with different parameters behind real leaders (the replica, which is SUMO):
    the per-pair Levenberg-Marquardt fits, all started from one population point, find each
    driver's own parameters; a driver beyond a bound is held at it."""
    drivers = [
        CFParams(accel=1.4, decel=2.2, tau=1.3, minGap=2.0, maxSpeed=22.0),
        CFParams(accel=0.8, decel=1.5, tau=0.8, minGap=3.5, maxSpeed=18.0),
        CFParams(accel=2.5, decel=3.0, tau=1.8, minGap=1.5, maxSpeed=26.0),
        CFParams(accel=1.0, decel=1.2, tau=1.0, minGap=4.5, maxSpeed=15.0),
        CFParams(accel=1.8, decel=2.6, tau=0.6, minGap=2.5, maxSpeed=30.0),
        CFParams(accel=1.4, decel=2.2, tau=3.5, minGap=2.0, maxSpeed=22.0),  # tau beyond its bound (3 s)
    ]
    pairs = [_replica_pairs(real_pairs[i:], d, n=1, steps=500)[0] for i, d in enumerate(drivers)]
    fits = fit_per_pair(pairs, CFParams(accel=1.2, decel=2.0, tau=1.2, minGap=2.5, maxSpeed=20.0), max_nfev=60)
    assert [f.name for f in fits] == [p.name for p in pairs]
    for f, d in zip(fits[:5], drivers[:5]):
        assert f.rmse_m < 0.05, f.name  # metres
        for name in ("accel", "tau", "minGap"):  # the parameters congested following identifies
            assert getattr(f.params, name) == pytest.approx(getattr(d, name), rel=0.05), (f.name, name)
    for f in fits:
        for name in FITTED:
            lo, hi = BOUNDS[name]
            assert lo <= getattr(f.params, name) <= hi
    assert fits[5].params.tau == pytest.approx(BOUNDS["tau"][1])
    assert fits[5].rmse_m > 0.05  # it cannot reach the driver


def test_population_objectives(real_pairs) -> None:
    pairs = _replica_pairs(real_pairs, TRUE, n=8, steps=300)
    for objective in OBJECTIVES:
        pop, med = fit_population(pairs, model="idm", max_nfev=30, objective=objective)
        assert med < 0.05, objective
        assert pop.tau == pytest.approx(TRUE.tau, rel=0.05), objective
    with pytest.raises(SpecError, match="objective: expected one of"):
        fit_population(pairs, objective="median")
