"""Demonstrations out (sim.merges.transitions): encounter tables, NGSIM files and closed-loop decision
logs as transition arrays; the .npz round trip; imitation's Trajectory objects; and, on a real
SUMO run, the exported observations equal to what the controller observed."""

from __future__ import annotations

import sys
import types
import warnings
from dataclasses import dataclass

import numpy as np
import pandas as pd
import pytest
from sim_testutil import cache_env, short_run

from irl.domains.merge.actions import actions_of
from irl.domains.merge.mdp import ShortEncounterWarning
from merge_irl.units import M_PER_FT
from sim.closed_loop.config import ControllerConfig
from sim.closed_loop.controller import Controller
from sim.drivers.observe import CONTINUOUS_NAMES
from sim.drivers.policy import SumoPolicy
from sim.merges.encounters import extract
from sim.merges.take_over import TakeOverRule
from sim.merges.transitions import (
    Transitions,
    TransitionsError,
    concatenate,
    from_decisions,
    from_encounters,
    load,
    rollout_transitions,
    save,
    to_imitation_trajectories,
)


def encounter_table(sizes=(10, 7, 6), seed=0) -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    n = sum(sizes)
    d_ac = rng.uniform(20, 200, n)
    v_ac = rng.normal(0, 5, n)
    d_ac[:2] = v_ac[:2] = np.nan  # no lead car C
    return pd.DataFrame({
        "encounter_id": np.repeat(np.arange(len(sizes)) + 11, sizes),
        "Frame_ID": np.concatenate([np.arange(s) + 100 for s in sizes]),
        "d_AC": d_ac, "d_AB": rng.uniform(-40, 100, n), "v_AC": v_ac, "v_AB": rng.normal(0, 5, n),
        "B_is_truck": False, "acc_A": rng.normal(0, 5, n), "v_A": rng.uniform(20, 80, n),
        "len_C": np.where(np.isnan(d_ac), np.nan, 15.0), "len_B": 16.0,
    })


def test_encounters_export_shapes_dones_and_episode_boundaries() -> None:
    df = encounter_table()
    t = from_encounters(df, decision_step_s=0.3)
    # 10 rows: decisions at rows 0, 3, 6; 7 rows: 0, 3; 6 rows: 0, 3 (an incomplete last step dropped)
    rows = np.array([0, 3, 6, 10, 13, 17, 20])
    nxt = np.array([3, 6, 9, 13, 16, 20, 22])  # the row 3 frames later; the 6-row encounter ends at row 22
    assert t.obs.shape == (7, 7) and t.next_obs.shape == (7, 7) and t.obs.dtype == np.float64
    assert t.acts.dtype == np.int64 and t.dones.dtype == bool and t.episode.dtype == np.int64
    assert t.obs_names == CONTINUOUS_NAMES and t.decision_step_s == 0.3
    assert t.episode.tolist() == [0, 0, 0, 1, 1, 2, 2] and t.n_episodes == 3
    assert t.dones.tolist() == [False, False, True, False, True, False, True]
    want = df[list(CONTINUOUS_NAMES)].to_numpy()
    np.testing.assert_array_equal(t.obs, want[rows])
    np.testing.assert_array_equal(t.next_obs, want[nxt])
    assert np.isnan(t.obs[0, 0]) and np.isnan(t.obs[0, 5])  # no C: NaN, as the controller observes
    step_acc = np.array([df.acc_A.to_numpy()[r:r + 3].mean() for r in rows])
    np.testing.assert_array_equal(t.acts, actions_of(step_acc))
    np.testing.assert_allclose(t.acc_mps2, step_acc * M_PER_FT)
    # every frame a decision: next_obs is the next row, also across an encounter's end
    t1 = from_encounters(df, decision_step_s=0.1)
    assert t1.n == len(df) and t1.dones.sum() == 3
    np.testing.assert_array_equal(t1.next_obs[~t1.dones], t1.obs[1:][~t1.dones[:-1]])
    # missing lengths: NaN; no speed of A: refused
    assert np.isnan(from_encounters(df.drop(columns=["len_C", "len_B"])).obs[:, 5:]).all()
    with pytest.raises(TransitionsError, match="v_A"):
        from_encounters(df.drop(columns=["v_A"]))
    with pytest.raises(TransitionsError, match="multiple of 0.1"):
        from_encounters(df, decision_step_s=0.25)


