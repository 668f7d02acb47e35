"""Held-out log-likelihood of policies that expose their action distribution (a ``probs(obs)``
method; Stable-Baselines3's ``get_distribution`` has the same path without torch here), and
VecNormalize statistics applied to what the policy sees."""

from __future__ import annotations

import pickle
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from irl.domains.merge.car_following import car_following_decisions
from sim.drivers.action_distribution import ObsNormalized, action_probs_fn, gaussian_bin_probs, with_vecnormalize
from sim.drivers.callables import CallablePolicy
from sim.drivers.observe import policy_rows
from sim.drivers.policy import PolicyError


def encounters(n=3, rows=31, seed=0):
    rng = np.random.default_rng(seed)
    return pd.DataFrame({
        "encounter_id": np.repeat(np.arange(n) + 7, rows),
        "d_AC": rng.uniform(20, 250, n * rows), "v_AC": rng.normal(5, 5, n * rows),
        "d_AB": rng.uniform(-50, 120, n * rows), "v_AB": rng.normal(0, 5, n * rows),
        "B_is_truck": False, "acc_A": rng.choice([-12.0, -3.0, 0.0, 3.0, 9.0], n * rows),
        "v_A": rng.uniform(20, 80, n * rows),
    })


class GapRule:
    """Brakes more likely when the gap to C is short: a distribution that depends on the observation."""

    def probs(self, obs):
        short = float(obs[0] < 80.0)
        return np.array([0.5 * short + 0.05, 0.1, 0.6 - 0.5 * short, 0.15, 0.1])

    def __call__(self, obs):
        return int(np.argmax(self.probs(obs)))


def zero_rule(obs):
    return 2


def test_a_probs_method_gives_the_held_out_log_likelihood_of_the_decisions():
    enc = encounters()
    pol = CallablePolicy(GapRule(), name="gap")
    total, per = pol.heldout_loglik(enc, decision_step_s=0.3, where="test")
    dec = car_following_decisions(enc, decision_step_s=0.3)
    rule = GapRule()
    expected = sum(np.log(rule.probs(o)[a]) for o, a in zip(policy_rows(dec.obs), dec.actions))
    assert dec.n > 10 and total == pytest.approx(expected) and per == pytest.approx(expected / dec.n)
    # a rule with no distribution: none
    assert all(np.isnan(CallablePolicy(lambda o: 2).heldout_loglik(enc, decision_step_s=0.3, where="t")))


def test_vecnormalize_statistics_normalise_what_the_policy_sees(tmp_path):
    mean, var = np.arange(7.0), np.full(7, 4.0)
    seen = []

    def rule(obs):
        seen.append(np.array(obs))
        return 2

    stats = SimpleNamespace(obs_rms=SimpleNamespace(mean=mean, var=var), clip_obs=5.0, epsilon=1e-8, norm_obs=True)
    path = tmp_path / "vecnormalize.pkl"
    path.write_bytes(pickle.dumps(stats))
    wrapped = with_vecnormalize(rule, path)
    obs = np.array([100.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0])
    assert wrapped(obs) == 2
    np.testing.assert_allclose(seen[-1], np.clip((obs - mean) / 2.0, -5, 5))
    assert action_probs_fn(wrapped) is None  # the rule has no distribution
    normed = ObsNormalized(GapRule(), np.zeros(7), np.ones(7))
    assert action_probs_fn(normed) is not None
    pol = pickle.loads(pickle.dumps(CallablePolicy(zero_rule, obs_stats=str(path))))  # as evaluation workers get it
    assert isinstance(pol.fn, ObsNormalized) and pol.fn.fn is zero_rule and pol.fn.clip_obs == 5.0
    bad = tmp_path / "bad.pkl"
    bad.write_bytes(pickle.dumps({"x": 1}))
    with pytest.raises(PolicyError, match="no observation statistics"):
        with_vecnormalize(rule, bad)


def test_a_gaussian_acceleration_gives_each_action_its_bin_mass():
    p = gaussian_bin_probs(np.array([0.0, -3.0, 3.0]), np.array([0.05, 0.5, 0.5]))
    np.testing.assert_allclose(p.sum(axis=1), 1.0)
    assert np.argmax(p[0]) == 2 and np.argmax(p[1]) == 0 and np.argmax(p[2]) == 4


def _stats_file(tmp_path, name="vn.pkl", **fields):
    rms = {"mean": np.zeros(7), "var": np.ones(7), "count": 100.0, **{k: v for k, v in fields.items() if k in
                                                                      ("mean", "var", "count")}}
    stats = SimpleNamespace(obs_rms=SimpleNamespace(**rms), clip_obs=fields.get("clip_obs", 10.0),
                            epsilon=fields.get("epsilon", 1e-8), norm_obs=fields.get("norm_obs", True))
    path = tmp_path / name
    path.write_bytes(pickle.dumps(stats))
    return path


def _with(i, value, base=1.0):
    a = np.full(7, base)
    a[i] = value
    return a


@pytest.mark.parametrize("fields,match", [
    ({"mean": _with(0, np.nan, 0.0)}, r"obs_rms\.mean must be finite numbers, got d_AC nan"),
    ({"mean": _with(4, np.inf, 0.0)}, r"obs_rms\.mean must be finite numbers, got v_A inf"),
    ({"var": _with(1, -1.0)}, r"obs_rms\.var must be finite numbers >= 0, got v_AC -1\.0"),
    ({"var": _with(0, np.inf)}, r"obs_rms\.var must be finite numbers >= 0, got d_AC inf"),
    ({"var": _with(6, np.nan)}, r"obs_rms\.var must be finite numbers >= 0, got len_B nan"),
    ({"var": np.array(["a"] * 7)}, r"obs_rms\.var must be 7 numbers"),
    ({"count": 0.0}, r"obs_rms\.count must be a positive finite number, got 0\.0"),
    ({"count": np.nan}, r"obs_rms\.count must be a positive finite number"),
    ({"clip_obs": -1.0}, r"clip_obs must be a positive number, got -1\.0"),
    ({"epsilon": 0.0}, r"epsilon must be a positive finite number, got 0\.0"),
])
def test_vecnormalize_statistics_that_would_poison_every_observation_are_refused(tmp_path, fields, match):
    """Before: a NaN mean or a negative variance put NaN into every observation the policy got,
    an infinite variance turned that column into 0 at every decision."""
    path = _stats_file(tmp_path, **fields)
    with pytest.raises(PolicyError, match=match) as e:
        with_vecnormalize(lambda o: 2, path)
    assert str(e.value).startswith(str(path)) and "\n" not in str(e.value)


def test_vecnormalize_without_norm_obs_passes_observations_through(tmp_path):
    path = _stats_file(tmp_path, norm_obs=False, var=_with(0, -1.0))  # statistics unused, so not checked
    seen = []
    wrapped = with_vecnormalize(lambda o: seen.append(np.array(o)) or 2, path)
    obs = np.array([1000.0, 1.0, -50.0, 3.0, 90.0, 15.0, 15.0])
    assert wrapped(obs) == 2
    np.testing.assert_allclose(seen[-1], obs)  # not clipped at clip_obs either
