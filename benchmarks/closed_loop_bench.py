"""Benchmark: closed loop (one controlled car per merge) + rerun logging vs the bare ``sumo`` binary.

Side by side on the same scenario, network, routes and seed:

* ``bare``: the ``sumo`` binary, no output (pure simulation), and ``bare+fcd``: with
  ``--fcd-output`` from the warm-up on (what a user would run to get trajectories);
* ``closed loop``: ``sim.runtime.run.run_scenario`` with the :class:`sim.closed_loop.controller.Controller`
  driving every merge's lag car with a learned-policy table (a random ``[1250, 5]`` Q table,
  sampled actions) and the :class:`analysis.recording.log.RerunLogger` writing an ``.rrd``;
* ``rerun logging alone``: the wall time spent inside the logger's hook calls, per
  vehicle-frame.

Targets: closed loop at most 2.3x the bare binary (3x before 2026-12-07); logging alone under
10 microseconds per vehicle-frame. With ``--parts``, the CPU time of the run alone (the recorded
table, no hooks) and with the controller, beside the closed loop's: what each part adds.
Run: ``python -m benchmarks.closed_loop_bench [--repeat N] [--parts]``.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from analysis.recording.log import RerunLogger
from benchmarks.bare_sumo import time_bare
from irl.domains.merge.bins import MergeBins
from scenarios.loader import load_scenario
from scenarios.spec.parse import with_overrides
from sim.closed_loop.controller import Controller
from sim.drivers.learned import LearnedPolicy
from sim.drivers.policy import Policy
from sim.runtime.run import run_scenario


class _Timed:
    """Wraps a hook and accumulates the wall time of its calls."""

    def __init__(self, hook):
        self.hook, self.seconds = hook, 0.0

    def on_start(self, ctx):
        t = time.perf_counter()
        self.hook.on_start(ctx)
        self.seconds += time.perf_counter() - t

    def on_step(self, ctx, frame):
        t = time.perf_counter()
        self.hook.on_step(ctx, frame)
        self.seconds += time.perf_counter() - t

    def on_end(self, ctx):
        t = time.perf_counter()
        self.hook.on_end(ctx)
        self.seconds += time.perf_counter() - t


def bench_policy(driver: str | None = None) -> Policy:
    """The driver file ``driver``, or (None) a random tabular policy: a ``[1250, 5]`` Q table, seed 0."""
    if driver is not None:
        from sim.drivers.formats import driver_policy

        return driver_policy(driver)
    rng = np.random.default_rng(0)
    q = rng.normal(size=(1250, 5))
    lp = q - np.log(np.exp(q).sum(axis=1, keepdims=True))
    edges = {"d_AC": (35, 60, 90, 130), "d_AB": (10, 30, 60, 100), "v_AC": (-7.5, -2.5, 2.5, 7.5),
             "v_AB": (-7.5, -2.5, 2.5, 7.5)}
    return LearnedPolicy(lp, MergeBins.from_dict(edges), name="bench")


def cpu_of_parts(spec, work: Path, driver: str | None = None) -> dict[str, float]:
    """CPU seconds (user + system, this process) of the run alone (recording the table, no
    hooks) and with the controller: with the full closed loop's CPU time, what each part adds."""
    out = {}
    for name, hooks in (("run", []), ("run+controller", [Controller(bench_policy(driver))])):
        c = time.process_time()
        run_scenario(spec, hooks=hooks, work_dir=work / name)
        out[name] = time.process_time() - c
    return out