def test_npz_round_trip_and_bad_files(tmp_path) -> None:
    t = concatenate([from_encounters(encounter_table()), from_encounters(encounter_table((8, 9), seed=1))])
    assert t.episode.tolist()[-5:] == [3, 3, 4, 4, 4] and t.n_episodes == 5  # 8 rows: 2 decisions, 9: 3
    path = save(t, tmp_path / "demos.npz")
    back = load(path)
    for k in ("obs", "acts", "next_obs", "dones", "episode", "acc_mps2"):
        np.testing.assert_array_equal(getattr(back, k), getattr(t, k))
        assert getattr(back, k).dtype == getattr(t, k).dtype
    assert back.obs_names == t.obs_names and back.decision_step_s == t.decision_step_s
    with np.load(path) as z:  # plain numpy reads it, no pickle
        assert z["obs"].shape == t.obs.shape and str(z["format"]) == "merge-irl-transitions/1"
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    np.savez(tmp_path / "other.npz", format=np.array("something/1"))
    np.savez(tmp_path / "partial.npz", format=np.array("merge-irl-transitions/1"), obs=t.obs)
    for name, said in (("none.npz", "no such"), ("junk.npz", "cannot read"), ("other.npz", "something/1"),
                       ("partial.npz", "missing array")):
        with pytest.raises(TransitionsError, match=said):
            load(tmp_path / name)
    with pytest.raises(TransitionsError, match="dones"):
        Transitions(t.obs, t.acts, t.next_obs, ~t.dones, t.episode)
    with pytest.raises(TransitionsError, match="episode"):
        Transitions(t.obs, t.acts, t.next_obs, t.dones, t.episode[::-1])
    with pytest.raises(TransitionsError, match="acts"):
        Transitions(t.obs, t.acts + 5, t.next_obs, t.dones, t.episode)
    with pytest.raises(TransitionsError, match="next_obs"):
        Transitions(t.obs, t.acts, t.next_obs[:-1], t.dones, t.episode)


def test_decision_log_export() -> None:
    # two controls interleaved in frame order, as the controller logs them
    log = pd.DataFrame({
        "frame": [10, 11, 13, 14, 16, 19], "a_id": [1, 2, 1, 2, 1, 2], "b_id": [5, 6, 5, 6, 5, 6],
        "action": [0, 2, 1, 3, 4, 2], "acc_cmd": [-8.0, 0.0, -2.7, 2.7, 8.0, 0.0], "speed_A": np.arange(6.0) + 40,
        "d_AC": np.arange(6.0) + 100, "d_AB": np.arange(6.0), "v_AC": np.ones(6), "v_AB": np.zeros(6),
        "len_C": 15.0, "len_B": 16.0,
    })
    t = from_decisions(log)
    assert t.decision_step_s == pytest.approx(0.3)  # the frame step between one control's decisions
    assert t.episode.tolist() == [0, 0, 0, 1, 1, 1] and t.dones.tolist() == [False, False, True] * 2
    assert t.acts.tolist() == [0, 1, 4, 2, 3, 2]
    np.testing.assert_allclose(t.acc_mps2, np.array([-8.0, -2.7, 8.0, 0.0, 2.7, 0.0]) * M_PER_FT)
    assert t.obs[:, 4].tolist() == [40, 42, 44, 41, 43, 45]  # v_A is the log's speed_A
    np.testing.assert_array_equal(t.next_obs[[0, 1, 3, 4]], t.obs[[1, 2, 4, 5]])
    np.testing.assert_array_equal(t.next_obs[[2, 5]], t.obs[[2, 5]])  # nothing observed after the release
    with pytest.raises(TransitionsError, match="missing column"):
        from_decisions(log.drop(columns=["speed_A"]))
    with pytest.raises(TransitionsError, match="action indices"):
        from_decisions(log.assign(action=7))


@dataclass(frozen=True)
class _FakeTrajectory:  # imitation.data.types.Trajectory's fields
    obs: np.ndarray
    acts: np.ndarray
    infos: object
    terminal: bool


def test_imitation_trajectories_through_a_stand_in_module(monkeypatch) -> None:
    t = from_encounters(encounter_table())
    for name in ("imitation", "imitation.data"):
        monkeypatch.setitem(sys.modules, name, types.ModuleType(name))
    fake = types.ModuleType("imitation.data.types")
    fake.Trajectory = _FakeTrajectory  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "imitation.data.types", fake)
    trajs = to_imitation_trajectories(t)
    assert len(trajs) == 3 and [len(tr.acts) for tr in trajs] == [3, 2, 2]
    for tr, rows in zip(trajs, t.episodes()):
        assert tr.obs.shape == (len(rows) + 1, 7) and tr.terminal and tr.acts.dtype == np.int64
        np.testing.assert_array_equal(tr.obs[:-1], t.policy_obs()[rows])
        np.testing.assert_array_equal(tr.obs[-1], t.policy_next_obs()[rows[-1]])
        assert np.isfinite(tr.obs).all()
    cont = to_imitation_trajectories(t, action="continuous")
    assert cont[0].acts.shape == (3, 1) and cont[0].acts.dtype == np.float32
    with pytest.raises(TransitionsError, match="'discrete' or 'continuous'"):
        to_imitation_trajectories(t, action="both")
    monkeypatch.setitem(sys.modules, "imitation.data.types", None)  # not installed
    with pytest.raises(TransitionsError, match="pip install imitation"):
        to_imitation_trajectories(t)


