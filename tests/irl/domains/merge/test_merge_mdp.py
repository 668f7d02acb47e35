"""The merge MDP: discretization of encounter tables, the kinematic fallback model, the authors' files.

The domain itself (bins, encoding, features) is tested in test_domain_merge.py."""


import numpy as np
import pandas as pd
import pytest

from irl.domains.merge import mdp as m
from irl.domains.merge.actions import ACTION_ACC_FT_S2, actions_of
from irl.domains.merge.bins import MergeBins, fit_quantile_bins
from irl.domains.merge.states import VARIABLES, state_index, state_parts
from irl.errors import ConfigError, DemonstrationError


def encounters(n=3, rows=40, seed=0):
    rng = np.random.default_rng(seed)
    return pd.DataFrame({
        "encounter_id": np.repeat(np.arange(n) + 100, rows),
        "frame": np.tile(np.arange(rows), n),
        "d_AC": rng.uniform(5, 200, n * rows),
        "d_AB": rng.uniform(0, 120, n * rows),
        "v_AC": rng.normal(0, 6, n * rows),
        "v_AB": rng.normal(0, 6, n * rows),
        "B_is_truck": np.repeat(np.arange(n) % 2, rows),
        "acc_A": rng.uniform(-11, 11, n * rows),
    })


def test_quantile_bins_and_discretize_are_consistent():
    df = encounters()
    bins = fit_quantile_bins(df)
    assert bins.d_AC[0] == 35.0
    for name in ("d_AB", "v_AC", "v_AB"):
        counts = np.bincount(bins.bin_index(name, df[name]), minlength=5)
        assert np.all(np.abs(counts - len(df) / 5) <= 2)  # quantile bins: equal counts
    d = m.discretize(df, bins, decision_step_s=0.1)
    assert d.n_trajectories == 3 and d.names == ("encounter 100", "encounter 101", "encounter 102")
    s = np.concatenate(d.states)
    parts = state_parts(s)
    assert np.all((parts[:, 1] == 4) == (df["d_AC"].to_numpy() < 35.0))  # bin 4 = closest
    for i, name in enumerate(VARIABLES):
        v = df[name].to_numpy()
        e = np.asarray(getattr(bins, name))
        idx = parts[:, i + 1]
        if name == "d_AC":
            idx = 4 - idx
        assert np.all(v >= np.r_[-np.inf, e][idx]) and np.all(v < np.r_[e, np.inf][idx])
    np.testing.assert_array_equal(parts[:, 0], df["B_is_truck"].to_numpy())
    np.testing.assert_array_equal(np.concatenate(d.actions), actions_of(df["acc_A"]))


def test_discretize_validates_columns():
    df = encounters().drop(columns=["acc_A"])
    with pytest.raises(DemonstrationError, match=r"lacks column\(s\) \['acc_A'\]"):
        m.discretize(df, MergeBins.assumed_authors())
    df = encounters()
    df.loc[5, "v_AB"] = np.nan
    with pytest.raises(DemonstrationError, match=r"row 5, column 'v_AB'"):
        m.discretize(df, MergeBins.assumed_authors())


