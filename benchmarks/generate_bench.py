"""Benchmark: ``generate`` (libsumo + full NGSIM table + encounters + Parquet) vs bare ``sumo --fcd-output``.

Same network, routes, seed and step. Prints the wall time of each, the ratio, vehicle-steps per
second, and the scaling when the demand or the duration is doubled::

    python -m benchmarks.generate_bench [--scenario i80] [--duration 300] [--repeat 3]

The bare binary writes FCD (position, speed, lane, acceleration) for the recorded period
(``--device.fcd.begin`` = warm-up); ours is timed in-process (``sim.merges.generate.generate``) and
as the ``merge-irl generate`` command (which adds Python start-up and imports). The last
column compares ours with the bare binary writing nothing (target: at most 2x).
"""

from __future__ import annotations

import argparse
import dataclasses
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchmarks.bare_sumo import time_bare
from scenarios.loader import load_scenario
from scenarios.spec.model import ScenarioSpec
from scenarios.spec.parse import with_overrides
from sim.merges.generate import generate


def time_ours(spec: ScenarioSpec, work: Path) -> tuple[float, float, int]:
    """(wall s, CPU s, vehicle-steps) of ``generate`` in this process."""
    c0, t0 = time.process_time(), time.perf_counter()
    res = generate(spec, work / "ours")
    return time.perf_counter() - t0, time.process_time() - c0, res.simulation.n_vehicle_steps


def time_cli(spec: ScenarioSpec, work: Path) -> float:
    toml = work / "spec.toml"
    toml.write_text(spec.to_toml())
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "analysis", "generate", "--scenario", str(toml), "--no-progress",
                    "--out", str(work / "cli")], check=True, capture_output=True)
    return time.perf_counter() - t0


def scaled_demand(spec: ScenarioSpec, factor: float) -> ScenarioSpec:
    d = spec.demand
    return dataclasses.replace(spec, demand=dataclasses.replace(
        d, main_veh_h=tuple(factor * v for v in d.main_veh_h), ramp_veh_h=factor * d.ramp_veh_h))


def measure(spec: ScenarioSpec, repeat: int, *, cli: bool = False) -> dict[str, float]:
    """Best of ``repeat`` for each of: bare wall/CPU, ours wall/CPU (and the CLI's wall)."""
    rows, clis, steps = [], [], 0
    for _ in range(repeat):
        with tempfile.TemporaryDirectory() as tmp:
            work = Path(tmp)
            bw, bc = time_bare(spec, work)
            ow, oc, steps = time_ours(spec, work)
            nw = time_bare(spec, work, fcd=False)[0]
            rows.append((bw, bc, ow, oc, nw))
            if cli:
                clis.append(time_cli(spec, work))
    best = [min(r[i] for r in rows) for i in range(5)]
    out = {"bare_s": best[0], "bare_cpu": best[1], "ours_s": best[2], "ours_cpu": best[3], "nofcd_s": best[4],
           "vehicle_steps": steps}
    if cli:
        out["cli_s"] = min(clis)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="i80")
    ap.add_argument("--duration", type=float, default=300.0)
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args(argv)
    preset = with_overrides(load_scenario(a.scenario), duration_s=a.duration)
    w = preset.simulation.warmup_s
    half = scaled_demand(preset, 0.5)  # the scaling runs start below capacity so demand can double
    cases = [
        (f"{preset.name}", preset, True),
        ("half demand", half, False),
        ("2x demand", preset, False),
        ("2x duration", with_overrides(half, duration_s=w + 2 * (a.duration - w)), False),
    ]
    print(f"scenario {preset.name}, seed {preset.simulation.seed}, step {preset.simulation.step_s} s, "
          f"warm-up {w:g} s, best of {a.repeat}; CPU = user + system seconds")
    print(f"{'case':<12} {'sim s':>6} {'veh-steps':>10} {'bare wall':>9} {'ours wall':>9} {'ratio':>6} "
          f"{'bare CPU':>8} {'ours CPU':>8} {'ratio':>6} {'ours veh-steps/CPU s':>20} {'CLI wall':>8} "
          f"{'vs no-output':>12}")
    results = {}
    for name, spec, cli in cases:
        m = measure(spec, a.repeat, cli=cli)
        results[name] = m
        print(f"{name:<12} {spec.simulation.duration_s:6.0f} {m['vehicle_steps']:10d} {m['bare_s']:9.2f} "
              f"{m['ours_s']:9.2f} {m['ours_s'] / m['bare_s']:6.2f} {m['bare_cpu']:8.2f} {m['ours_cpu']:8.2f} "
              f"{m['ours_cpu'] / m['bare_cpu']:6.2f} {m['vehicle_steps'] / m['ours_cpu']:20.0f} "
              f"{m.get('cli_s', float('nan')):8.2f} {m['ours_s'] / m['nofcd_s']:12.2f}")
    b = results["half demand"]
    for name in ("2x demand", "2x duration"):
        m = results[name]
        print(f"{name} vs half demand: vehicle-steps x{m['vehicle_steps'] / b['vehicle_steps']:.2f}, "
              f"ours CPU x{m['ours_cpu'] / b['ours_cpu']:.2f} (wall x{m['ours_s'] / b['ours_s']:.2f}), "
              f"bare CPU x{m['bare_cpu'] / b['bare_cpu']:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