def test_exported_encounters_are_what_the_controller_observes(tmp_path) -> None:
    ctl = Controller(SumoPolicy(), ControllerConfig())  # observes SUMO's driver every 0.3 s
    res = short_run(tmp_path, seed=2001, duration_s=200.0, hooks=[ctl])
    enc = extract(
        res.table, take_over=TakeOverRule.of_controller(ControllerConfig(), res.aux_lane_start_ft),
        teleported=res.teleported_vehicle_ids).frames
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ShortEncounterWarning)
        t = from_encounters(enc, decision_step_s=ctl.decision_step_s)
    dec = ctl.decision_table()
    g = enc.groupby("encounter_id", sort=False)
    ids = g[["A_id", "B_id"]].first().to_numpy()[g.size().to_numpy() >= 3]  # shorter than a step: no decision
    assert t.n_episodes == len(ids) >= 5
    logged = from_decisions(dec, decision_step_s=ctl.decision_step_s)
    matched = 0
    for (a, b), rows in zip(ids, t.episodes()):
        mine = dec[(dec.a_id == a) & (dec.b_id == b)].sort_values("frame")
        obs = mine[["d_AC", "v_AC", "d_AB", "v_AB", "speed_A", "len_C", "len_B"]].to_numpy()
        # the controller's decisions of that control, from the take-over, every 3 frames: the same observations
        assert len(mine) >= len(rows)
        np.testing.assert_allclose(t.obs[rows], obs[:len(rows)], rtol=0, atol=1e-9)
        np.testing.assert_allclose(t.next_obs[rows[:-1]], obs[1:len(rows)], rtol=0, atol=1e-9)
        assert (np.diff(mine.frame.to_numpy()[:len(rows)]) == 3).all()
        matched += len(rows)
    assert matched >= 30 and np.isnan(t.obs[:, 0]).any() == np.isnan(logged.obs[:, 0]).any()
    assert logged.n == len(dec) and logged.dones.sum() == dec.groupby(["a_id", "b_id"]).ngroups


@pytest.mark.sumo
def test_rollout_of_a_callable_policy(tmp_path) -> None:
    from sim.drivers.callables import CallablePolicy

    with cache_env(tmp_path):
        t = rollout_transitions("synthetic", CallablePolicy(lambda obs: -0.5, name="soft-brake"), 7,
                                duration_s=110.0)
    assert t.n > 0 and t.n_episodes >= 1 and t.dones.sum() == t.n_episodes and t.decision_step_s == 0.3
    assert (t.acts == 1).all()  # -0.5 m/s^2 is Low Brake
    np.testing.assert_allclose(t.acc_mps2, -0.5)  # applied as returned (A's emergency deceleration is far)
    assert np.isfinite(t.obs[:, 2:5]).all()


def test_a_recordings_gap_ends_an_episode_and_no_next_obs_lies_across_it():
    """Exported transitions split where frames are missing, as learning does."""
    import warnings as _w

    from irl_testdata import encounter_table

    from irl.domains.merge.mdp import FrameGapWarning
    from sim.merges.transitions import from_encounters

    df = encounter_table(n=1, rows=60)
    gapped = df[~df.Frame_ID.between(1018, 1031)].reset_index(drop=True)  # 18 rows, then 14 frames missing
    with _w.catch_warnings(record=True) as said:
        _w.simplefilter("always")
        tr = from_encounters(gapped, decision_step_s=0.3)
    assert [w.category for w in said] == [FrameGapWarning]
    assert len(set(tr.episode.tolist())) == 2 and int(tr.dones.sum()) == 2
    last = int(np.flatnonzero(tr.episode == 0)[-1])  # the first part's last decision: frame 1015
    v_a = list(tr.obs_names).index("v_A")
    before = gapped[gapped.Frame_ID < 1018]
    # k = 3 frames later is beyond the part: its next observation is the part's own last row
    # (frame 1017), not the first row after the gap (frame 1032)
    assert tr.next_obs[last, v_a] == before["v_A"].iloc[-1]
