"""Benchmark: the multi-agent environment as a learner steps it, against the single-agent one, side by side.

Same scenario, seed and simulated time; every loop asks a policy for every action it sends (a
Stable-Baselines3 ``ActorCriticPolicy`` with its default network when SB3 and torch are installed,
else a numpy network of the same shape: two hidden layers of 64, tanh), so the cost a learner
pays per policy call is in the figures:

* ``env``: :class:`sim.env.MergeEnv`, one controlled car at a time (``reset()`` continues the run),
  the policy on one observation per step;
* ``ParallelEnv, live agents``: :class:`sim.env.multi_agent.MergeParallelEnv`, the policy on the
  live agents' observations only (one call per step);
* ``slots xN``: :class:`sim.env.agent_slots.AgentSlotsVectorEnv` with ``max_agents=N``, the
  policy on all ``N`` slots, idle ones included (what Stable-Baselines3 does through SuperSuit).

Printed per loop: decisions (controlled steps), steps (policy calls), the live-agent share
(decisions / (steps x slots): the rest is zero-padding), wall time, decisions per second and its
ratio to the single-agent environment's (target: multi-agent >= 1.3x), and wall time per step
against the live-agents-only loop's; then the policy call alone on 1, 2, 4 rows (what the idle
slots' rows cost per step, apart from the noise of SUMO's steps).
``--policy zero`` sends Zero for every car without a network: the environments' own cost.
Run: ``python -m benchmarks.marl_bench [--scenario synthetic] [--sim-s 600] [--seed 1] [--repeat 3] [--policy zero]``.
"""

from __future__ import annotations

import argparse
import functools
import time
from collections.abc import Callable

import numpy as np

from scenarios.loader import load_scenario

#: A policy: observations ``[n, 7]`` -> actions ``[n]``.
PolicyFn = Callable[[np.ndarray], np.ndarray]


def make_policy(obs_space, act_space, seed: int, kind: str = "sb3") -> tuple[str, PolicyFn]:
    """The policy every loop calls: SB3's default ``ActorCriticPolicy`` (``predict``), else numpy;
    ``kind="zero"``: Zero for every car, no network (the environments' own cost)."""
    if kind == "zero":
        return "Zero for every car, no policy network", lambda obs: np.full(len(obs), 2)
    try:
        import torch
        from stable_baselines3.common.policies import ActorCriticPolicy
    except ImportError:
        rng = np.random.default_rng(seed)
        w = [rng.normal(0, 0.1, s) for s in ((7, 64), (64, 64), (64, act_space.n))]

        def np_policy(obs: np.ndarray) -> np.ndarray:
            h = np.tanh(np.tanh(obs @ w[0]) @ w[1])
            return np.argmax(h @ w[2], axis=1)
        return "numpy MLP 64-64", np_policy
    torch.manual_seed(seed)
    torch.set_num_threads(1)
    policy = ActorCriticPolicy(obs_space, act_space, lr_schedule=lambda _: 3e-4)

    def sb3_policy(obs: np.ndarray) -> np.ndarray:
        return policy.predict(obs, deterministic=False)[0]
    return "SB3 ActorCriticPolicy.predict (MLP 64-64)", sb3_policy


def policy_call_ms(policy: PolicyFn, rows: list[int], n: int = 2000) -> dict[int, float]:
    """Median ms of one policy call on ``k`` zero observations, per ``k`` of ``rows`` (interleaved)."""
    times: dict[int, list[float]] = {k: [] for k in rows}
    batches = {k: np.zeros((k, 7)) for k in rows}
    for _ in range(n):
        for k in rows:
            t = time.perf_counter()
            policy(batches[k])
            times[k].append(time.perf_counter() - t)
    return {k: 1e3 * float(np.median(v)) for k, v in times.items()}


def single_env(spec, seed: int, sim_s: float, policy: PolicyFn) -> dict[str, float]:
    from sim.env import MergeEnv

    env = MergeEnv(spec, run_s=sim_s)
    t = time.perf_counter()
    obs, _ = env.reset(seed=seed)
    session = env._session
    n = 0
    while True:
        obs, _, term, trunc, info = env.step(policy(obs[None])[0])
        n += 1
        if term or trunc:
            if info["release_reason"] == "end_of_run" or session is None or session.done:
                break
            obs, _ = env.reset()
            if env._session is not session:  # the run ended while looking for a take-over
                break
    wall = time.perf_counter() - t
    env.close()
    return {"wall": wall, "decisions": n, "steps": n, "slots": 1}


