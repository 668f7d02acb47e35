"""imitation 1.0.1's behaviour cloning trained on transitions this project exports
(:func:`sim.merges.transitions.from_encounters`, :func:`~sim.merges.transitions.to_imitation_trajectories`),
saved the documented ways (Stable-Baselines3's ``policy.save``, imitation's ``util.save_policy``)
and reloaded by :func:`studies.support.policy_files.load_policy`: the reloaded policy gives the
same action probabilities and actions on fixed observations. Marked ``imitation``: CI runs it in
the imitation-bench environment (torch 2.13, where the documented loads refuse these files)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from extras import require_imitation

from studies.support.policy_files import PolicyFileError, load_policy, save_policy

pytestmark = pytest.mark.imitation


def encounters(sizes=(30, 24, 27, 21), seed=3) -> pd.DataFrame:
    """An encounter table (the columns :func:`sim.merges.transitions.from_encounters` reads), A's
    acceleration tied to the gap to C so the actions are learnable."""
    rng = np.random.default_rng(seed)
    n = sum(sizes)
    d_ac = rng.uniform(20, 200, n)
    return pd.DataFrame({
        "encounter_id": np.repeat(np.arange(len(sizes)) + 1, sizes),
        "Frame_ID": np.concatenate([np.arange(s) + 100 for s in sizes]),
        "d_AC": d_ac, "d_AB": rng.uniform(-40, 100, n), "v_AC": rng.normal(0, 5, n), "v_AB": rng.normal(0, 5, n),
        "B_is_truck": False, "acc_A": (d_ac - 110) / 10, "v_A": rng.uniform(20, 80, n),
        "len_C": 15.0, "len_B": 16.0,
    })


def trained_bc(log_dir: Path):
    """imitation's BC (its default FeedForward32Policy) trained 8 batches of 16 decisions, seeded."""
    require_imitation()
    import gymnasium as gym
    import torch
    from imitation.algorithms import bc
    from imitation.util import logger as imit_logger

    from sim.drivers.observe import POLICY_OBS_HIGH, POLICY_OBS_LOW
    from sim.merges.transitions import from_encounters, to_imitation_trajectories

    t = from_encounters(encounters(), decision_step_s=0.3)
    demos = to_imitation_trajectories(t)
    assert len(demos) == 4 and sum(len(d.acts) for d in demos) == t.n
    torch.manual_seed(0)
    space = gym.spaces.Box(POLICY_OBS_LOW, POLICY_OBS_HIGH, dtype=np.float64)
    trainer = bc.BC(observation_space=space, action_space=gym.spaces.Discrete(5), demonstrations=demos,
                    rng=np.random.default_rng(0), batch_size=16, device="cpu",
                    custom_logger=imit_logger.configure(log_dir, ["csv"]))
    before = [p.detach().clone() for p in trainer.policy.parameters()]
    trainer.train(n_batches=8, progress_bar=False, log_interval=10**9)
    assert any(not torch.equal(a, b) for a, b in zip(before, trainer.policy.parameters())), "BC did not train"
    return trainer.policy, t.policy_obs()


def probs(policy, obs: np.ndarray) -> np.ndarray:
    import torch

    with torch.no_grad():
        return policy.get_distribution(policy.obs_to_tensor(obs)[0]).distribution.probs.numpy()


def test_bc_saved_with_policy_save_reloads_with_the_same_probabilities(tmp_path: Path) -> None:
    policy, obs = trained_bc(tmp_path / "log")
    from stable_baselines3.common.policies import ActorCriticPolicy

    path = save_policy(policy, tmp_path / "bc.zip")
    back = load_policy(path)
    assert type(back) is ActorCriticPolicy and back is not policy
    assert [p.shape for p in back.parameters()] == [p.shape for p in policy.parameters()]
    p0, p1 = probs(policy, obs), probs(back, obs)
    assert p0.shape == (len(obs), 5)
    np.testing.assert_array_equal(p1, p0)
    np.testing.assert_array_equal(back.predict(obs, deterministic=True)[0], policy.predict(obs, deterministic=True)[0])
    # not trivially equal: a fresh policy of the same class answers otherwise
    fresh = ActorCriticPolicy(**policy._get_constructor_parameters())
    assert not np.allclose(probs(fresh, obs), p0)


def test_bc_saved_with_imitations_save_policy_reloads(tmp_path: Path) -> None:
    policy, obs = trained_bc(tmp_path / "log")
    from imitation.util import util

    util.save_policy(policy, tmp_path / "bc.pt")
    back = load_policy(tmp_path / "bc.pt")
    np.testing.assert_array_equal(probs(back, obs), probs(policy, obs))


def test_a_missing_or_foreign_file_is_refused_naming_it(tmp_path: Path) -> None:
    require_imitation()
    import torch

    with pytest.raises(PolicyFileError, match="no such policy file"):
        load_policy(tmp_path / "absent.zip")
    torch.save({"weights": torch.zeros(3)}, tmp_path / "w.pt")
    with pytest.raises(PolicyFileError, match=r"w\.pt: holds dict, not a Stable-Baselines3 policy"):
        load_policy(tmp_path / "w.pt")