def test_kinematic_fallback():
    b = MergeBins.assumed_authors()
    # representative values are finite and follow the bin order
    rep = b.representatives("d_AC")
    assert np.all(np.isfinite(rep)) and np.all(np.diff(rep) < 0)
    assert np.all(np.diff(b.representatives("v_AB")) > 0)
    s = state_index(0, 2, 2, 2, 2)  # mid bins; relative speeds 0
    # over a long step, high braking lowers the relative speeds by a bin or more and opens gaps
    nxt = state_parts(m.kinematic_next_state(np.array([s]), np.array([0]), b, decision_step_s=1.0))[0]
    assert nxt[3] < 2 and nxt[4] < 2 and nxt[1] <= 2
    # high acceleration raises them
    nxt = state_parts(m.kinematic_next_state(np.array([s]), np.array([4]), b, decision_step_s=1.0))[0]
    assert nxt[3] > 2 and nxt[4] > 2
    # truck flag never changes; the model is deterministic and row-stochastic
    t = m.kinematic_model(b, decision_step_s=1.0).to_dense()
    np.testing.assert_allclose(t.sum(axis=2), 1.0)
    src, _, dst = np.nonzero(t)
    assert np.all(src // 625 == dst // 625)


def test_authors_merge_trajectories_load(railusm):
    d = m.load(railusm / "merge_ngsim")
    assert d.n_trajectories == 12 and d.n_steps == 1197
    assert d.names[:3] == ("traj_0.txt", "traj_1.txt", "traj_2.txt") and d.names[-1] == "traj_11.txt"
    counts = np.bincount(np.concatenate(d.actions), minlength=5)
    assert dict(enumerate(counts.tolist())) == {0: 108, 1: 168, 2: 693, 3: 128, 4: 100}
    s = np.concatenate(d.states)
    assert np.unique(s).size == 172
    a = np.concatenate(d.actions)
    assert np.unique(s * 5 + a).size == 342  # distinct (s, a) of the authors' 12 trajectories (1197 steps, 172 states)
    src, act, dst = d.transitions()
    pairs = {}
    for x, y, z in zip(src.tolist(), act.tolist(), dst.tolist()):
        pairs.setdefault((x, y), set()).add(z)
    assert sum(len(v) > 1 for v in pairs.values()) == 141
    t = m.estimated_transitions(d, MergeBins.assumed_authors()).to_dense()
    np.testing.assert_allclose(t.sum(axis=2), 1.0)
    src, act, dst = d.transitions()
    assert np.all(t[src, act, dst] > 0)


def test_frames_without_car_c_discretize_by_the_no_lead_rule():
    df = encounters()
    df.loc[[3, 50], ["d_AC", "v_AC"]] = np.nan
    bins = fit_quantile_bins(df)
    d = m.discretize(df, bins, decision_step_s=0.1)
    parts = state_parts(np.concatenate(d.states))
    assert parts[3, 1] == parts[50, 1] == 0  # farthest d_AC bin
    assert parts[3, 3] == bins.bin_index("v_AC", 0.0) == bins.no_lead_v_AC_bin()
    # only one of the two NaN: an error naming the row and the column
    df.loc[7, "d_AC"] = np.nan
    with pytest.raises(DemonstrationError, match=r"row 7, column 'd_AC'.*no car C"):
        m.discretize(df, bins)


def test_resampling_at_the_decision_step_averages_the_forward_differences():
    df = encounters()
    bins = fit_quantile_bins(df)
    r = m.resample_encounters(df, bins, decision_step_s=0.3)
    rows = df[df.encounter_id == 100]
    n = len(rows) // 3
    acc = rows["acc_A"].to_numpy()[: 3 * n].reshape(n, 3).mean(axis=1)
    np.testing.assert_array_equal(r.demos.actions[0], actions_of(acc))
    np.testing.assert_array_equal(r.demos.states[0], bins.encode(rows)[: 3 * n: 3])
    # the driver encoding starts one step later, the previous action from the step before
    d = m.resample_encounters(df, bins, decision_step_s=0.3, encoding="driver", features="driver").demos
    assert d.n_states == 6250 and d.features.shape[2] == len(m.feature_set("driver", bins, "driver").names)
    np.testing.assert_array_equal(d.states[0] % 5, actions_of(acc)[:-1])
    np.testing.assert_array_equal(d.states[0] // 5, bins.encode(rows)[3: 3 * n: 3])
    # per-action mean acceleration of the decisions; midpoint for an action never taken
    all_acc = np.concatenate([g["acc_A"].to_numpy()[: 3 * (len(g) // 3)].reshape(-1, 3).mean(axis=1)
                              for _, g in df.groupby("encounter_id", sort=False)])
    acts = actions_of(all_acc)
    for a in range(5):
        want = all_acc[acts == a].mean() if (acts == a).any() else ACTION_ACC_FT_S2[a]
        assert r.action_acc_ft_s2[a] == pytest.approx(want)
    assert m.action_mean_acc([1.0, 2.0], [3, 3]) == (-8.0, -2.7, 0.0, 1.5, 8.0)
    with pytest.raises(ConfigError, match="multiple of 0.1"):
        m.discretize(df, bins, decision_step_s=0.25)


def test_kinematic_driver_encoding_sets_previous_action():
    bins = MergeBins.assumed_authors()
    s = np.array([7, 400, 1249])
    for a in range(5):
        nd = m.kinematic_next_state(s * 5 + 1, np.full(3, a), bins, 0.3, encoding="driver")
        np.testing.assert_array_equal(nd % 5, a)
        np.testing.assert_array_equal(nd // 5, m.kinematic_next_state(s, np.full(3, a), bins, 0.3))


def test_a_folder_given_as_an_encounter_table_is_named_a_folder(tmp_path):
    from irl.domains.merge.mdp import read_encounters
    from irl.errors import DemonstrationError

    with pytest.raises(DemonstrationError, match="a folder, not an encounter table"):
        read_encounters(tmp_path)
    with pytest.raises(DemonstrationError, match="no such encounter file"):
        read_encounters(tmp_path / "missing.parquet")
