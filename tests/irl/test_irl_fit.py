"""The fit dispatcher: every method and solver, seeds, extreme settings, errors."""

import numpy as np
import pytest
from irl_testdata import gridworld_demos, random_mdp

from irl.config import IRLConfig
from irl.errors import ConfigError
from irl.fit import fit
from irl.result import SavedModel

SMALL = {"max_outer": 20, "max_inner": 300, "alpha": 0.5}


@pytest.mark.parametrize("method", ["qavg", "qsm", "mlirl"])
@pytest.mark.parametrize("solver", ["exact", "faithful"])
def test_fixed_seed_fixed_result(method, solver):
    t, demos = random_mdp(2)
    cfg = IRLConfig(beta=0.5, gamma=0.9, solver=solver, **SMALL)
    a = fit(method, demos, cfg, np.random.default_rng(42), transitions=t)
    b = fit(method, demos, cfg, np.random.default_rng(42), transitions=t)
    c = fit(method, demos, cfg, np.random.default_rng(43), transitions=t)
    np.testing.assert_array_equal(a.theta, b.theta)
    np.testing.assert_array_equal(a.loglik_trace, b.loglik_trace)
    assert a.loglik == b.loglik
    assert not np.array_equal(a.theta_trace[0], c.theta_trace[0])  # the seed sets theta0
    assert a.theta_trace.shape == (a.n_iterations, demos.n_features)
    assert a.method == method and a.wall_time_s > 0
    assert a.q.shape == (demos.n_states, demos.n_actions)


@pytest.mark.parametrize("method", ["qavg", "qsm", "mlirl"])
@pytest.mark.parametrize("solver", ["exact", "faithful"])
def test_large_beta_and_weights_stay_finite(method, solver):
    t, demos = random_mdp(1)
    cfg = IRLConfig(beta=10.0, gamma=0.9, solver=solver, max_outer=3, max_inner=300)
    res = fit(method, demos, cfg, np.random.default_rng(0), transitions=t,
              theta0=np.full(demos.n_features, 1e4))
    assert np.isfinite(res.loglik_trace[0]), res.message
    assert np.all(np.isfinite(res.q)) and np.isfinite(res.loglik)
    assert np.all(np.isfinite(res.theta))


def test_gridworld_fits_and_saves():
    demos = gridworld_demos("0.0")
    res = fit("qavg", demos, IRLConfig.paper(l2=1e-3), np.random.default_rng(0))
    assert res.converged
    model = SavedModel.from_fit(res, domain="gridworld")
    assert model.to_json_dict()["loglik"] == res.loglik


def test_faithful_qavg_follows_the_fixed_step_rule():
    demos = gridworld_demos("0.0")
    cfg = IRLConfig.reference(solver="faithful", max_outer=25)
    res = fit("qavg", demos, cfg, np.random.default_rng(0))
    steps = np.linalg.norm(np.diff(res.theta_trace, axis=0), axis=1)
    np.testing.assert_allclose(steps, cfg.step_size, rtol=1e-12)
    assert res.n_iterations == 25 and not res.converged
    assert np.all(np.diff(res.loglik_trace) > -1e-9)  # small steps uphill on this concave L


def test_exact_beats_or_matches_faithful_on_gridworld():
    demos = gridworld_demos("0.0")
    exact = fit("qavg", demos, IRLConfig.reference(), np.random.default_rng(0))
    faithful = fit("qavg", demos, IRLConfig.reference(solver="faithful", max_outer=300),
                   np.random.default_rng(0))
    assert exact.loglik >= faithful.loglik


def test_errors_name_what_is_wrong():
    t, demos = random_mdp(0)
    with pytest.raises(ConfigError, match="unknown IRL method 'maxent'"):
        fit("maxent", demos, IRLConfig(), np.random.default_rng(0))
    with pytest.raises(ConfigError, match="MLIRL needs a transition model"):
        fit("mlirl", demos, IRLConfig(), np.random.default_rng(0))
    with pytest.raises(ConfigError, match="transitions must have shape"):
        fit("mlirl", demos, IRLConfig(), np.random.default_rng(0), transitions=t[:, :2])
    with pytest.raises(ConfigError, match="theta0 must be 3 finite numbers"):
        fit("qavg", demos, IRLConfig(), np.random.default_rng(0), theta0=np.ones(2))
