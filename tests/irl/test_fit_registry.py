"""irl.fit: the one entry point and its registry, REIRL's options included."""

import numpy as np
import pytest
from irl_testdata import random_mdp

from irl.config import IRLConfig
from irl.errors import ConfigError
from irl.fit import REGISTRY, fit, method_names
from irl.methods.reirl import fit_reirl


def test_registry_holds_the_four_methods_in_the_papers_row_order():
    assert method_names() == ("mlirl", "qavg", "qsm", "reirl")
    assert [m.label for m in REGISTRY.values()] == ["MLIRL", "Q-Avg", "Q-SM", "REIRL"]
    assert [REGISTRY[m].needs_transitions for m in method_names()] == [True, False, False, True]


@pytest.mark.parametrize("method", ["qavg", "qsm", "mlirl", "reirl"])
def test_every_method_runs_through_fit(method):
    t, demos = random_mdp(3)
    res = fit(method, demos, IRLConfig(beta=1.0, gamma=0.9, max_outer=20), np.random.default_rng(0), transitions=t)
    assert res.method == method
    assert res.theta.shape == (demos.n_features,) and np.isfinite(res.loglik)


def test_reirl_options_reach_reirl():
    t, demos = random_mdp(4)
    _, baseline = random_mdp(5)
    cfg = IRLConfig(beta=1.0, gamma=0.9)
    via_fit = fit("reirl", demos, cfg, np.random.default_rng(1), transitions=t, baseline=baseline, epsilon=0.3)
    direct = fit_reirl(demos, cfg, np.random.default_rng(1), transitions=t, baseline=baseline, epsilon=0.3)
    default = fit("reirl", demos, cfg, np.random.default_rng(1), transitions=t, baseline=baseline)
    np.testing.assert_array_equal(via_fit.theta, direct.theta)
    assert via_fit.extra["epsilon"] == 0.3 and default.extra["epsilon"] != 0.3


def test_unknown_method_or_option_is_a_config_error():
    t, demos = random_mdp(3)
    with pytest.raises(ConfigError, match="unknown IRL method 'maxent'"):
        fit("maxent", demos, IRLConfig(), np.random.default_rng(0))
    with pytest.raises(ConfigError, match="qavg takes no option epsilon"):
        fit("qavg", demos, IRLConfig(), np.random.default_rng(0), epsilon=0.1)
