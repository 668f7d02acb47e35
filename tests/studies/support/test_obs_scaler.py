"""analysis/experiments/obs_scaler.py: the imitation learners' observation scaler, without torch."""

from __future__ import annotations

import numpy as np

from sim.drivers.observe import NO_LEAD_GAP_FT, policy_rows
from studies.support.obs_scaler import ObsScaler


def test_scaler_fills_the_missing_lead_car_and_standardises_on_the_training_rows() -> None:
    rng = np.random.default_rng(0)
    obs = np.column_stack([rng.uniform(20, 200, 40), rng.normal(0, 5, 40), rng.uniform(-60, 60, 40),
                           rng.normal(0, 5, 40), rng.uniform(40, 90, 40), np.full(40, 15.0), np.full(40, 16.0)])
    obs[:5, [0, 1, 5]] = np.nan  # no lead car C in the first five decisions
    obs[5, 6] = np.nan  # B's length unknown once
    sc = ObsScaler.fit(obs)
    x = sc(obs)
    assert x.dtype == np.float32 and x.shape == (40, 7) and np.isfinite(x).all()
    np.testing.assert_allclose(x.mean(axis=0), 0.0, atol=1e-5)
    varying = np.asarray(sc.std) != 1.0
    np.testing.assert_allclose(x[:, varying].std(axis=0), 1.0, atol=1e-5)
    # the no-lead rows read as a car NO_LEAD_GAP_FT ahead at A's speed, as the environment's observation
    np.testing.assert_allclose(policy_rows(obs)[:5, :2], np.tile([NO_LEAD_GAP_FT, 0.0], (5, 1)))
    np.testing.assert_allclose(x[:5, 0], (NO_LEAD_GAP_FT - sc.mean[0]) / sc.std[0], rtol=1e-6)
    # one observation (the callable's [7]) scales like its row; a policy observation (already
    # filled) scales like the continuous row it came from
    np.testing.assert_array_equal(sc(obs[7]), x[7:8])
    np.testing.assert_array_equal(sc(policy_rows(obs)), x)
