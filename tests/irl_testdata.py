"""Small IRL test inputs: random MDP demonstrations and the authors' gridworld data.

The gridworld features follow REFERENCE.md (state = 5*row + col; features depend on the state
only: yellow 4, green 0, red 20, pink 24, blue {1, 8, 11, 18, 21}).
"""

from __future__ import annotations


import numpy as np

from irl.demonstrations import Demonstrations

from shared_data import DATA

GRIDWORLD_DIR = DATA / "railusm" / "gridworld"


def gridworld_features() -> np.ndarray:
    """``[25, 4, 5]`` colour indicators of the state (same for every action)."""
    f = np.zeros((25, 4, 5))
    for k, cells in enumerate(([4], [0], [20], [24], [1, 8, 11, 18, 21])):
        f[cells, :, k] = 1.0
    return f


def gridworld_demos(noise: str = "0.0", kind: str = "expert") -> Demonstrations:
    """Read ``noise_<noise>_<kind>_trajs`` (one file per trajectory, ``state<TAB>action``)."""
    folder = GRIDWORLD_DIR / f"noise_{noise}_{kind}_trajs"
    files = sorted(folder.glob("*.txt"))
    states, actions = [], []
    for path in files:
        rows = [line.split() for line in path.read_text().splitlines() if line.strip()]
        states.append(np.array([int(r[0]) for r in rows]))
        actions.append(np.array([int(r[1]) for r in rows]))
    return Demonstrations(tuple(states), tuple(actions), gridworld_features(), 25, 4,
                          source=str(folder), names=tuple(p.name for p in files))


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


MERGE_DIR = GRIDWORLD_DIR.parent / "merge_ngsim"


def merge_features() -> np.ndarray:
    """``[1250, 5, 3]`` FMFeatures of REFERENCE.md: Safe, Time-to-travel, Ahead-of-truck."""
    s = np.arange(1250)
    truck, x1 = s // 625, (s // 125) % 5
    a = np.arange(5)
    f = np.zeros((1250, 5, 3))
    f[:, :, 0] = 1.0 - ((x1[:, None] == 4) & (a[None, :] >= 3))
    f[:, :, 1] = (a[None, :] >= 2) * np.ones((1250, 1))
    f[:, :, 2] = (truck[:, None] == 1) & (a[None, :] >= 3)
    return f


def merge_demos() -> Demonstrations:
    """The authors' 12 discretized NGSIM merge trajectories (``traj_0..11.txt``)."""
    files = sorted(MERGE_DIR.glob("traj_*.txt"), key=lambda p: int(p.stem.split("_")[1]))
    states, actions = [], []
    for path in files:
        rows = [line.split() for line in path.read_text().splitlines() if line.strip()]
        states.append(np.array([int(r[0]) for r in rows]))
        actions.append(np.array([int(r[1]) for r in rows]))
    return Demonstrations(tuple(states), tuple(actions), merge_features(), 1250, 5,
                          source=str(MERGE_DIR), names=tuple(p.name for p in files))
