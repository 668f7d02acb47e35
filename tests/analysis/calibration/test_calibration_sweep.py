"""Per-pair fits through the sweep runner: every pair fitted once, in the pairs' order, each fit
at least as good as the population parameters on its own pair, within the bounds."""

from __future__ import annotations

import numpy as np
from shared_data import PAIRS_DIR

from analysis.calibration import BOUNDS, evaluate, load_pairs
from analysis.calibration.pairs import pair_files
from analysis.calibration.sweep import calibrate_parallel


def test_parallel_per_pair_fits_cover_every_pair() -> None:
    files = pair_files(PAIRS_DIR, limit=6)
    pairs = load_pairs(PAIRS_DIR, limit=6)
    res = calibrate_parallel(pairs, files, model="idm", max_nfev_population=8, max_nfev_per_pair=10,
                             workers=2)
    assert [f.name for f in res.per_pair] == [p.name for p in pairs]
    pop_rmse = {s.name: s.rmse_m for s in evaluate(res.population, pairs).pairs}
    own = np.array([f.rmse_m for f in res.per_pair])
    assert np.all(own <= np.array([pop_rmse[p.name] for p in pairs]) + 1e-6)
    for f in res.per_pair:
        for name in res.fitted:
            lo, hi = BOUNDS[name]
            assert lo <= getattr(f.params, name) <= hi
    assert res.spread_of("tau").q10 <= res.spread_of("tau").q90
