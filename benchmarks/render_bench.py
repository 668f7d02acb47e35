"""Benchmark: the cost of one ``rgb_array`` frame (:class:`sim.env.render.TopDownRenderer`).

Frames of one run (``synthetic``, seed 2, Zero at every decision) are drawn again and again:
``frame()`` (the road copied, the cars, the letters A/B/C, the clock) beside the floor of any
frame, copying the pre-drawn road and header (``background.copy()``). The fastest of
``--repeat`` passes is kept; printed: ms per frame of each and their ratio.
Run: ``python -m benchmarks.render_bench [--frames 30] [--repeat 7]``.
"""

from __future__ import annotations

import argparse
import time

from sim.env import MergeEnv


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=30)
    ap.add_argument("--repeat", type=int, default=7)
    a = ap.parse_args(argv)
    env = MergeEnv(run_s=240.0, render_mode="rgb_array")
    try:
        env.reset(seed=2)
        env.render()
        frames = []
        for _ in range(a.frames):
            _, _, terminated, truncated, _ = env.step(2)
            assert env._ctl is not None
            frames.append((env._frame, dict(env._ctl.role_rows)))
            if terminated or truncated:
                env.reset()
        rnd = env._renderer
    finally:
        env.close()
    best = {"frame()": float("inf"), "background.copy()": float("inf")}
    for _ in range(a.repeat):
        t = time.perf_counter()
        for f, roles in frames:
            rnd.frame(f, roles)
        best["frame()"] = min(best["frame()"], (time.perf_counter() - t) / len(frames))
        t = time.perf_counter()
        for _ in frames:
            rnd.background.copy()
        best["background.copy()"] = min(best["background.copy()"], (time.perf_counter() - t) / len(frames))
    for name, s in best.items():
        print(f"{name:20s}{1e3 * s:8.3f} ms per frame ({rnd.height}x{rnd.width})")
    print(f"frame() / background.copy(): {best['frame()'] / best['background.copy()']:.1f}x")


if __name__ == "__main__":
    main()