def time_closed_loop(spec, work: Path, driver: str | None = None) -> dict[str, float]:
    """One closed-loop run with rerun logging: a random tabular policy, or the driver file ``driver``."""
    policy = bench_policy(driver)
    ctl = Controller(policy)
    tctl = _Timed(ctl)
    log = RerunLogger(work / "bench.rrd", controller=ctl)
    tlog = _Timed(log)
    c = time.process_time()  # every thread of this process, rerun's writer included
    t = time.perf_counter()
    res = run_scenario(spec, hooks=[tctl, tlog], work_dir=work / "run")
    wall = time.perf_counter() - t
    return {"wall": wall, "cpu": time.process_time() - c, "sumo": res.sumo_time_s, "controller": tctl.seconds, "logger": tlog.seconds,
            "vehicle_frames": float(log.n_vehicle_frames), "controls": float(len(ctl.controls)),
            "rrd_mb": (work / "bench.rrd").stat().st_size / 1e6}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="synthetic")
    ap.add_argument("--duration", type=float, default=None, help="simulated seconds (default: the scenario's)")
    ap.add_argument("--repeat", type=int, default=5, help="repetitions (medians are reported)")
    ap.add_argument("--driver", default=None, metavar="DRIVER.json",
                    help="drive with this driver file (e.g. a planning driver) instead of a random tabular policy")
    ap.add_argument("--parts", action="store_true",
                    help="also the CPU time of the run alone and with the controller (no logger), per repetition")
    args = ap.parse_args(argv)
    spec = load_scenario(args.scenario)
    if args.duration is not None:
        spec = with_overrides(spec, duration_s=args.duration)
    bare, bare_cpu, fcd, ours, parts = [], [], [], [], []
    with tempfile.TemporaryDirectory(prefix="merge-irl-clbench-") as tmp:
        work = Path(tmp)
        time_bare(spec, work, fcd=False)  # builds / warms the network cache
        for i in range(args.repeat):
            wall, cpu = time_bare(spec, work, fcd=False)
            bare.append(wall)
            bare_cpu.append(cpu)
            fcd.append(time_bare(spec, work, fcd=True)[0])
            (work / f"r{i}").mkdir()
            ours.append(time_closed_loop(spec, work / f"r{i}", args.driver))
            if args.parts:
                parts.append(cpu_of_parts(spec, work / f"r{i}", args.driver))
    med = lambda xs: float(np.median(xs))  # noqa: E731
    b, f = med(bare), med(fcd)
    o = {k: med([r[k] for r in ours]) for k in ours[0]}
    # ratios are paired within each repetition (the three runs of one repetition follow each
    # other), which cancels most of a shared machine's slow phases
    ratios = [r["wall"] / x for r, x in zip(ours, bare)]
    ratios_fcd = [r["wall"] / x for r, x in zip(ours, fcd)]
    us_log = 1e6 * o["logger"] / max(1.0, o["vehicle_frames"])
    us_ctl = 1e6 * o["controller"] / max(1.0, o["vehicle_frames"])
    print(f"scenario {spec.name}: {spec.simulation.duration_s:g} s simulated, seed {spec.simulation.seed}, "
          f"median of {args.repeat}")
    print(f"  bare sumo binary (no output)     {b:7.2f} s")
    print(f"  bare sumo binary + fcd-output    {f:7.2f} s")
    print(f"  closed loop + rerun logging      {o['wall']:7.2f} s   ({int(o['controls'])} controlled cars, "
          f"{int(o['vehicle_frames'])} vehicle-frames, .rrd {o['rrd_mb']:.1f} MB)")
    print(f"    of which simulationStep        {o['sumo']:7.2f} s")
    print(f"    of which controller            {o['controller']:7.2f} s   ({us_ctl:.2f} us per vehicle-frame)")
    print(f"    of which rerun logging         {o['logger']:7.2f} s   ({us_log:.2f} us per vehicle-frame)")
    print(f"  ratio closed loop / bare         {med(ratios):7.2f} x   (target <= 2.3; per repetition "
          f"{', '.join(f'{r:.2f}' for r in ratios)})")
    print(f"  ratio of best times / bare       {min(r['wall'] for r in ours) / min(bare):7.2f} x   "
          f"(the least disturbed run of each)")
    print(f"  CPU-time ratio / bare            {med([r['cpu'] / x for r, x in zip(ours, bare_cpu)]):7.2f} x   "
          f"(user + system; less sensitive to a busy machine than wall time)")
    print(f"  ratio closed loop / bare+fcd     {med(ratios_fcd):7.2f} x   (per repetition "
          f"{', '.join(f'{r:.2f}' for r in ratios_fcd)})")
    print(f"  rerun logging per vehicle-frame  {us_log:7.2f} us  (target < 10)")
    if parts:
        bc = med(bare_cpu)
        by_part = {**{k: med([p[k] for p in parts]) for k in parts[0]}, "closed loop + rerun": o["cpu"]}
        print("  CPU time / bare CPU, by part:    " + ", ".join(f"{k} {v:.2f} s ({v / bc:.2f}x)" for k, v in by_part.items())
              + f"; bare {bc:.2f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
