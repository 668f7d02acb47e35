"""Small IRL test inputs: random MDP demonstrations, gridworld demonstrations and a merge
encounter table with frame numbers.

The gridworld demonstrations come from the project's own generator (``irl.domains.gridworld``: the
paper's 5x5 gridworld, laid out as the authors' code does), with fixed seeds and about the authors' sizes
(12 expert trajectories without noise, 14 with 10% slips), so the tests run on a fresh clone.
The authors' own files (AGPL, not shipped) are tested through the ``railusm`` fixture.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from irl.demonstrations import Demonstrations
from irl.domains import gridworld

#: noise -> (experts drawn, seed, baseline trajectories, baseline length): 12 experts / 38 steps
#: without noise, 14 / 50 with 10% slips (duplicates removed); uniform-random baselines of 12 x 5
#: and 14 x 7 steps, as the authors' sets.
_GRIDWORLD = {"0.0": (12, 0, 12, 5), "0.1": (15, 1, 14, 7)}


def gridworld_features() -> np.ndarray:
    """``[25, 4, 5]`` colour indicators of the state (same for every action), written out here."""
    f = np.zeros((25, 4, 5))
    for k, cells in enumerate(([4], [0], [20], [24], [1, 8, 11, 18, 21])):
        f[cells, :, k] = 1.0
    return f


def gridworld_demos(noise: str = "0.0", kind: str = "expert") -> Demonstrations:
    """Generated gridworld demonstrations with slip ``noise`` ("0.0" or "0.1"), deterministic.

    ``kind="expert"``: expert trajectories to the nearest corner avoiding blue (the noise-free
    ones have one successor per observed (s, a)); ``kind="baseline"``: 12 or 14 uniform-random
    trajectories of fixed length (the REIRL sampling set).
    """
    n, seed, n_baseline, length = _GRIDWORLD[noise]
    rng = np.random.default_rng(seed)
    if kind == "expert":
        demos = gridworld.generate_experts(n, float(noise), rng)
    elif kind == "baseline":
        demos = gridworld.generate_baseline(n_baseline, length, float(noise), rng)
    else:
        raise ValueError(f"kind must be 'expert' or 'baseline', got {kind!r}")
    np.testing.assert_array_equal(demos.features, gridworld_features())  # the authors' layout: yellow 4, green 0, red 20, pink 24, blue 1/8/11/18/21
    return demos


def random_mdp(seed: int, n_states: int = 6, n_actions: int = 3, n_features: int = 3,
               n_traj: int = 5, length: int = 6, single_successor: bool = False):
    """A random MDP ``T [S, A, S]``, features ``[S, A, K]`` and demonstrations sampled from it.

    With ``single_successor`` the dynamics are deterministic, so every observed (s, a) has one
    successor. Actions are drawn uniformly at random.
    """
    rng = np.random.default_rng(seed)
    S, A, K = n_states, n_actions, n_features
    if single_successor:
        t = np.zeros((S, A, S))
        t[np.arange(S)[:, None], np.arange(A)[None, :], rng.integers(0, S, size=(S, A))] = 1.0
    else:
        t = rng.dirichlet(np.full(S, 0.5), size=(S, A))
    phi = rng.normal(size=(S, A, K))
    states, actions = [], []
    for _ in range(n_traj):
        s = int(rng.integers(S))
        ss, aa = [], []
        for _ in range(length):
            a = int(rng.integers(A))
            ss.append(s)
            aa.append(a)
            s = int(rng.choice(S, p=t[s, a]))
        states.append(np.array(ss))
        actions.append(np.array(aa))
    return t, Demonstrations(tuple(states), tuple(actions), phi, S, A, source=f"random mdp {seed}")


def encounter_table(n: int = 3, rows: int = 60, seed: int = 0, first_frame: int = 1000) -> pd.DataFrame:
    """An encounter table with Frame_ID (consecutive frames per encounter) and the columns the
    car-following and planning decisions read."""
    rng = np.random.default_rng(seed)
    v_a = rng.uniform(30, 60, n * rows)
    return pd.DataFrame({
        "encounter_id": np.repeat(np.arange(n) + 1, rows),
        "C_id": np.repeat(np.arange(n) + 50, rows),
        "Frame_ID": np.tile(np.arange(rows) + first_frame, n),
        "d_AC": rng.uniform(40, 200, n * rows), "d_AB": rng.uniform(-40, 120, n * rows),
        "v_AC": rng.normal(0, 6, n * rows), "v_AB": rng.normal(0, 6, n * rows),
        "B_is_truck": np.repeat(np.arange(n) % 2 == 1, rows), "acc_A": rng.uniform(-11, 11, n * rows),
        "v_A": v_a, "len_C": 15.0, "len_B": 16.0,
    })


def planning_encounters(n: int = 4, rows: int = 31, seed: int = 0) -> pd.DataFrame:
    """``n`` encounters of ``rows`` frames for the planning driver: random gaps and speeds (ft,
    ft/s), A braking hard (-12 ft/s^2) where ``d_AC < 60`` ft, else -3/0/3; two lead cars C."""
    rng = np.random.default_rng(seed)
    d_ac = rng.uniform(20, 250, n * rows)
    return pd.DataFrame({
        "encounter_id": np.repeat(np.arange(n) + 7, rows), "d_AC": d_ac, "v_AC": rng.normal(5, 5, n * rows),
        "d_AB": rng.uniform(-50, 120, n * rows), "v_AB": rng.normal(0, 5, n * rows), "B_is_truck": False,
        "acc_A": np.where(d_ac < 60, -12.0, rng.choice([-3.0, 0.0, 3.0], n * rows)),
        "v_A": rng.uniform(20, 80, n * rows), "C_id": np.repeat([1, 2], n * rows // 2 + 1)[: n * rows],
    })