def parallel_live(spec, seed: int, sim_s: float, policy: PolicyFn) -> dict[str, float]:
    from sim.env.multi_agent import MergeParallelEnv

    env = MergeParallelEnv(scenario=spec, run_s=sim_s)
    t = time.perf_counter()
    obs, _ = env.reset(seed=seed)
    n = steps = 0
    while env.agents:
        agents = list(env.agents)
        acts = policy(np.stack([obs[a] for a in agents]))
        n += len(agents)
        steps += 1
        obs, *_ = env.step(dict(zip(agents, acts)))
    wall = time.perf_counter() - t
    env.close()
    return {"wall": wall, "decisions": n, "steps": steps, "slots": float("nan")}


def slots_loop(spec, seed: int, sim_s: float, policy: PolicyFn, n_slots: int) -> dict[str, float]:
    from sim.env.agent_slots import AgentSlotsVectorEnv

    venv = AgentSlotsVectorEnv(scenario=spec, run_s=sim_s, max_agents=n_slots)
    t = time.perf_counter()
    obs, _ = venv.reset(seed=seed)
    par = venv.par_env
    session = par._session
    steps = 0
    while par._session is session:  # one run: the next reset starts another session
        obs, *_ = venv.step(policy(obs))
        steps += 1
    wall = time.perf_counter() - t
    live = venv.live_steps
    venv.close()
    return {"wall": wall, "decisions": live, "steps": steps, "slots": n_slots}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="synthetic")
    ap.add_argument("--sim-s", type=float, default=600.0, help="simulated seconds of each run (warm-up included)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--slots", type=int, nargs="+", default=[1, 2, 4], help="max_agents of the slots loops")
    ap.add_argument("--repeat", type=int, default=3, help="runs of each, alternating; the fastest is kept")
    ap.add_argument("--policy", choices=("sb3", "zero"), default="sb3",
                    help="sb3: SB3's default policy network (numpy without SB3); zero: Zero, no network")
    a = ap.parse_args(argv)
    spec = load_scenario(a.scenario)
    from sim.env import MergeEnv

    spaces = MergeEnv(spec, run_s=a.sim_s)  # its spaces (no SUMO started)
    pname, policy = make_policy(spaces.observation_space, spaces.action_space, a.seed, a.policy)
    loops: dict[str, Callable[[], dict[str, float]]] = {
        "env (MergeEnv)": lambda: single_env(spec, a.seed, a.sim_s, policy),
        "ParallelEnv, live agents": lambda: parallel_live(spec, a.seed, a.sim_s, policy)}
    for k in a.slots:
        loops[f"slots x{k} (AgentSlots)"] = functools.partial(slots_loop, spec, a.seed, a.sim_s, policy, k)
    runs: dict[str, list[dict[str, float]]] = {name: [] for name in loops}
    for _ in range(max(1, a.repeat)):  # alternating, so a busy moment of the machine hits all
        for name, fn in loops.items():
            runs[name].append(fn())
    best = {name: min(rs, key=lambda r: r["wall"]) for name, rs in runs.items()}
    print(f"scenario {a.scenario}, seed {a.seed}, {a.sim_s:g} simulated s, policy: {pname}, "
          f"fastest of {max(1, a.repeat)} alternating runs each")
    print(f"{'':28s}{'decisions':>10s}{'steps':>8s}{'live share':>12s}{'wall s':>9s}{'decisions/s':>13s}"
          f"{'vs env':>8s}{'ms/step':>9s}{'vs live-only':>14s}")
    env_dps = best["env (MergeEnv)"]["decisions"] / best["env (MergeEnv)"]["wall"]
    live = best["ParallelEnv, live agents"]
    live_ms = 1e3 * live["wall"] / live["steps"]
    for name, r in best.items():
        dps = r["decisions"] / r["wall"]
        share = r["decisions"] / (r["steps"] * r["slots"]) if r["slots"] == r["slots"] else float("nan")
        ms = 1e3 * r["wall"] / r["steps"]
        share_s = f"{share:.0%}" if share == share else "all live"
        print(f"{name:28s}{int(r['decisions']):>10d}{int(r['steps']):>8d}{share_s:>12s}{r['wall']:>9.2f}"
              f"{dps:>13.0f}{dps / env_dps:>7.2f}x{ms:>9.3f}{ms / live_ms:>13.2f}x")
    calls = policy_call_ms(policy, sorted({1, *a.slots}))
    print("policy call alone (the padding's cost per step: the rows of idle slots), median of 2000 calls: "
          + ", ".join(f"{k} rows {ms:.3f} ms" for k, ms in calls.items()))
    print("target: multi-agent decisions/s >= 1.3x the single-agent environment's; "
          "padding: a slots loop's ms/step against the live-agents-only loop's (same run, same decisions for "
          "the same cap)")


if __name__ == "__main__":
    main()
