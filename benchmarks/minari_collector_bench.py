"""Benchmark: Minari's ``DataCollector`` around :class:`sim.env.MergeEnv` against the bare
environment, side by side.

Same scenario, the same 64-bit seed (``2**63 + 5``: mapped into SUMO's range by
:mod:`sim.env.seeds`), ``--episodes`` episodes of one SUMO run (the later resets with
``minari_autoseed=False``: the next take-over of the same run), the same seeded random actions;
the two alternate ``--repeat`` times and the fastest of each is kept. Printed: wall seconds and
steps of each, their ratio, ``create_dataset``'s seconds (arrow format), and whether the
collected observations equal the bare environment's. The first collector of a process also
pays jax's import (Minari's ``create`` extra); the fastest-of rule leaves it out after the
first repeat.

Run: ``python -m benchmarks.minari_collector_bench [--episodes 4] [--run-s 600] [--repeat 3]``
(needs the ``rl`` extra).
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
import warnings

import numpy as np

SEED = 2**63 + 5


def episodes(env, n: int) -> tuple[float, int, list[np.ndarray]]:
    """``n`` episodes of seeded random actions: (wall s, steps, each episode's observations)."""
    rng = np.random.default_rng(0)
    steps, out = 0, []
    t = time.perf_counter()
    for i in range(n):
        obs, _ = env.reset(seed=SEED if i == 0 else None, options=None if i == 0 else {"minari_autoseed": False})
        seen = [obs]
        while True:
            obs, _, term, trunc, _ = env.step(int(rng.integers(5)))
            seen.append(obs)
            steps += 1
            if term or trunc:
                break
        out.append(np.array(seen))
    return time.perf_counter() - t, steps, out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--episodes", type=int, default=4)
    ap.add_argument("--run-s", type=float, default=600.0, help="simulated seconds of the SUMO run (default 600)")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args(argv)
    import minari

    from sim.env import MergeEnv

    os.environ["MINARI_DATASETS_PATH"] = tempfile.mkdtemp(prefix="minari-bench-")
    warnings.filterwarnings("ignore", category=UserWarning, module="minari")
    bare, coll, write = [], [], []
    same = True
    for r in range(args.repeat):
        env = MergeEnv(run_s=args.run_s)
        try:
            wall, steps, obs_bare = episodes(env, args.episodes)
        finally:
            env.close()
        bare.append((wall, steps))
        env = minari.DataCollector(MergeEnv(run_s=args.run_s), data_format="arrow")
        try:
            wall, steps, _ = episodes(env, args.episodes)
            t = time.perf_counter()
            ds = env.create_dataset(f"bench/collector{r}-v0", algorithm_name="random")
            write.append(time.perf_counter() - t)
        finally:
            env.close()
        coll.append((wall, steps))
        got = [e.observations for e in ds.iterate_episodes()]
        same = same and len(got) == len(obs_bare) and all(np.array_equal(a, b) for a, b in zip(got, obs_bare))
    (b_s, b_n), (c_s, c_n) = min(bare), min(coll)
    print(f"bare MergeEnv:          {b_s:.3f} s, {b_n} steps ({1e3 * b_s / b_n:.2f} ms/step)")
    print(f"DataCollector(MergeEnv): {c_s:.3f} s, {c_n} steps ({1e3 * c_s / c_n:.2f} ms/step)")
    print(f"ratio collector / bare: {c_s / b_s:.2f}x; create_dataset (arrow): {min(write):.3f} s")
    print(f"collected observations equal the bare environment's: {same}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
