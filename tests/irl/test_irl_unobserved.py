"""Pairs with no observed successor under Q-Avg and Q-SM (irl.unobserved_successors): hand-computed Q on a
3-state example, finite-difference gradients, configuration checks, model.json round trip."""

import json

import numpy as np
import pandas as pd
import pytest
from irl_testdata import random_mdp

from analysis.cli.main import main
from irl.bellman.fixed_point import iteration_fixed_point
from irl.boltzmann import demo_counts, loglik_from_counts, loglik_grad_from_counts
from irl.config import IRLConfig
from irl.demonstrations import Demonstrations
from irl.domains.merge.bins import MergeBins
from irl.domains.merge.mdp import kinematic_successors
from irl.errors import ConfigError, DemonstrationError
from irl.fit import fit
from irl.methods.boltzmann_fit import ExactBoltzmann
from irl.methods.qavg import qavg_basis, qavg_q
from irl.problems import DOMAINS, load_problem
from irl.result import SavedModel
from irl.unobserved_successors import fallback_successors, free_successors

# One trajectory 0 -a0-> 1 -a1-> 2 (last step: action 0 in state 2). Observed successors:
# (0,0) -> 1 and (1,1) -> 2; every other pair has none. One-hot features: theta is R.
R = np.array([[1.0, 2.0], [3.0, 4.0], [0.0, 6.0]])
THETA = R.ravel()
GAMMA = 0.5
#: the kinematic test's successors of the unobserved pairs ((0,0) and (1,1) are observed)
NEXT = np.array([[0, 2], [0, 0], [2, 1]])


def tiny_demos() -> Demonstrations:
    return Demonstrations(states=(np.array([0, 1, 2]),), actions=(np.array([0, 1, 0]),),
                          features=np.eye(6).reshape(3, 2, 6), n_states=3, n_actions=2, source="tiny")


def config(rule: str, **kw) -> IRLConfig:
    return IRLConfig(gamma=GAMMA, unobserved=rule, **kw)


def test_terminal_rule_is_the_paper_q():
    # Q(2,.) = R(2,.); Q(1,1) = 4 + .5 mean(0, 6) = 5.5; Q(1,0) = 3;
    # Q(0,0) = 1 + .5 mean(3, 5.5) = 3.125; Q(0,1) = 2
    want = np.array([[3.125, 2.0], [3.0, 5.5], [0.0, 6.0]])
    np.testing.assert_allclose(qavg_q(THETA, tiny_demos(), config("terminal")), want, atol=1e-12)


def test_self_rule_q_avg_by_hand():
    # state 2: m2 = mean(0, 6) / (1 - .5) = 6, Q(2,.) = R(2,.) + 3 = (3, 9)
    # state 1: Q(1,1) = 4 + .5 * 6 = 7; m1 = (3 + 7) / 1.5 = 20/3; Q(1,0) = 3 + 10/3 = 19/3
    # state 0: Q(0,0) = 1 + .5 * 20/3 = 13/3; m0 = (2 + 13/3) / 1.5 = 38/9; Q(0,1) = 2 + 19/9 = 37/9
    want = np.array([[13 / 3, 37 / 9], [19 / 3, 7.0], [3.0, 9.0]])
    np.testing.assert_allclose(qavg_q(THETA, tiny_demos(), config("self")), want, atol=1e-12)


def test_kinematic_rule_q_avg_satisfies_its_equations():
    # successors: observed (0,0)->1, (1,1)->2; from NEXT (0,1)->2, (1,0)->0, (2,0)->2, (2,1)->1.
    # Q = R + .5 mean_b Q(s', b) is linear: solve it here with the test's own 6x6 system.
    succ_of = {(0, 0): 1, (1, 1): 2, (0, 1): 2, (1, 0): 0, (2, 0): 2, (2, 1): 1}
    m = np.zeros((6, 6))
    for (s, a), s2 in succ_of.items():
        m[s * 2 + a, s2 * 2: s2 * 2 + 2] = 0.5
    want = np.linalg.solve(np.eye(6) - GAMMA * m, R.ravel()).reshape(3, 2)
    got = qavg_q(THETA, tiny_demos(), config("kinematic"), fallback_next=NEXT)
    np.testing.assert_allclose(got, want, atol=1e-12)
    # the observed pairs keep their observed successor: NEXT[0, 0] = 0 is not used
    assert got[0, 0] == pytest.approx(1.0 + GAMMA * got[1].mean())


