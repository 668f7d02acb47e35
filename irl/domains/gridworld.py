"""The paper's 5x5 gridworld (section 4.1), laid out as the authors' code does (their
``GWFeatures``: the states, actions and features below).

* state ``s = 5 * row + col`` (row 0 at the top), 25 states;
* actions ``0 = col-1`` (left), ``1 = row+1`` (down), ``2 = col+1`` (right), ``3 = row-1`` (up);
  a move off the grid leaves the agent in place;
* five state-only colour features, broadcast over actions to ``[25, 4, 5]``:
  f0 yellow = state 4 (top right), f1 green = 0 (top left), f2 red = 20 (bottom left),
  f3 pink = 24 (bottom right), f4 blue = {1, 8, 11, 18, 21};
* noise ``p``: the intended move happens with probability ``1 - p``; with probability ``p`` the
  agent slips to one side of it (perpendicular to the intended direction), ``p/2`` each side;
  a slip off the grid also leaves the agent in place.

The expert goes to the nearest corner by the shortest path that avoids blue cells (ties broken
at random), and ends with one ``(corner, action)`` step; the baseline is a uniform-random policy
with trajectories of fixed length.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from irl.demonstrations import Demonstrations
from irl.errors import ConfigError

SIZE = 5
N_STATES = SIZE * SIZE
N_ACTIONS = 4
FEATURE_NAMES = ("yellow", "green", "red", "pink", "blue")
CORNERS = (4, 0, 20, 24)  # f0..f3 in feature order
BLUE = frozenset({1, 8, 11, 18, 21})
#: (d_row, d_col) of each action.
MOVES = ((0, -1), (1, 0), (0, 1), (-1, 0))
#: The two lateral slips of each action (perpendicular moves, as action indices).
LATERAL = ((1, 3), (0, 2), (1, 3), (0, 2))
#: Action taken at the final (corner, action) step, per corner, as in the authors' no-noise files.
CORNER_ACTION = {0: 2, 4: 1, 20: 0, 24: 3}


def move(state: int, action: int) -> int:
    """Deterministic successor of ``state`` under ``action`` (off the grid: stay)."""
    row, col = divmod(int(state), SIZE)
    dr, dc = MOVES[int(action)]
    r, c = row + dr, col + dc
    if 0 <= r < SIZE and 0 <= c < SIZE:
        return r * SIZE + c
    return int(state)


def features() -> np.ndarray:
    """``[25, 4, 5]`` binary features (state-only, identical across actions)."""
    phi = np.zeros((N_STATES, 5))
    for k, corner in enumerate(CORNERS):
        phi[corner, k] = 1.0
    for s in BLUE:
        phi[s, 4] = 1.0
    return np.repeat(phi[:, None, :], N_ACTIONS, axis=1)


def transition_model(noise: float = 0.0) -> np.ndarray:
    """True model ``T[s, a, s']`` (``[25, 4, 25]``, rows sum to 1) for lateral slip ``noise``.

    Raises:
        ConfigError: ``noise`` is outside [0, 1].
    """
    if not 0.0 <= noise <= 1.0:
        raise ConfigError(f"gridworld noise must be in [0, 1], got {noise}")
    t = np.zeros((N_STATES, N_ACTIONS, N_STATES))
    for s in range(N_STATES):
        for a in range(N_ACTIONS):
            t[s, a, move(s, a)] += 1.0 - noise
            for lat in LATERAL[a]:
                t[s, a, move(s, lat)] += noise / 2.0
    return t


def corner_distances() -> np.ndarray:
    """``[25]`` length of the shortest blue-avoiding path to the nearest corner.

    Paths never pass through a blue cell; a blue start cell gets 1 + the best non-blue
    neighbour's distance.
    """
    dist = np.full(N_STATES, np.inf)
    queue: deque[int] = deque()
    for c in CORNERS:
        dist[c] = 0
        queue.append(c)
    while queue:
        s = queue.popleft()
        for a in range(N_ACTIONS):
            n = move(s, a)
            if n in BLUE or dist[n] <= dist[s] + 1:
                continue
            dist[n] = dist[s] + 1
            queue.append(n)
    for b in BLUE:
        nb = [dist[move(b, a)] for a in range(N_ACTIONS) if move(b, a) not in BLUE]
        dist[b] = 1 + min(nb)
    return dist


def expert_actions(state: int, dist: np.ndarray | None = None) -> list[int]:
    """The optimal actions at a non-corner ``state``: moves that step to a non-blue cell one
    closer to the nearest corner."""
    dist = corner_distances() if dist is None else dist
    return [a for a in range(N_ACTIONS)
            if move(state, a) != state and move(state, a) not in BLUE
            and dist[move(state, a)] == dist[state] - 1]


def start_states() -> np.ndarray:
    """The states a trajectory may start in: neither blue nor a corner."""
    return np.array([s for s in range(N_STATES) if s not in BLUE and s not in CORNERS])


def _sample_next(t: np.ndarray, s: int, a: int, rng: np.random.Generator) -> int:
    return int(rng.choice(N_STATES, p=t[s, a]))


def generate_experts(
    n: int, noise: float, rng: np.random.Generator, *, max_len: int = 50, deduplicate: bool = True
) -> Demonstrations:
    """``n`` expert trajectories (then duplicates removed unless ``deduplicate=False``).

    Each starts uniformly in ``start_states()``, follows a random optimal action (towards the
    nearest corner avoiding blue) under the noisy model, and ends with one
    ``(corner, CORNER_ACTION[corner])`` step; at most ``max_len`` steps before the corner.
    """
    t = transition_model(noise)
    dist = corner_distances()
    starts = start_states()
    states, actions = [], []
    for _ in range(int(n)):
        s = int(rng.choice(starts))
        ss: list[int] = []
        aa: list[int] = []
        while s not in CORNERS and len(ss) < max_len:
            a = int(rng.choice(expert_actions(s, dist)))
            ss.append(s)
            aa.append(a)
            s = _sample_next(t, s, a, rng)
        ss.append(s)
        aa.append(CORNER_ACTION.get(s, int(rng.integers(N_ACTIONS))))
        states.append(np.array(ss))
        actions.append(np.array(aa))
    demos = Demonstrations(tuple(states), tuple(actions), features(), N_STATES, N_ACTIONS,
                           source=f"gridworld experts (noise {noise})")
    return demos.deduplicated() if deduplicate else demos


def generate_baseline(
    n: int, length: int, noise: float, rng: np.random.Generator
) -> Demonstrations:
    """``n`` uniform-random-policy trajectories of exactly ``length`` steps from ``start_states()``.

    Raises:
        ConfigError: ``length`` < 1.
    """
    if int(length) < 1:
        raise ConfigError(f"baseline trajectory length must be >= 1, got {length}")
    t = transition_model(noise)
    starts = start_states()
    states, actions = [], []
    for _ in range(int(n)):
        s = int(rng.choice(starts))
        ss, aa = [], []
        for _ in range(int(length)):
            a = int(rng.integers(N_ACTIONS))
            ss.append(s)
            aa.append(a)
            s = _sample_next(t, s, a, rng)
        states.append(np.array(ss))
        actions.append(np.array(aa))
    return Demonstrations(tuple(states), tuple(actions), features(), N_STATES, N_ACTIONS,
                          source=f"gridworld uniform-random baseline (noise {noise})")


def load(path) -> Demonstrations:
    """Gridworld trajectories in the authors' text format, with the gridworld features."""
    from irl.io import load_text_trajectories

    return load_text_trajectories(path, n_states=N_STATES, n_actions=N_ACTIONS, features=features())
