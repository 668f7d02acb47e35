"""Car-following features, their decisions, the car-following logit driver and its file
(irl/domains/merge/car_following.py, irl/domains/merge/cf_logit.py), and its policy and
held-out score in the closed-loop harness."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pandas as pd
import pytest

from analysis.evaluation.heldout_scoring import HeldOut, policy_heldout_loglik
from irl.domains.merge.actions import ZERO_ACTION, actions_of
from irl.domains.merge.bins import MergeBins
from irl.domains.merge.car_following import (
    CF_FEATURES,
    GapNeed,
    car_following_decisions,
    car_following_features,
)
from irl.domains.merge.cf_logit import CarFollowingLogit
from irl.domains.merge.mdp import resample_encounters
from irl.errors import ConfigError, DemonstrationError, ModelFileError
from sim.drivers.learned import CarFollowingLogitPolicy
from sim.drivers.observe import MergeObservation

ACC = (-12.0, -3.0, 0.0, 3.0, 9.0)
COL = {n: i for i, n in enumerate(CF_FEATURES)}


def encounters(n=4, rows=31, seed=0, with_c=True):
    """A table in which A brakes when the gap to C is short (so the gap-need weight is learnable)."""
    rng = np.random.default_rng(seed)
    d_ac = rng.uniform(20, 250, n * rows)
    v_a = rng.uniform(20, 80, n * rows)
    acc = np.where(d_ac < 60, -12.0, rng.choice([-3.0, 0.0, 3.0], n * rows))
    return pd.DataFrame({
        "encounter_id": np.repeat(np.arange(n) + 7, rows),
        "d_AC": d_ac if with_c else np.nan, "v_AC": rng.normal(5, 5, n * rows) if with_c else np.nan,
        "d_AB": rng.uniform(-50, 120, n * rows), "v_AB": rng.normal(0, 5, n * rows),
        "B_is_truck": False, "acc_A": acc, "v_A": v_a,
    })


def test_gap_need_is_the_idm_interaction_term():
    g = GapNeed()
    # s = 100 - length ft, v = 60 ft/s, dv = 10 ft/s: (s*/s)^2 with s* = s0 + v T + v dv / (2 sqrt(a b))
    s_star = g.min_gap_ft + 60 * g.time_headway_s + 60 * 10 / (2 * np.sqrt(g.accel_ft_s2 * g.decel_ft_s2))
    assert g.need(100.0, 60.0, 10.0) == pytest.approx((s_star / (100.0 - g.length_ft)) ** 2)
    assert g.need(g.length_ft + 0.1, 60.0, 10.0) == g.clip  # s floored at 1 ft, then clipped
    # opening fast: the dynamic part is floored at 0, s* = s0
    assert g.need(100.0, 10.0, -50.0) == pytest.approx((g.min_gap_ft / (100.0 - g.length_ft)) ** 2)
    # the leader's own length when known (a 45-ft truck: the bumper gap is 55 ft), a car's when NaN
    assert g.need(100.0, 60.0, 10.0, 45.0) == pytest.approx((s_star / 55.0) ** 2)
    np.testing.assert_allclose(g.need([100.0, 100.0], 60.0, 10.0, [np.nan, 45.0]),
                               [g.need(100.0, 60.0, 10.0), (s_star / 55.0) ** 2])
    with pytest.raises(ConfigError):
        GapNeed(time_headway_s=0.0)


def test_features_by_hand():
    g = GapNeed()
    obs = np.array([[100.0, 10.0, -30.0, 5.0, 60.0, 45.0, 14.0],   # C (a 45-ft truck) ahead, B behind A
                    [np.nan, np.nan, 40.0, -2.0, 30.0, np.nan, 45.0],  # no C, B (a truck) ahead
                    [100.0, 10.0, 40.0, -2.0, 60.0, np.nan, np.nan]])  # lengths unknown: cars
    F = car_following_features(obs, np.array([4, -1, 2]), ACC, g)
    assert F.shape == (3, 5, len(CF_FEATURES))
    acc = np.asarray(ACC) / 8.0
    s_star = g.min_gap_ft + 60 * g.time_headway_s + 60 * 10 / (2 * np.sqrt(g.accel_ft_s2 * g.decel_ft_s2))
    np.testing.assert_allclose(F[0, :, COL["acc_x_gap_need_C"]], acc * (s_star / (100.0 - 45.0)) ** 2)
    np.testing.assert_allclose(F[0, :, COL["acc_x_gap_need_B"]], 0.0)  # B behind A
    np.testing.assert_allclose(F[1, :, COL["acc_x_gap_need_C"]], 0.0)  # no C
    np.testing.assert_allclose(F[1, :, COL["acc_x_gap_need_B"]], acc * g.need(40.0, 30.0, -2.0, 45.0))
    np.testing.assert_allclose(F[2, :, COL["acc_x_gap_need_C"]], acc * g.need(100.0, 60.0, 10.0, g.length_ft))
    np.testing.assert_allclose(F[2, :, COL["acc_x_gap_need_B"]], acc * g.need(40.0, 60.0, -2.0, g.length_ft))
    # the same B taken for a car (length unknown): the bumper gap 25 ft instead of the truck's 1 ft floor
    as_car = car_following_features(np.where(np.arange(7) == 6, np.nan, obs[1])[None], np.array([-1]), ACC, g)
    assert F[1, 0, COL["acc_x_gap_need_B"]] == pytest.approx(acc[0] * g.clip)
    assert as_car[0, 0, COL["acc_x_gap_need_B"]] > 0.5 * acc[0] * g.clip
    np.testing.assert_allclose(F[0, :, COL["acc_x_free_road"]], acc * (60.0 / g.desired_speed_ft_s) ** 4)
    np.testing.assert_array_equal(F[0, :, COL["keep_action"]], [0, 0, 0, 0, 1])
    np.testing.assert_array_equal(F[1, :, COL["keep_action"]], np.arange(5) == ZERO_ACTION)  # unknown: Zero
    np.testing.assert_allclose(F[0, :, COL["jerk"]], np.abs(acc - acc[4]))
    np.testing.assert_array_equal(F[:, :, COL["bias_high_brake"]], [[1, 0, 0, 0, 0]] * 3)
    assert np.isfinite(F).all()
    with pytest.raises(ConfigError, match="len_C, len_B"):
        car_following_features(obs[:, :5], np.array([0, 0, 0]), ACC)  # no lengths: not an observation
    for bad in (-50.0, 0.0, np.inf):
        wrong = obs.copy()
        wrong[2, 6] = bad
        with pytest.raises(ConfigError, match="obs row 2, len_B"):
            car_following_features(wrong, np.array([0, 0, 0]), ACC)
    with pytest.raises(ConfigError, match="whole actions"):
        car_following_features(obs, np.array([0.7, 0, 0]), ACC)
    np.testing.assert_array_equal(car_following_features(obs, np.array([4.0, -1.0, 2.0]), ACC, g), F)


def test_decisions_follow_resample_encounters_with_the_driver_encoding():
    df = encounters()
    dec = car_following_decisions(df, decision_step_s=0.3)
    ref = resample_encounters(df, MergeBins.assumed_authors(), encoding="driver", decision_step_s=0.3)
    states, actions, _ = ref.demos.flat()
    np.testing.assert_array_equal(dec.actions, actions)
    np.testing.assert_array_equal(dec.prev, states % 5)
    assert dec.n == 4 * 9  # 31 rows: 10 whole steps, the first is the previous action only
    # decision j of encounter e observes row 31 e + 3 j (j = 1..9); its action is the mean acc of
    # rows 3j..3j+2 of the encounter, its previous action that of rows 3(j-1)..3j-1
    expected_rows = [31 * e + 3 * j for e in range(4) for j in range(1, 10)]
    np.testing.assert_array_equal(dec.obs[:, :5], df.iloc[expected_rows][["d_AC", "v_AC", "d_AB", "v_AB", "v_A"]].to_numpy(float))
    assert np.isnan(dec.obs[:, 5:]).all()  # a table without lengths: unknown (the features take cars)
    step = actions_of(df["acc_A"].to_numpy().reshape(4, 10 * 3 + 1)[:, :30].reshape(4, 10, 3).mean(axis=2))  # [4, 10]
    np.testing.assert_array_equal(dec.actions, step[:, 1:].ravel())
    np.testing.assert_array_equal(dec.prev, step[:, :-1].ravel())
    assert dec.actions[0] == actions_of(np.array([df["acc_A"][3:6].mean()]))[0]
    assert dec.prev[0] == actions_of(np.array([df["acc_A"][0:3].mean()]))[0]
    assert dec.action_acc_ft_s2 == ref.action_acc_ft_s2
    with pytest.raises(DemonstrationError, match="v_A"):
        car_following_decisions(df.drop(columns=["v_A"]))
    # lengths, where the table has them, are observed with the row (NaN kept: unknown)
    rng = np.random.default_rng(1)
    with_len = df.assign(len_C=rng.uniform(14, 50, len(df)), len_B=np.where(np.arange(len(df)) % 2, 45.0, np.nan))
    got = car_following_decisions(with_len, decision_step_s=0.3)
    np.testing.assert_array_equal(got.obs, with_len.iloc[expected_rows][
        ["d_AC", "v_AC", "d_AB", "v_AB", "v_A", "len_C", "len_B"]].to_numpy(float))
    for bad in (-3.0, 0.0, np.inf, "long"):
        for row in (expected_rows[4], 1):  # a decision's row and a row between decisions: every row is checked
            broken = with_len.astype({"len_C": object})
            broken.loc[row, "len_C"] = bad
            with pytest.raises(DemonstrationError, match=f"row {row}, column 'len_C': .* got {bad!r}$"):
                car_following_decisions(broken, decision_step_s=0.3)
    broken = with_len.copy()
    broken.loc[2, "v_A"] = -3.0
    with pytest.raises(DemonstrationError, match=r"row 2, column 'v_A': .* got -3\.0$"):
        car_following_decisions(broken, decision_step_s=0.3)


def test_fit_learns_to_brake_on_a_short_gap_and_round_trips_through_its_file(tmp_path):
    dec = car_following_decisions(encounters(n=30, seed=1), decision_step_s=0.3)
    model = CarFollowingLogit.fit(dec, l2=0.1)
    assert model.converged and model.info["n_demo_steps"] == dec.n
    assert model.theta[COL["acc_x_gap_need_C"]] < 0  # braking when the gap falls short
    assert model.loglik == pytest.approx(model.loglik_of(dec))
    uniform = dec.n * np.log(1 / 5)
    assert model.loglik > uniform + 100
    path = model.save(tmp_path / "cf_model.json")
    back = CarFollowingLogit.load(path)
    np.testing.assert_array_equal(back.theta, model.theta)
    assert back.action_acc_ft_s2 == model.action_acc_ft_s2 and back.gap_need == model.gap_need
    assert back.loglik == pytest.approx(model.loglik) and back.info == model.info
    lp = back.log_policy(dec.obs, dec.prev)
    np.testing.assert_allclose(np.exp(lp).sum(1), 1.0)
    # the driver is named by its file, as a model file is, and flagged when its fit did not converge
    from analysis.evaluation.policies import cf_policy

    assert cf_policy(path).name == "cf_model" and cf_policy(path).flags == ()
    stuck = dataclasses.replace(model, converged=False).save(tmp_path / "cf-dagger.json")
    assert cf_policy(stuck).name == "cf-dagger" and cf_policy(stuck).flags == ("not_converged",)


def test_labels_enter_the_fit():
    dec = car_following_decisions(encounters(n=10, seed=2), decision_step_s=0.3)
    alone = CarFollowingLogit.fit(dec)
    labels = dataclasses.replace(dec, actions=np.zeros_like(dec.actions))  # an expert who always brakes hard
    both = CarFollowingLogit.fit(dec, labels=labels)
    assert both.info["n_label_steps"] == dec.n
    p_alone = np.exp(alone.log_policy(dec.obs, dec.prev))[:, 0].mean()
    p_both = np.exp(both.log_policy(dec.obs, dec.prev))[:, 0].mean()
    assert p_both > p_alone + 0.1
    assert both.loglik < alone.loglik  # scored on the demonstrations alone


@pytest.mark.parametrize("change, match", [
    (lambda d: d.update(format="merge-irl-model/1"), "expected format.*got 'merge-irl-model/1'"),
    (lambda d: d.update(format="merge-irl-cf-logit/1"), "took every leader for a car.*train it again"),
    (lambda d: d.update(format=[]), r"expected format .* got \[\]"),  # unhashable: no TypeError
    (lambda d: d.pop("theta"), "theta: missing"),
    (lambda d: d.update(theta=[1.0, 2.0]), "theta: must have at least 9 items"),
    (lambda d: d["theta"].__setitem__(3, "a"), r"theta\[3\]: must be a number, got 'a'"),
    (lambda d: d["theta"].__setitem__(0, True), r"theta\[0\]: must be a number, got True"),
    (lambda d: d.update(decision_step_s=True), "decision_step_s: must be a number, got True"),
    (lambda d: d.update(decision_step_s=0.25), "multiple of 0.1"),
    (lambda d: d.update(action_acc_ft_s2=d["action_acc_ft_s2"][::-1]), "must increase"),
    (lambda d: d.update(action_acc_ft_s2="12345"), "action_acc_ft_s2: must be a list, got '12345'"),
    (lambda d: d["gap_need"].pop("clip"), "gap_need.clip: missing"),
    (lambda d: d["gap_need"].update(clip=True), "gap_need.clip: must be a number, got True"),
    (lambda d: d.update(converged="false"), "converged: must be true or false"),
    (lambda d: d.update(info="x"), "info: must be an object"),
    (lambda d: d.update(l2=-5), "l2: must be greater than or equal to 0, got -5"),
    (lambda d: d.update(feature_names=["a"]), "feature_names"),
    (lambda d: d["gap_need"].update(clip=-1), "positive"),
])
def test_bad_model_files_name_the_fault(tmp_path, change, match):
    dec = car_following_decisions(encounters(), decision_step_s=0.3)
    data = CarFollowingLogit.fit(dec).to_json_dict()
    change(data)
    p = tmp_path / "m.json"
    p.write_text(json.dumps(data))
    with pytest.raises(ModelFileError, match=match):
        CarFollowingLogit.load(p)
    p.write_text("{not json")
    with pytest.raises(ModelFileError, match="JSON"):
        CarFollowingLogit.load(p)


def test_policy_and_heldout_score_use_the_model():
    df = encounters(n=8, seed=3)
    dec = car_following_decisions(df, decision_step_s=0.3)
    model = CarFollowingLogit.fit(dec)
    pol = CarFollowingLogitPolicy(model)
    assert pol.decision_step_s == 0.3 and pol.action_acc_ft_s2 == model.action_acc_ft_s2
    o = dec.obs[5]
    p = pol.probs(MergeObservation(d_AC=o[0], d_AB=o[2], v_AC=o[1], v_AB=o[3], b_is_truck=False, speed_A=o[4],
                                   prev_action=int(dec.prev[5])))
    np.testing.assert_allclose(p, np.exp(model.log_policy(dec.obs[5:6], dec.prev[5:6]))[0])
    # before the first decision the initial action stands for the previous one
    first = MergeObservation(d_AC=o[0], d_AB=o[2], v_AC=o[1], v_AB=o[3], b_is_truck=False, speed_A=o[4],
                             prev_action=-1, initial_action=0)
    np.testing.assert_allclose(pol.probs(first), np.exp(model.log_policy(dec.obs[5:6], np.array([0])))[0])
    assert not np.allclose(pol.probs(first), np.exp(model.log_policy(dec.obs[5:6], np.array([4])))[0])
    total, per_step = policy_heldout_loglik(pol, HeldOut(df, np.zeros(5, dtype=np.int64), "test"))
    assert total == pytest.approx(model.loglik_of(dec)) and per_step == pytest.approx(total / dec.n)