def test_self_rule_q_sm_satisfies_the_boltzmann_backup():
    beta = 0.8
    succ = free_successors(tiny_demos(), config("self"))
    assert not succ.terminal.any()
    fp = iteration_fixed_point(R, succ, beta, GAMMA)
    assert fp.converged
    q = fp.q

    def v(s):
        p = np.exp(beta * (q[s] - q[s].max()))
        p /= p.sum()
        return float(p @ q[s])

    succ_of = {(0, 0): 1, (1, 1): 2, (0, 1): 0, (1, 0): 1, (2, 0): 2, (2, 1): 2}
    for (s, a), s2 in succ_of.items():
        assert q[s, a] == pytest.approx(R[s, a] + GAMMA * v(s2), abs=1e-9)


def test_unobserved_rules_change_only_what_they_should():
    d = tiny_demos()
    term = free_successors(d, config("terminal"))
    selfs = free_successors(d, config("self"))
    np.testing.assert_array_equal(term.terminal, [False, True, True, False, True, True])
    rows_observed = [0, 3]
    np.testing.assert_array_equal(term.p[rows_observed].toarray(), selfs.p[rows_observed].toarray())
    np.testing.assert_allclose(np.asarray(selfs.p.sum(axis=1)).ravel(), 1.0)


def central_difference(f, theta, h=1e-5):
    g = np.zeros_like(theta)
    for k in range(theta.size):
        e = np.zeros_like(theta)
        e[k] = h
        g[k] = (f(theta + e) - f(theta - e)) / (2 * h)
    return g


def _next_table(seed, S, A):
    return np.random.default_rng(50 + seed).integers(0, S, size=(S, A))


@pytest.mark.parametrize("rule", ["self", "kinematic"])
@pytest.mark.parametrize("seed", [0, 1])
def test_q_avg_gradient_matches_finite_differences(rule, seed):
    _, demos = random_mdp(seed, n_traj=2, length=4)  # few transitions: many unobserved pairs
    cfg = IRLConfig(beta=0.7, gamma=0.95, unobserved=rule)
    nxt = _next_table(seed, demos.n_states, demos.n_actions) if rule == "kinematic" else None
    counts = demo_counts(demos)
    assert free_successors(demos, IRLConfig()).terminal.sum() > demos.n_states  # the premise
    basis = qavg_basis(demos, cfg.gamma, free_successors(demos, cfg, nxt))
    theta = np.random.default_rng(seed).uniform(-1, 1, demos.n_features)
    _, grad = loglik_grad_from_counts(basis @ theta, basis, cfg.beta, counts)
    fd = central_difference(lambda th: loglik_from_counts(qavg_q(th, demos, cfg, nxt), cfg.beta, counts), theta)
    np.testing.assert_allclose(grad, fd, atol=1e-6 * max(1.0, np.abs(fd).max()), rtol=0)
    assert np.abs(grad).max() > 1e-3


@pytest.mark.parametrize("rule", ["self", "kinematic"])
@pytest.mark.parametrize("seed", [0, 1])
def test_q_sm_gradient_matches_finite_differences(rule, seed):
    _, demos = random_mdp(seed, n_traj=2, length=4)
    cfg = IRLConfig(beta=0.7, gamma=0.9, unobserved=rule)
    nxt = _next_table(seed, demos.n_states, demos.n_actions) if rule == "kinematic" else None
    succ = free_successors(demos, cfg, nxt)
    theta = np.random.default_rng(seed).uniform(-1, 1, demos.n_features)
    e = ExactBoltzmann(demos, succ, cfg).evaluate(theta)
    assert e.ok

    def ll(th):
        out = ExactBoltzmann(demos, succ, cfg).evaluate(th)
        assert out.ok
        return out.loglik

    fd = central_difference(ll, theta)
    np.testing.assert_allclose(e.grad, fd, atol=1e-6 * max(1.0, np.abs(fd).max()), rtol=0)
    assert np.abs(e.grad).max() > 1e-3


@pytest.mark.parametrize("method", ["qavg", "qsm"])
def test_fit_uses_the_rule(method):
    _, demos = random_mdp(3, n_traj=2, length=4)
    rng = np.random.default_rng
    nxt = _next_table(3, demos.n_states, demos.n_actions)
    base = IRLConfig(beta=1.0, gamma=0.9, l2=0.1)
    fits = {rule: fit(method, demos, IRLConfig(**{**base.to_dict(), "unobserved": rule}), rng(0),
                      **({"fallback_next": nxt} if rule == "kinematic" else {}))
            for rule in ("terminal", "self", "kinematic")}
    for rule, r in fits.items():
        assert r.config.unobserved == rule and np.isfinite(r.loglik), r.message
    if method == "qavg":
        for rule, r in fits.items():
            cfg = IRLConfig(**{**base.to_dict(), "unobserved": rule})
            np.testing.assert_allclose(r.q, qavg_q(r.theta, demos, cfg, nxt if rule == "kinematic" else None),
                                       atol=1e-9)
    assert abs(fits["self"].loglik - fits["terminal"].loglik) > 1e-6


