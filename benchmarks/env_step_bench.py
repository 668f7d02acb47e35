"""Benchmark: the Gymnasium environment (:mod:`sim.env`) against the closed-loop runner, side by side.

Same scenario, seed and simulated time, Zero (action 2) at every decision:

* ``closed loop``: :func:`sim.runtime.run.run_scenario` with the :class:`sim.closed_loop.controller.Controller` driving
  every merge's lag car (a constant policy);
* ``env``: :class:`sim.env.MergeEnv` stepped by a Python loop (``reset(seed)`` once, then ``reset()``
  continues the same SUMO run to its next take-over), one controlled car at a time;
* ``multi-agent (ParallelEnv)``: :class:`sim.env.multi_agent.MergeParallelEnv` over the same run, every
  controlled lag car an agent, Zero for each (target: decisions per second at least 1.3x
  the single-agent environment's, within 1.1x of the closed loop per decision);
* ``env x1`` / ``env x2 (AsyncVectorEnv)``: one and two worker processes, one SUMO each (target:
  two at least 1.6x one's steps per second on 2 idle cores), with the load average, and the most
  lock-stepped workers could gain (:func:`lockstep_bound`: each worker's calls replayed alone).

Printed per decision: wall time, and the overhead (wall time outside ``simulationStep``, i.e.
Python: reading frames, the controller, the environment); the time inside ``env.step()`` alone
per decision; per simulated second: wall time. The closed loop controls every merge at once and
so decides more often per simulated second than the environment, which drives one A at a time
and runs SUMO alone between take-overs (in ``reset``): per decision, that time counts against
the environment; per simulated second it does not.
Target: the environment's overhead per decision at most 1.3x the closed loop's.
Run: ``python -m benchmarks.env_step_bench [--sim-s 600] [--seed 1] [--repeat 3]``.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from scenarios.loader import load_scenario
from sim.closed_loop.config import ControllerConfig
from sim.closed_loop.controller import Controller
from sim.drivers.policy import ConstantPolicy
from sim.runtime.run import run_scenario

ZERO = 2


def closed_loop(spec, seed: int, sim_s: float) -> dict[str, float]:
    ctl = Controller(ConstantPolicy(ZERO), ControllerConfig(decision_step_s=0.3))
    t = time.perf_counter()
    res = run_scenario(spec, seed=seed, duration_s=sim_s, hooks=[ctl])
    wall = time.perf_counter() - t
    n = len(ctl.decision_table())
    return {"wall": wall, "sumo": res.sumo_time_s, "decisions": n, "episodes": len(ctl.controls)}


def env_loop(spec, seed: int, sim_s: float) -> dict[str, float]:
    from sim.env import MergeEnv

    env = MergeEnv(spec, run_s=sim_s, reward=None)
    t = time.perf_counter()
    env.reset(seed=seed)
    session = env._session
    n = episodes = 0
    in_step = 0.0
    while True:
        ts = time.perf_counter()
        _, _, term, trunc, info = env.step(ZERO)
        in_step += time.perf_counter() - ts
        n += 1
        if term or trunc:
            episodes += 1
            if info["release_reason"] == "end_of_run" or session is None or session.done:
                break
            env.reset()
            if env._session is not session:  # the run ended while looking for a take-over
                break
    wall = time.perf_counter() - t
    sumo = session.sumo_time_s if session is not None else float("nan")
    env.close()
    return {"wall": wall, "sumo": sumo, "decisions": n, "episodes": episodes, "in_step": in_step}


def multi_agent_loop(spec, seed: int, sim_s: float) -> dict[str, float]:
    from sim.env.multi_agent import MergeParallelEnv

    env = MergeParallelEnv(scenario=spec, run_s=sim_s, reward=None)
    t = time.perf_counter()
    env.reset(seed=seed)
    session = env._session
    n = steps = 0
    while env.agents:
        n += len(env.agents)
        steps += 1
        env.step(dict.fromkeys(env.agents, ZERO))
    wall = time.perf_counter() - t
    sumo = session.sumo_time_s if session is not None else float("nan")
    episodes = len(env.possible_agents)
    env.close()
    return {"wall": wall, "sumo": sumo, "decisions": n, "episodes": episodes, "steps": steps}


def vector_episodes(spec_name: str, seed: int, steps: int, workers: int = 2) -> tuple[float, int, float]:
    import gymnasium as gym

    from sim.env import make_env

    envs = gym.vector.AsyncVectorEnv([make_env(scenario=spec_name, run_s=3600.0)] * workers, context="spawn")
    try:
        t0 = time.perf_counter()
        envs.reset(seed=[seed + i for i in range(workers)])
        t = time.perf_counter()
        done = 0
        for _ in range(steps):
            _, _, term, trunc, _ = envs.step(np.full(workers, ZERO))
            done += int(np.sum(term | trunc))
        wall = time.perf_counter() - t
        return wall, done, t - t0
    finally:
        envs.close()


def worker_calls(spec_name: str, seed: int, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """One vector worker's calls replayed alone in this process: ``steps`` calls as
    ``AsyncVectorEnv`` makes them (``step(Zero)``; the call after an episode's end is its reset,
    Gymnasium's next-step autoreset), after ``reset(seed)``. Returns ``(frames [steps], wall s
    [steps])``: the simulated frames each call ran (deterministic) and its wall time."""
    from sim.env import MergeEnv

    env = MergeEnv(spec_name, run_s=3600.0)
    try:
        env.reset(seed=seed)
        frames, walls = np.zeros(steps), np.zeros(steps)
        ended = False
        for k in range(steps):
            session = env._session
            s0 = session._step if session is not None else 0
            t = time.perf_counter()
            if ended:
                env.reset()
                ended = False
            else:
                _, _, term, trunc, _ = env.step(ZERO)
                ended = bool(term or trunc)
            walls[k] = time.perf_counter() - t
            now = env._session
            frames[k] = (now._step if now is not None else 0) - (s0 if now is session else 0)
        return frames, walls
    finally:
        env.close()


def lockstep_bound(spec_name: str, seed: int, steps: int) -> tuple[float, float]:
    """The most two lock-stepped workers (seeds ``seed``, ``seed + 1``) can gain over one (seed
    ``seed``) in steps per second: every vector step waits for the slower call, so two workers
    take ``sum(max(a, b))`` for ``2 * steps`` steps where one takes ``sum(a)`` for ``steps``, with
    no cost of their own. Returns ``(from simulated frames, from wall times)``: the first counts a
    call's cost as the frames it simulated plus one (the call itself), independent of the
    machine's load; the second the calls' wall times here."""
    fa, wa = worker_calls(spec_name, seed, steps)
    fb, wb = worker_calls(spec_name, seed + 1, steps)
    fa, fb = fa + 1.0, fb + 1.0
    return 2 * fa.sum() / np.maximum(fa, fb).sum(), 2 * wa.sum() / np.maximum(wa, wb).sum()


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="synthetic")
    ap.add_argument("--sim-s", type=float, default=600.0, help="simulated seconds of each run (warm-up included)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--vector-steps", type=int, default=600, help="steps of the 2-worker AsyncVectorEnv")
    ap.add_argument("--repeat", type=int, default=3, help="runs of each, alternating; the fastest is kept")
    a = ap.parse_args(argv)
    spec = load_scenario(a.scenario)
    cls, evs, mas = [], [], []
    for _ in range(max(1, a.repeat)):  # alternating, so a busy moment of the machine hits all
        cls.append(closed_loop(spec, a.seed, a.sim_s))
        evs.append(env_loop(spec, a.seed, a.sim_s))
        mas.append(multi_agent_loop(spec, a.seed, a.sim_s))
    cl = min(cls, key=lambda r: r["wall"])
    ev = min(evs, key=lambda r: r["wall"])
    ma = min(mas, key=lambda r: r["wall"])
    print(f"scenario {a.scenario}, seed {a.seed}, {a.sim_s:g} simulated s per run, Zero at every 0.3 s decision, "
          f"fastest of {max(1, a.repeat)} alternating runs each")
    print(f"{'':28s}{'decisions':>10s}{'episodes':>10s}{'wall s':>9s}{'ms/decision':>13s}"
          f"{'overhead ms/dec':>17s}{'ms/sim s':>10s}{'episodes/s':>12s}")
    for name, r in (("closed loop (run_scenario)", cl), ("env (MergeEnv, 1 process)", ev),
                    ("multi-agent (ParallelEnv)", ma)):
        per = 1e3 * r["wall"] / max(r["decisions"], 1)
        over = 1e3 * (r["wall"] - r["sumo"]) / max(r["decisions"], 1)
        print(f"{name:28s}{r['decisions']:>10d}{r['episodes']:>10d}{r['wall']:>9.2f}{per:>13.3f}{over:>17.3f}"
              f"{1e3 * r['wall'] / a.sim_s:>10.2f}{r['episodes'] / r['wall']:>12.2f}")
    vec = {}
    for workers in (1, 2):
        vw, vdone, vstart = vec[workers] = vector_episodes(a.scenario, a.seed, a.vector_steps, workers)
        print(f"{f'env x{workers} (AsyncVectorEnv)':28s}{workers * a.vector_steps:>10d}{vdone:>10d}{vw:>9.2f}"
              f"{1e3 * vw / (workers * a.vector_steps):>13.3f}{'':>17s}{'':>10s}{vdone / vw:>12.2f}"
              f"   (+{vstart:.1f} s start and first reset)")
    r_dec = (ev["wall"] / ev["decisions"]) / (cl["wall"] / cl["decisions"])
    r_over = ((ev["wall"] - ev["sumo"]) / ev["decisions"]) / ((cl["wall"] - cl["sumo"]) / cl["decisions"])
    r_step = (ev["in_step"] / ev["decisions"]) / (cl["wall"] / cl["decisions"])
    print(f"env.step() alone: {1e3 * ev['in_step'] / ev['decisions']:.3f} ms per decision (SUMO to the next decision "
          f"included); the rest of the env's wall time is reset() running SUMO between take-overs")
    print(f"env / closed loop per decision: wall {r_dec:.2f}x, overhead {r_over:.2f}x, env.step() alone {r_step:.2f}x; "
          f"per simulated second {ev['wall'] / cl['wall']:.2f}x (target: at most 1.3x)")
    dps = {k: r["decisions"] / r["wall"] for k, r in (("cl", cl), ("env", ev), ("ma", ma))}
    print(f"multi-agent: {ma['steps']} steps for {ma['decisions']} decisions of {ma['episodes']} agents; decisions/s "
          f"{dps['ma']:.0f} vs env {dps['env']:.0f} ({dps['ma'] / dps['env']:.2f}x, target >= 1.3x) and closed loop "
          f"{dps['cl']:.0f} (per decision {dps['cl'] / dps['ma']:.2f}x the closed loop's time, target <= 1.1x)")
    sps = {w: w * a.vector_steps / vec[w][0] for w in vec}
    bound_frames, bound_wall = lockstep_bound(a.scenario, a.seed, a.vector_steps)
    print(f"AsyncVectorEnv steps/s: 1 worker {sps[1]:.0f}, 2 workers {sps[2]:.0f} ({sps[2] / sps[1]:.2f}x, "
          f"target >= 1.6x on 2 idle cores); load average {os.getloadavg()[0]:.1f}")
    print(f"  lock-step bound of 2 workers / 1 (each vector step waits for the slower worker; resets run SUMO "
          f"to the next take-over): {bound_frames:.2f}x from simulated frames per call, {bound_wall:.2f}x from "
          f"the calls' wall times here")


if __name__ == "__main__":
    main()
