"""Benchmark: the environment's seams, what they cost and what adding one takes.

* Files to add an observation: the script writes one module (a two-column observation) into a
  fresh folder, makes the environment with ``observation="module:Class"`` and runs it; it counts
  the files it wrote (1) and checks that no file of the checkout changed (``git status``).
* Per call: the default observation through the registry's observer
  (``EnvCore.observation``) against :func:`sim.drivers.observe.policy_observation` called
  directly (what the environment did before), and the task reward with its value check
  (:func:`sim.env.rewards.reward_value`) and its terms for ``info["rewards"]`` against the bare
  ``float(reward(...))``, on the observations of real decisions.
* Per step: the environment with the default observation and with the added one, same seed and
  actions, alternating, the fastest of ``--repeat`` kept.

Run: ``python -m benchmarks.env_seams_bench [--steps 300] [--repeat 3] [--seed 1]``.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

OBSERVATION_FILE = '''
import numpy as np
from gymnasium import spaces


class SpeedGap:
    def __init__(self, config):
        self.config = config

    def space(self):
        return spaces.Box(np.array([0.0, -1e4]), np.array([300.0, 1e4]), dtype=np.float64)

    def observe(self, obs):
        gap = obs.d_AC - obs.len_C if np.isfinite(obs.d_AC) and np.isfinite(obs.len_C) else 1000.0
        return np.array([obs.speed_A, gap], dtype=np.float64)
'''


def _git_status() -> str:
    return subprocess.run(["git", "status", "--porcelain"], cwd=ROOT, capture_output=True, text=True).stdout


def run_steps(observation: str, seed: int, steps: int) -> tuple[float, list]:
    """Seconds for ``steps`` env steps (Zero), and the MergeObservations the agent decided on."""
    from sim.env import MergeEnv

    env = MergeEnv(run_s=1800.0, observation=observation)
    seen = []
    try:
        env.reset(seed=seed)
        t = time.perf_counter()
        for _ in range(steps):
            if env._pending is not None:
                seen.append(env._pending[3])
            _, _, term, trunc, _ = env.step(2)
            if term or trunc:
                env.reset()
        return time.perf_counter() - t, seen
    finally:
        env.close()


def per_call(fn, items, repeat: int) -> float:
    best = float("inf")
    for _ in range(repeat):
        t = time.perf_counter()
        for x in items:
            fn(x)
        best = min(best, time.perf_counter() - t)
    return best / max(len(items), 1)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args(argv)
    from sim.drivers.observe import policy_observation
    from sim.env.config import MergeEnvConfig
    from sim.env.core import EnvCore
    from sim.env.rewards import reward_value
    from sim.env.task_reward import TaskReward

    before = _git_status()
    with tempfile.TemporaryDirectory() as tmp:
        (Path(tmp) / "bench_speed_gap.py").write_text(OBSERVATION_FILE)
        written = [p for p in Path(tmp).rglob("*") if p.is_file() and "__pycache__" not in p.parts]
        sys.path.insert(0, tmp)
        added = "bench_speed_gap:SpeedGap"
        default_s, added_s = float("inf"), float("inf")
        seen: list = []
        for _ in range(args.repeat):
            s, seen = run_steps("policy", args.seed, args.steps)
            default_s = min(default_s, s)
            added_s = min(added_s, run_steps(added, args.seed, args.steps)[0])
        sys.path.remove(tmp)
    changed = _git_status() != before
    print(f"files to add an observation: {len(written)} ({', '.join(p.name for p in written)}); "
          f"checkout files changed: {'yes' if changed else 'none'}")
    core = EnvCore(MergeEnvConfig(run_s=1800.0))
    n = max(1, 20_000 // max(len(seen), 1))
    items = seen * n
    direct = per_call(policy_observation, items, args.repeat)
    seam = per_call(core.observation, items, args.repeat)
    r = TaskReward()
    bare = per_call(lambda o: float(r(o, 2, 0.0)), items, args.repeat)
    checked = per_call(lambda o: (reward_value(r(o, 2, 0.0), "w"), core.reward_terms(o, 2, 0.0, 0.0)), items,
                       args.repeat)
    print(f"observations of {len(seen)} real decisions, {len(items)} calls, fastest of {args.repeat}:")
    print(f"  observation: direct {direct * 1e6:.2f} us, through the registry {seam * 1e6:.2f} us "
          f"(ratio {seam / direct:.2f})")
    print(f"  task reward: bare {bare * 1e6:.2f} us, checked + terms {checked * 1e6:.2f} us "
          f"(ratio {checked / bare:.2f})")
    print(f"env, {args.steps} steps, fastest of {args.repeat}: default {default_s / args.steps * 1e3:.3f} ms/step, "
          f"added observation {added_s / args.steps * 1e3:.3f} ms/step (ratio {added_s / default_s:.2f})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
