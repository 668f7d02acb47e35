"""Minari: transitions written as a Minari dataset (:mod:`sim.env.minari_dataset`) that
``minari.load_dataset`` reads back with the environment's spaces, per-episode rewards and
terminations and the project's metadata, whose arrays feed the project's own behaviour-cloning
baseline (the ``bc`` of :mod:`irl.baselines`); an existing id refused unless overwritten, a bad
id refused, nothing left behind. And Minari's ``DataCollector`` around :class:`sim.env.merge_env.MergeEnv`
on real SUMO: its default 64-bit seeds and its ``minari_autoseed`` option accepted, the same
seed the same episodes."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from extras import require_extra, require_imitation

from sim.merges.transitions import from_encounters


def encounter_table(sizes=(10, 7, 6, 9), seed=0) -> pd.DataFrame:
    """An encounter table (the columns from_encounters reads; the first rows have no car C)."""
    rng = np.random.default_rng(seed)
    n = sum(sizes)
    d_ac = rng.uniform(20, 200, n)
    v_ac = rng.normal(0, 5, n)
    d_ac[:2] = v_ac[:2] = np.nan
    return pd.DataFrame({
        "encounter_id": np.repeat(np.arange(len(sizes)) + 11, sizes),
        "Frame_ID": np.concatenate([np.arange(s) + 100 for s in sizes]),
        "d_AC": d_ac, "d_AB": rng.uniform(-40, 100, n), "v_AC": v_ac, "v_AB": rng.normal(0, 5, n),
        "B_is_truck": False, "acc_A": rng.normal(0, 5, n), "v_A": rng.uniform(20, 80, n),
        "len_C": np.where(np.isnan(d_ac), np.nan, 15.0), "len_B": 16.0,
    })


def bc_of_episodes(episodes):
    """The project's tabular behaviour cloning (irl.baselines ``bc``) fitted on Minari episodes:
    each observation's paper state (the authors' bins), each action; returns (policy, demos)."""
    from irl.baselines import fit_baseline
    from irl.demonstrations import Demonstrations
    from irl.domains.merge.bins import MergeBins
    from irl.domains.merge.states import n_states

    bins, S = MergeBins.assumed_authors(), n_states("paper")
    states, actions = [], []
    for e in episodes:
        o = e.observations[:-1]  # [n_e, 7]: d_AC, v_AC, d_AB, v_AB, v_A, len_C, len_B (ft, ft/s)
        states.append(bins.states(o[:, 0], o[:, 2], o[:, 1], o[:, 3], np.zeros(len(o), dtype=bool)))
        actions.append(np.asarray(e.actions, dtype=np.int64))
    demos = Demonstrations(tuple(states), tuple(actions), np.zeros((S, 5, 1)), S, 5, source="minari")
    return fit_baseline("bc", demos), demos


def test_transitions_written_to_minari_load_back_and_feed_behaviour_cloning(tmp_path, monkeypatch) -> None:
    minari = require_extra("minari", "rl")
    from irl.baselines import fit_baseline
    from sim.env.merge_env import OBS_HIGH, OBS_LOW
    from sim.env.minari_dataset import METADATA_KEY, write_minari

    t = from_encounters(encounter_table(), decision_step_s=0.3)
    ds = write_minari(t, "merge-irl/demos-v0", root=tmp_path / "data", provenance={"inputs": {"demos": "x"}})
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "data"))
    back = minari.load_dataset("merge-irl/demos-v0")
    assert back.total_episodes == t.n_episodes == ds.total_episodes == 4 and back.total_steps == t.n
    assert back.observation_space.shape == (7,) and back.action_space.n == 5
    np.testing.assert_array_equal(back.observation_space.low, OBS_LOW)
    np.testing.assert_array_equal(back.observation_space.high, OBS_HIGH)
    episodes = list(back.iterate_episodes())
    for e, rows in zip(episodes, t.episodes()):
        n = rows.size
        assert e.observations.shape == (n + 1, 7) and e.actions.shape == (n,)
        np.testing.assert_array_equal(e.observations[:-1], t.policy_obs()[rows])  # no NaN: the env's observation
        np.testing.assert_array_equal(e.observations[-1], t.policy_next_obs()[rows[-1]])
        np.testing.assert_array_equal(e.actions, t.acts[rows])
        np.testing.assert_array_equal(e.rewards, np.zeros(n))
        assert e.terminations.tolist() == [False] * (n - 1) + [True] and not e.truncations.any()
    meta = back.storage.metadata
    assert meta["dataset_id"] == "merge-irl/demos-v0" and meta["algorithm_name"] == "demonstrations"
    mine = meta[METADATA_KEY]
    assert mine["provenance"] == {"inputs": {"demos": "x"}} and mine["decision_step_s"] == 0.3
    assert mine["obs_names"][:2] == ["d_AC", "v_AC"] and mine["action_names"][0] == "High Brake"
    # the arrays feed the project's behaviour cloning: its fit beats uniform on its own data
    bc, demos = bc_of_episodes(episodes)
    assert bc.loglik(demos) > fit_baseline("uniform", demos).loglik(demos)
    assert sum(s.size for s in demos.states) == t.n


def test_an_existing_id_is_refused_unless_overwritten_and_a_bad_id_leaves_nothing(tmp_path, monkeypatch) -> None:
    require_extra("minari", "rl")
    from sim.env.minari_dataset import MinariExportError, write_minari

    monkeypatch.chdir(tmp_path)
    root = Path("data")  # relative, as a command line gives it
    t = from_encounters(encounter_table(), decision_step_s=0.3)
    write_minari(t, "demos-v0", root=root)
    with pytest.raises(MinariExportError, match=r"demos-v0: a Minari dataset .demos-v0. exists already \(replace it with --overwrite"):
        write_minari(t, "demos-v0", root=root)
    t2 = from_encounters(encounter_table(sizes=(12, 9)), decision_step_s=0.3)
    ds = write_minari(t2, "demos-v0", root=root, overwrite=True)
    assert ds.total_episodes == 2  # replaced whole
    for bad in ("demos", "a b-v0", "-v1"):
        with pytest.raises(MinariExportError, match=r"not a Minari dataset id"):
            write_minari(t, bad, root=root)
    assert sorted(os.listdir(root)) == ["demos-v0"]  # no hidden temporary folder left


# -- DataCollector around the environment (real SUMO) -------------------------------------------
def collect(env, n_episodes: int, seed=None, actions_seed: int = 0):
    """``n_episodes`` episodes of a seeded random policy through a DataCollector ``env``. ``seed``
    None: every reset seeded by the collector (64 random bits); else the first reset with
    ``seed`` and the later ones with the collector's seeding off (``minari_autoseed=False``), so
    the environment runs on to its next take-over in the same SUMO run."""
    rng = np.random.default_rng(actions_seed)
    for i in range(n_episodes):
        if seed is None:
            env.reset()
        else:
            env.reset(seed=seed if i == 0 else None, options=None if i == 0 else {"minari_autoseed": False})
        while True:
            _, _, term, trunc, _ = env.step(int(rng.integers(5)))
            if term or trunc:
                break


@pytest.mark.sumo
def test_data_collector_records_the_environment_with_its_64_bit_seeds(tmp_path, monkeypatch) -> None:
    minari = require_extra("minari", "rl")
    require_extra("jax", "rl")  # Minari's DataCollector needs jax (minari[create])
    from sim.env import MergeEnv
    from sim.env.seeds import SUMO_SEED_LIMIT

    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path))
    env = minari.DataCollector(MergeEnv(run_s=240.0), data_format="arrow")
    try:
        collect(env, 2)  # every reset: DataCollector's own seed, 64 random bits
        ds = env.create_dataset("merge-irl/collected-v0", algorithm_name="random", description="two episodes")
        seeds = [m["seed"] for m in ds.storage.get_episode_metadata([0, 1])]
        assert ds.total_episodes == 2 and all(isinstance(s, int) and s >= 0 for s in seeds)
        assert max(seeds) >= SUMO_SEED_LIMIT  # a seed SUMO could not take as it is (both below 2**31: odds 2**-66)
        # minari_autoseed=False: the collector passes it on to reset, which reads it as no option
        obs, info = env.reset(options={"minari_autoseed": False})
        assert obs.shape == (7,)
    finally:
        env.close()


@pytest.mark.sumo
def test_a_fixed_64_bit_seed_gives_the_same_collected_episodes(tmp_path, monkeypatch) -> None:
    minari = require_extra("minari", "rl")
    require_extra("jax", "rl")
    from sim.env import MergeEnv
    from sim.env.seeds import sumo_seed

    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path))
    runs = []
    for k in range(2):
        env = minari.DataCollector(MergeEnv(run_s=240.0), data_format="arrow")
        try:
            collect(env, 2, seed=2**63 + 5)
            ds = env.create_dataset(f"merge-irl/seeded{k}-v0", algorithm_name="random", description="seeded")
        finally:
            env.close()
        runs.append(list(ds.iterate_episodes()))
        assert [m.get("seed") for m in ds.storage.get_episode_metadata([0, 1])] == [2**63 + 5, None]
    a, b = runs
    assert len(a) == len(b) == 2
    for x, y in zip(a, b):
        np.testing.assert_array_equal(x.observations, y.observations)
        np.testing.assert_array_equal(x.actions, y.actions)
        np.testing.assert_array_equal(x.rewards, y.rewards)
    env = MergeEnv(run_s=240.0)
    try:
        _, info = env.reset(seed=2**63 + 5)
        assert info["seed"] == sumo_seed(2**63 + 5)  # the documented mapping is the run's SUMO seed
        np.testing.assert_array_equal(env.reset(seed=2**63 + 5)[0], a[0].observations[0])
    finally:
        env.close()


@pytest.mark.imitation
def test_imitations_behaviour_cloning_trains_on_a_loaded_minari_dataset(tmp_path, monkeypatch) -> None:
    """In the imitation-bench environment: the loaded Minari episodes as imitation Trajectories,
    and imitation 1.0.1's BC trained on them for a few batches."""
    require_imitation()
    minari = require_extra("minari", "rl")
    import torch
    from imitation.algorithms import bc
    from imitation.data.types import Trajectory
    from imitation.util import logger as imit_logger

    from sim.env.minari_dataset import write_minari

    t = from_encounters(encounter_table(sizes=(30, 24, 27, 21)), decision_step_s=0.3)
    write_minari(t, "merge-irl/bc-v0", root=tmp_path / "data")
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "data"))
    ds = minari.load_dataset("merge-irl/bc-v0")
    demos = [Trajectory(obs=e.observations, acts=e.actions, infos=None, terminal=bool(e.terminations[-1]))
             for e in ds.iterate_episodes()]
    assert len(demos) == 4 and sum(len(d.acts) for d in demos) == t.n
    torch.manual_seed(0)
    trainer = bc.BC(observation_space=ds.observation_space, action_space=ds.action_space, demonstrations=demos,
                    rng=np.random.default_rng(0), batch_size=8, device="cpu",
                    custom_logger=imit_logger.configure(tmp_path / "log", ["csv"]))
    before = [p.detach().clone() for p in trainer.policy.parameters()]
    trainer.train(n_batches=6, progress_bar=False, log_interval=10**9)
    assert any(not torch.equal(a, b) for a, b in zip(before, trainer.policy.parameters()))
    acts, _ = trainer.policy.predict(demos[0].obs, deterministic=True)
    assert acts.shape == (len(demos[0].obs),) and set(acts.tolist()) <= set(range(5))
