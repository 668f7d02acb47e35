""""Converged" only where the optimality check passes on the problem as given: a
feature in units 1e14 times too large or 1e-7 times too small gives every method the fit of
the unit-scale problem, mapped back (no weights near 1e14, no stop at the start), and no method
claims convergence at a point below the optimum; a diverged or unconverged model taken as the
environment's reward is warned about."""

from __future__ import annotations

import warnings
from dataclasses import replace

import numpy as np
import pytest
from irl_testdata import random_mdp

from irl.config import IRLConfig
from irl.domains.merge.bins import MergeBins
from irl.domains.merge.features import FEATURE_NAMES
from irl.fit import fit
from irl.result import SavedModel
from sim.drivers.formats import UnreliableRewardWarning, driver_reward

CFG = IRLConfig(beta=0.5, gamma=0.9)


def _fit(method, demos, t, **kw):
    extra = {"transitions": t} if method == "mlirl" else {}
    return fit(method, demos, CFG, np.random.default_rng(6), **extra, **kw)


@pytest.fixture(scope="module")
def problem():
    t, demos = random_mdp(6, n_traj=8, length=8)
    return t, demos


@pytest.mark.parametrize("method", ["qavg", "qsm", "mlirl"])
@pytest.mark.parametrize("k", [1e14, 1e-7])
def test_a_feature_in_extreme_units_gets_the_unit_fit(problem, method, k) -> None:
    t, demos = problem
    ref = _fit(method, demos, t)
    assert ref.converged
    unit = np.array([1.0, k, 1.0])
    res = _fit(method, replace(demos, features=demos.features * unit), t)
    assert res.converged, res.message
    assert res.loglik == pytest.approx(ref.loglik, abs=1e-5)
    np.testing.assert_allclose(res.theta * unit, ref.theta, rtol=1e-3, atol=1e-5)


@pytest.mark.parametrize("method", ["qavg", "qsm", "mlirl"])
@pytest.mark.parametrize("k", [1e14, 1e-7])
def test_no_convergence_is_claimed_below_the_optimum(problem, method, k) -> None:
    """From a start given by the user in the wrong units (weights of 1 on every feature)."""
    t, demos = problem
    ref = _fit(method, demos, t)
    unit = np.array([1.0, k, 1.0])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = _fit(method, replace(demos, features=demos.features * unit), t, theta0=np.ones(3))
    if res.converged:
        assert res.loglik == pytest.approx(ref.loglik, abs=1e-4), res.message
    else:
        assert "not an optimum" in res.message, res.message


def _model(tmp_path, **kw):
    rng = np.random.default_rng(3)
    edges = MergeBins.assumed_authors()
    m = SavedModel(method="qavg", theta=np.array([1.0, 0.5, -0.2]), loglik=-1.0, q=rng.normal(size=(1250, 5)),
                   config=IRLConfig(beta=1.0), domain="merge", feature_names=FEATURE_NAMES,
                   bin_edges={k: tuple(v) for k, v in edges.to_dict().items()}, **kw)
    return m.save(tmp_path / "qavg.json")


@pytest.mark.parametrize("kw, words", [(dict(converged=False), "its fit did not converge"),
                                       (dict(unbounded=True), "its weights are unbounded")])
def test_a_diverged_model_as_a_reward_is_warned_about(tmp_path, kw, words) -> None:
    with pytest.warns(UnreliableRewardWarning, match=words):
        driver_reward(_model(tmp_path, **kw))
    with warnings.catch_warnings():
        warnings.simplefilter("error", UnreliableRewardWarning)
        driver_reward(_model(tmp_path))  # a converged, bounded model: no warning
