"""Calibration objective: bounds respected, one bad pair does not dominate the population fit,
RMSPE / Theil's U scale free, bootstrap intervals of the held-out evaluation bracket the value."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from shared_data import PAIRS_DIR

from scenarios.calibration import (
    BOUNDS,
    FITTED,
    CFParams,
    evaluate,
    fit_population,
    load_pairs,
    simulate_follower,
)
from scenarios.calibration.objective import spacing_rmse, spacing_rmspe, theil_u
from scenarios.calibration.pairs import CarFollowingPair, PairBatch

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
