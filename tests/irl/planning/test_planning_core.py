"""The planning driver's numerics (irl/planning: model, policy, fit): exact
gradients, shapes, determinism, braking, theta recovery. No data files, no SUMO."""

from __future__ import annotations

import numpy as np
import pytest

from irl.domains.merge.actions import actions_of
from irl.errors import ConfigError
from irl.planning.features import Shape
from irl.planning.fit import fit_planner
from irl.planning.model import BACKUPS, PlannerConfig, leaf_accelerations, path_tensors
from irl.planning.policy import bin_log_policy, fine_log_policy, loglik_grad

ACC = np.array([-9.5, -2.2, 0.0, 2.3, 6.1])
SHAPE = Shape()


def random_obs(n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``n`` plausible observations: C mostly present, B ahead half the time."""
    v_A = rng.uniform(0.0, 90.0, n)
    d_AC = rng.uniform(20.0, 250.0, n)
    v_AC = rng.normal(0.0, 8.0, n)
    no_c = rng.random(n) < 0.1
    d_AC[no_c] = v_AC[no_c] = np.nan
    len_C = np.where(rng.random(n) < 0.2, np.nan, rng.choice([14.8, 39.4], n))
    obs = np.column_stack([d_AC, v_AC, rng.uniform(-80.0, 200.0, n), rng.normal(0.0, 8.0, n), v_A, len_C,
                           np.full(n, 14.8)])
    prev = rng.normal(0.0, 3.0, n)
    prev[rng.random(n) < 0.1] = np.nan
    return obs, prev, rng.normal(0.0, 2.0, n)


@pytest.mark.parametrize("backup", BACKUPS)
@pytest.mark.parametrize("depth,later", [(2, "bins"), (3, "bins+hold")])
def test_gradient_matches_central_differences(backup: str, depth: int, later: str) -> None:
    rng = np.random.default_rng(1)
    cfg = PlannerConfig(horizon_s=2.1, depth=depth, backup=backup, c_model="ca", gamma=0.9, grid="g13", later=later,
                        jerk=True)
    obs, prev, acc_C = random_obs(30, rng)
    T = path_tensors(obs, prev, acc_C, ACC, SHAPE, cfg)
    y = rng.integers(0, 5, 30)
    theta = rng.normal(0.0, 0.3, len(cfg.feature_names))
    w = rng.uniform(0.5, 2.0, 30)

    def ll(th: np.ndarray) -> float:
        return loglik_grad(th, T, y, backup, cfg.collision_penalty, w)[0]

    g = loglik_grad(theta, T, y, backup, cfg.collision_penalty, w)[1]
    eps = 1e-6
    num = np.array([(ll(theta + eps * e) - ll(theta - eps * e)) / (2 * eps) for e in np.eye(theta.size)])
    np.testing.assert_allclose(g, num, rtol=1e-5, atol=1e-6)


@pytest.mark.parametrize("grid,depth,later", [("g24", 2, "bins"), ("g13", 3, "bins+hold"), ("bins", 2, "bins")])
def test_shapes_and_bins(grid: str, depth: int, later: str) -> None:
    cfg = PlannerConfig(grid=grid, depth=depth, later=later)
    obs, prev, acc_C = random_obs(7, np.random.default_rng(2))
    T = path_tensors(obs, prev, acc_C, ACC, SHAPE, cfg)
    G = cfg.fine_grid(ACC).size
    C = 5 + (later == "bins+hold")
    assert T.Phi.shape == (7, G) + (C,) * (depth - 1) + (len(cfg.feature_names),)
    assert T.Col.shape == T.Phi.shape[:-1] and np.all(np.isfinite(T.Phi))
    assert sorted(set(T.bins.tolist())) == [0, 1, 2, 3, 4]
    np.testing.assert_array_equal(T.bins, actions_of(cfg.fine_grid(ACC)))
    theta = np.random.default_rng(3).normal(0, 0.5, len(cfg.feature_names))
    lpf = fine_log_policy(T, theta, cfg.backup, cfg.collision_penalty)
    lpb = bin_log_policy(T, theta, cfg.backup, cfg.collision_penalty)
    assert lpf.shape == (7, G) and lpb.shape == (7, 5)
    np.testing.assert_allclose(np.exp(lpb).sum(axis=1), 1.0)
    for b in range(5):  # a paper action's probability is the sum of its fine actions'
        np.testing.assert_allclose(np.exp(lpb[:, b]), np.exp(lpf[:, T.bins == b]).sum(axis=1))
    leaf = leaf_accelerations(cfg, ACC)
    assert leaf.shape[-1] == cfg.n_steps
    np.testing.assert_array_equal(leaf[..., 0].reshape(G, -1)[:, 0], cfg.fine_grid(ACC))


def test_bad_config_and_inputs_raise() -> None:
    with pytest.raises(ConfigError, match="grid"):
        PlannerConfig(grid="g7")
    with pytest.raises(ConfigError, match="depth"):
        PlannerConfig(depth=4)
    with pytest.raises(ConfigError, match=r"\[N, 7\]"):
        path_tensors(np.zeros((3, 6)), np.zeros(3), np.zeros(3), ACC, SHAPE, PlannerConfig())


def test_fit_is_deterministic() -> None:
    cfg = PlannerConfig(grid="g13")
    obs, prev, acc_C = random_obs(300, np.random.default_rng(3))
    y = np.random.default_rng(4).integers(0, 5, 300)
    fits = [fit_planner(path_tensors(obs, prev, acc_C, ACC, SHAPE, cfg), y, cfg) for _ in range(2)]
    np.testing.assert_array_equal(fits[0].theta, fits[1].theta)
    assert fits[0].loglik == fits[1].loglik and fits[0].converged


@pytest.mark.parametrize("backup", BACKUPS)
def test_brakes_when_closing_fast_on_a_stopped_car(backup: str) -> None:
    cfg = PlannerConfig(backup=backup, with_bias=False, grid="g24")
    theta = np.zeros(len(cfg.feature_names))
    theta[cfg.feature_names.index("gap_need_C")] = -1.0
    # A at 60 ft/s, a stopped 14.8-ft C 80 ft ahead (front to front): bumper gap ~65 ft
    obs = np.array([[80.0, 60.0, np.nan, np.nan, 60.0, 14.8, np.nan]])
    T = path_tensors(obs, np.zeros(1), np.zeros(1), ACC, SHAPE, cfg)
    lpb = bin_log_policy(T, theta, backup, cfg.collision_penalty)
    assert int(np.argmax(lpb[0])) == 0, np.exp(lpb)
    lpf = fine_log_policy(T, theta, backup, cfg.collision_penalty)
    assert cfg.fine_grid(ACC)[int(np.argmax(lpf[0]))] <= -4.8


def test_jerk_relaxes_towards_the_state_demand() -> None:
    """Free road and a speed wish: with a moderate jerk weight the best fine acceleration leaves
    Zero but stays inside a coarse bin's width; a heavier jerk weight never asks for more."""
    cfg = PlannerConfig(with_bias=False, grid="g24", backup="softmax", jerk=True)
    names = cfg.feature_names
    obs = np.array([[np.nan, np.nan, np.nan, np.nan, 40.0, np.nan, np.nan]])
    T = path_tensors(obs, np.zeros(1), np.zeros(1), ACC, SHAPE, cfg)
    best = []
    for w_jerk in (5.0, 20.0, 150.0):
        theta = np.zeros(len(names))
        theta[names.index("jerk")] = -w_jerk
        theta[names.index("speed_dev")] = -20.0
        best.append(cfg.fine_grid(ACC)[int(np.argmax(fine_log_policy(T, theta, "softmax", -100.0)[0]))])
    assert 0.0 < best[1] < 4.8
    assert best[0] >= best[1] >= best[2] >= 0.0


def test_fit_recovers_theta_of_simulated_data() -> None:
    rng = np.random.default_rng(5)
    cfg = PlannerConfig(horizon_s=2.1, backup="boltzmann", with_bias=False, grid="g13", jerk=True)
    names = cfg.feature_names
    true = np.zeros(len(names))
    for name, val in {"gap_need_C": -0.5, "inv_ttc_C": -2.0, "headway_C": -1.0, "speed_gain": 1.0,
                      "speed_dev": -2.0, "comfort": -3.0, "jerk": -20.0}.items():
        true[names.index(name)] = val
    n = 8000
    obs, prev, acc_C = random_obs(n, rng)
    T = path_tensors(obs, prev, acc_C, ACC, SHAPE, cfg)
    p = np.exp(bin_log_policy(T, true, cfg.backup, cfg.collision_penalty))
    y = np.minimum((rng.random(n)[:, None] > np.cumsum(p, axis=1)).sum(axis=1), 4)
    fit = fit_planner(T, y, cfg, l2=0.01)
    assert fit.converged and fit.grad_norm < 1e-3
    err = np.linalg.norm(fit.theta - true) / np.linalg.norm(true)
    assert err < 0.35, (err, dict(zip(names, fit.theta.round(2))))
    big = np.abs(true) >= 1.0
    assert np.all(np.sign(fit.theta[big]) == np.sign(true[big]))


@pytest.mark.parametrize("backup", ["softmax", "boltzmann"])
def test_lag_gradient_matches_central_differences(backup: str) -> None:
    """An actuation lag: per-decision bins and the floor; the exact gradient still holds."""
    rng = np.random.default_rng(4)
    cfg = PlannerConfig(horizon_s=2.1, depth=2, backup=backup, grid="g13", later="bins+hold", jerk=False,
                        free_road=True, lag=0.3, v0_ft_s=95.0)
    obs, prev, acc_C = random_obs(30, rng)
    prev[:3] = [-12.0, 9.0, 0.0]
    T = path_tensors(obs, prev, acc_C, ACC, SHAPE, cfg)
    assert T.bins.shape == (30, T.Phi.shape[1]) and "jerk" not in cfg.feature_names
    y = rng.integers(0, 5, 30)
    y[:2] = [4, 0]  # out of reach of every lagged choice: the floor keeps it finite
    theta = rng.normal(0.0, 0.3, len(cfg.feature_names))

    def ll(th: np.ndarray) -> float:
        return loglik_grad(th, T, y, backup, cfg.collision_penalty)[0]

    assert np.isfinite(ll(theta))
    g = loglik_grad(theta, T, y, backup, cfg.collision_penalty)[1]
    eps = 1e-6
    num = np.array([(ll(theta + eps * e) - ll(theta - eps * e)) / (2 * eps) for e in np.eye(theta.size)])
    np.testing.assert_allclose(g, num, rtol=1e-5, atol=1e-6)
    lp = bin_log_policy(T, theta, backup, cfg.collision_penalty)
    np.testing.assert_allclose(np.exp(lp).sum(axis=1), 1.0)
    assert ll(theta) == pytest.approx(float(lp[np.arange(30), y].sum()))


def test_lag_applies_to_the_first_step_and_bins() -> None:
    cfg = PlannerConfig(horizon_s=0.9, grid="g13", lag=0.5, jerk=False)
    obs, _, acc_C = random_obs(2, np.random.default_rng(0))
    prev = np.array([-10.0, np.nan])
    T = path_tensors(obs, prev, acc_C, ACC, SHAPE, cfg)
    fine = cfg.fine_grid(ACC)
    np.testing.assert_array_equal(T.bins, actions_of(np.stack([0.5 * -10.0 + 0.5 * fine, 0.5 * fine])))
    np.testing.assert_array_equal(T.take(np.array([1])).bins, T.bins[1:])
    for bad in (0.0, 1.5, True):
        with pytest.raises(ConfigError, match="lag"):
            PlannerConfig(lag=bad)
    with pytest.raises(ConfigError, match="v0_ft_s"):
        PlannerConfig(v0_ft_s=-1.0)


def test_fixed_jerk_weight_is_kept_and_the_rest_fitted() -> None:
    rng = np.random.default_rng(5)
    cfg = PlannerConfig(horizon_s=0.9, grid="g13", jerk=True, jerk_weight=-2.0)
    obs, prev, acc_C = random_obs(200, rng)
    T = path_tensors(obs, prev, acc_C, ACC, SHAPE, cfg)
    y = rng.integers(0, 5, 200)
    fit = fit_planner(T, y, cfg, l2=0.1)
    j = cfg.feature_names.index("jerk")
    assert fit.theta[j] == -2.0 and fit.converged and fit.grad_norm < 1e-4
    ll, g = loglik_grad(fit.theta, T, y, cfg.backup, cfg.collision_penalty)
    assert ll == pytest.approx(fit.loglik)
    free = np.arange(fit.theta.size) != j
    np.testing.assert_allclose((-g + 0.1 * fit.theta)[free] / 200, 0.0, atol=1e-4)
    with pytest.raises(ConfigError, match="jerk_weight"):
        PlannerConfig(jerk_weight=1.0)
