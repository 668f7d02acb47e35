"""Closed-loop evaluation: applied accelerations from the model, decision step,
baseline drivers, safety filter, collision-rate interval, Wasserstein distances, model flags."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from analysis.evaluation.aggregate import aggregate, rate_ci95
from analysis.evaluation.distances import TTC_CAP_S, ttc_to_c, w1_to_demos
from analysis.evaluation.metrics import EpisodeMetrics
from analysis.evaluation.thresholds import check_thresholds, parse_thresholds
from irl.baselines import BaselinePolicy
from irl.config import IRLConfig
from irl.domains.merge.actions import ACTION_ACC_FT_S2
from irl.domains.merge.bins import MergeBins
from irl.result import SavedModel
from sim.drivers.learned import BaselineTabularPolicy, LearnedPolicy, model_flags
from sim.drivers.observe import MergeObservation

EDGES = MergeBins.assumed_authors()


def test_collision_rate_interval_is_wilson():
    rate, lo, hi = rate_ci95(0, 30)
    assert rate == 0 and lo == pytest.approx(0.0, abs=1e-12)
    assert hi == pytest.approx(1.96 ** 2 / (30 + 1.96 ** 2), rel=1e-3)  # Wilson upper bound at k = 0
    rate, lo, hi = rate_ci95(3, 10)
    assert lo < 0.3 < hi < 0.61
    assert all(np.isnan(rate_ci95(0, 0)))


def test_wasserstein_distances_to_demos():
    rng = np.random.default_rng(0)
    demos = pd.DataFrame({"v_A": rng.normal(60, 5, 400), "acc_A": rng.normal(0, 3, 400),
                          "d_AC": rng.uniform(20, 200, 400), "v_AC": rng.normal(1, 3, 400)})
    dec = pd.DataFrame({"speed_A": demos["v_A"] + 2.0, "acc_cmd": demos["acc_A"], "d_AC": demos["d_AC"] + 10.0,
                        "v_AC": demos["v_AC"]})
    w = w1_to_demos(dec, demos)
    assert w["w1_speed_A_ft_s"] == pytest.approx(2.0)
    assert w["w1_acc_A_ft_s2"] == pytest.approx(0.0, abs=1e-12)
    assert w["w1_d_AC_ft"] == pytest.approx(10.0)
    assert w["w1_ttc_s"] > 0
    assert np.isnan(w1_to_demos(dec, demos.drop(columns="v_A"))["w1_speed_A_ft_s"])
    ttc = ttc_to_c(np.array([100.0, 100.0, np.nan, 1000.0]), np.array([10.0, -1.0, 2.0, 1.0]))
    assert ttc.tolist() == [10.0, TTC_CAP_S]


def test_markov_baseline_driver_follows_the_previous_action():
    log_first = np.log(np.full((1250, 5), 0.2))
    nxt = np.full((5, 5), 0.05)
    np.fill_diagonal(nxt, 0.8)
    pol = BaselineTabularPolicy(BaselinePolicy("markov", log_first, np.log(nxt)), EDGES)
    assert pol.name == "markov"
    obs = MergeObservation(50.0, 10.0, 0.0, 0.0, False, state=3, prev_action=4)
    assert np.argmax(pol.probs(obs)) == 4 and pol.probs(obs).sum() == pytest.approx(1.0)
    first = MergeObservation(50.0, 10.0, 0.0, 0.0, False, state=3)
    assert pol.probs(first) == pytest.approx(np.full(5, 0.2))


def _model(**kw) -> SavedModel:
    return SavedModel(method="qavg", theta=np.zeros(3), loglik=-1.0, q=np.zeros((1250, 5)), config=IRLConfig(),
                      domain="merge", bin_edges={k: tuple(v) for k, v in EDGES.to_dict().items()}, **kw)


def test_flags_reach_the_policy_the_metrics_and_the_gate():
    m = _model(converged=False, unbounded=True, info={"extra": {"infeasible": 1.0}})
    assert model_flags(m) == ("not_converged", "unbounded", "infeasible")
    pol = LearnedPolicy.from_model(m)
    assert pol.flags == ("not_converged", "unbounded", "infeasible")
    assert LearnedPolicy.from_model(_model()).flags == ()
    ep = EpisodeMetrics("qavg", 1, 2, 1, 0, 0, 0, 0, 0, 5.0, 1.0, 20.0, 60.0, (1, 0, 0, 0, 0), 0.1)
    flagged = aggregate([ep], flags=pol.flags)
    clean = aggregate([ep])
    assert flagged.flagged == 1 and clean.flagged == 0
    breaches = check_thresholds(parse_thresholds("flagged>0"), {"qavg": flagged.to_dict(), "sumo": clean.to_dict()})
    assert [b.policy for b in breaches] == ["qavg"]
    from analysis.evaluation.report import flag_lines, report_table

    assert "FLAGGED: not_converged, unbounded, infeasible" in report_table({"qavg": flagged})
    assert len(flag_lines({"qavg": flagged, "sumo": clean})) == 1


def test_old_model_defaults_and_bad_accelerations():
    pol = LearnedPolicy.from_model(_model())
    assert pol.action_acc_ft_s2 == tuple(float(x) for x in ACTION_ACC_FT_S2)  # bin midpoints
    assert pol.decision_step_s == pytest.approx(0.1) and pol.state_encoding == "paper"
    from sim.drivers.policy import PolicyError

    with pytest.raises(PolicyError, match="action_acc_ft_s2"):
        LearnedPolicy(pol.log_pi, EDGES, action_acc_ft_s2=(1.0, 2.0))


@pytest.mark.sumo
def test_learned_driver_applies_its_action_accelerations_on_its_step():
    """A model that always picks Zero whose saved Zero acceleration is +3 ft/s^2, deciding every 0.5 s."""
    from analysis.evaluation.episode import run_episode
    from sim.closed_loop.config import ControllerConfig

    lp = np.full((1250, 5), -50.0)
    lp[:, 2] = 0.0
    lp -= np.log(np.exp(lp).sum(axis=1, keepdims=True))
    pol = LearnedPolicy(lp, EDGES, "zero-plus", action_acc_ft_s2=(-12.0, -3.0, 3.0, 3.5, 7.0), decision_step_s=0.5)
    r = run_episode("synthetic", pol, 3, duration_s=110.0, controller=ControllerConfig(), keep_table=True)
    dec = r.decisions
    assert len(dec) >= 10
    assert (dec.action == 2).all() and np.allclose(dec.acc_cmd, 3.0)
    for _, d in dec.groupby("a_id"):
        assert set(np.diff(d.frame.to_numpy()) % 5) == {0}  # every 0.5 s = 5 frames
    t = r.table.set_index(["Vehicle_ID", "Frame_ID"]).sort_index()
    row = dec.iloc[0]
    nxt = t.loc[(int(row.a_id), int(row.frame) + 1)]
    now = t.loc[(int(row.a_id), int(row.frame))]
    assert nxt.v_Vel - now.v_Vel == pytest.approx(0.3, abs=1e-6)  # 3 ft/s^2 over 0.1 s


@pytest.mark.sumo
def test_safety_filter_intervenes_and_prevents_rear_end_collisions():
    """Always High Accel runs A into its leader (raw); the filter brakes instead and says how often."""
    from analysis.evaluation.episode import run_episode
    from sim.closed_loop.config import ControllerConfig
    from sim.drivers.policy import ConstantPolicy

    raw = run_episode("synthetic", ConstantPolicy(4), 5, duration_s=150.0)
    safe = run_episode("synthetic", ConstantPolicy(4), 5, duration_s=150.0,
                       controller=ControllerConfig(safety_ttc_s=3.0))
    assert raw.metrics.a_collisions >= 1 and raw.metrics.safety_interventions == 0
    assert safe.metrics.safety_interventions > 0
    assert safe.metrics.a_collisions < raw.metrics.a_collisions
    f = safe.decisions[safe.decisions.filtered.astype(bool)]
    assert len(f) == safe.metrics.safety_interventions and (f.action < 4).all()
    assert (safe.controls.n_interventions.sum()) == safe.metrics.safety_interventions


def test_driver_encoded_model_reaches_the_policy_and_the_heldout_loglik():
    from analysis.evaluation.heldout_scoring import HeldOut, policy_heldout_loglik
    from irl.domains.merge.actions import actions_of

    rng = np.random.default_rng(3)
    m = SavedModel(method="mlirl", theta=np.zeros(3), loglik=-1.0, q=rng.normal(size=(6250, 5)), config=IRLConfig(),
                   domain="merge", bin_edges={k: tuple(v) for k, v in EDGES.to_dict().items()},
                   state_encoding="driver", decision_step_s=0.3, action_acc_ft_s2=(-12.3, -3.0, 0.1, 3.0, 7.5))
    pol = LearnedPolicy.from_model(m)
    assert pol.state_encoding == "driver" and pol.decision_step_s == 0.3
    assert pol.action_acc_ft_s2 == (-12.3, -3.0, 0.1, 3.0, 7.5)
    n = 40
    df = pd.DataFrame({"encounter_id": np.repeat([1, 2], n // 2), "d_AC": rng.uniform(10, 200, n),
                       "d_AB": rng.uniform(-20, 120, n), "v_AC": rng.normal(0, 5, n), "v_AB": rng.normal(0, 5, n),
                       "B_is_truck": rng.random(n) < 0.2, "acc_A": rng.normal(0, 4, n)})
    a = actions_of(df["acc_A"].to_numpy())
    # scored as learning sees it: 0.3 s decisions (3 frames; action = mean acc_A over the step),
    # driver states = paper state at the decision's first frame x the previous decision's action
    # (an encounter's first decision only supplies that previous action)
    paper = EDGES.encode(df)
    s_exp, a_exp = [], []
    for e in (0, n // 2):
        step_act = actions_of(df["acc_A"].to_numpy()[e:e + 18].reshape(6, 3).mean(axis=1))
        s_exp += [paper[e + 3 * j] * 5 + step_act[j - 1] for j in range(1, 6)]
        a_exp += list(step_act[1:])
    total, per_step = policy_heldout_loglik(pol, HeldOut(df, np.bincount(a, minlength=5)))
    assert total == pytest.approx(pol.log_pi[s_exp, a_exp].sum()) and per_step == pytest.approx(total / 10)