def test_bad_settings_are_refused():
    d = tiny_demos()
    with pytest.raises(ConfigError, match="unobserved must be one of"):
        IRLConfig(unobserved="nearest")
    with pytest.raises(ConfigError, match="exact solver"):
        IRLConfig(unobserved="self", solver="faithful")
    with pytest.raises(ConfigError, match="fallback_next"):
        fit("qavg", d, config("kinematic"), np.random.default_rng(0))
    with pytest.raises(ConfigError, match="used by 'kinematic' only"):
        fit("qsm", d, config("self"), np.random.default_rng(0), fallback_next=NEXT)
    with pytest.raises(DemonstrationError, match=r"expected \[3, 2\] states"):
        free_successors(d, config("kinematic"), np.array([[0, 1], [2, 3], [0, 0]]))
    assert fallback_successors("terminal", 3, 2) is None


def _encounter_table(path):
    rng = np.random.default_rng(0)
    n, rows = 4, 30
    pd.DataFrame({
        "encounter_id": np.repeat(np.arange(n), rows), "frame": np.tile(np.arange(rows), n),
        "d_AC": rng.uniform(10, 150, n * rows), "d_AB": rng.uniform(0, 80, n * rows),
        "v_AC": rng.normal(0, 5, n * rows), "v_AB": rng.normal(0, 5, n * rows),
        "B_is_truck": np.repeat([0, 1, 0, 0], rows), "acc_A": rng.normal(0, 3, n * rows),
    }).to_parquet(path)
    return path


def test_rule_is_saved_to_and_loaded_from_model_json(tmp_path):
    table = _encounter_table(tmp_path / "enc.parquet")
    out = tmp_path / "m.json"
    rc = main(["learn", "--method", "qavg", "--domain", "merge", "--demos", str(table), "--features", "paper",
               "--unobserved", "kinematic", "--l2", "0.1", "--out", str(out), "--no-progress"])
    assert rc == 0
    m = SavedModel.load(out)
    assert m.config.unobserved == "kinematic"
    assert json.loads(out.read_text())["settings"]["unobserved"] == "kinematic"
    # the saved Q is Q-Avg's with the kinematic successors at the model's 0.3 s step and its accelerations
    p = load_problem("merge", table, bins=MergeBins.from_dict({k: list(v) for k, v in m.bin_edges.items()}),
                     features="paper")
    nxt = kinematic_successors(p.bins, m.decision_step_s, "paper", m.action_acc_ft_s2)
    np.testing.assert_allclose(m.q, qavg_q(m.theta, p.demos, m.config, nxt), atol=1e-9)
    terminal = qavg_q(m.theta, p.demos, IRLConfig(**{**m.config.to_dict(), "unobserved": "terminal"}))
    assert np.abs(m.q - terminal).max() > 1e-3  # the rule made a difference


def test_learn_default_rule_for_merge_and_old_files(tmp_path):
    table = _encounter_table(tmp_path / "enc.parquet")
    out = tmp_path / "m.json"
    assert main(["learn", "--method", "qavg", "--domain", "merge", "--demos", str(table), "--features", "paper",
                 "--l2", "0.1", "--out", str(out), "--no-progress"]) == 0
    assert SavedModel.load(out).config.unobserved == DOMAINS["merge"].defaults.unobserved
    # a model.json written before the setting existed reads as the paper's terminal pairs
    data = json.loads(out.read_text())
    del data["settings"]["unobserved"]
    out.write_text(json.dumps(data))
    assert SavedModel.load(out).config.unobserved == "terminal"


def test_kinematic_successors_are_the_kinematic_model():
    from irl.domains.merge.mdp import kinematic_model

    bins = MergeBins.assumed_authors()
    nxt = kinematic_successors(bins, 0.3, "paper")
    assert nxt.shape == (1250, 5)
    np.testing.assert_array_equal(nxt, np.argmax(kinematic_model(bins, 0.3).to_dense(), axis=2))
    drv = kinematic_successors(bins, 0.3, "driver")
    assert drv.shape == (6250, 5)
    np.testing.assert_array_equal(drv % 5, np.broadcast_to(np.arange(5), (6250, 5)))  # previous action := a
    np.testing.assert_array_equal(drv // 5, np.repeat(nxt, 5, axis=0))  # the paper part moves as without it
