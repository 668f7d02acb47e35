"""The baseline of the simulation benchmarks: the bare ``sumo`` binary on a scenario's own inputs."""

from __future__ import annotations

import resource
import subprocess
import time
from pathlib import Path

from scenarios.spec.model import ScenarioSpec
from sim.runtime.sumo_inputs import prepare_inputs, sumo_args, sumo_binary


def children_cpu_s() -> float:
    """User + system CPU seconds of this process's finished children."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def time_bare(spec: ScenarioSpec, work: Path, *, fcd: bool = True) -> tuple[float, float]:
    """(wall s, CPU s) of the bare binary with the same network, routes, seed and step.

    ``fcd``: write FCD output (position, speed, lane, acceleration) from the end of the
    warm-up, as a user would to get trajectories; otherwise write nothing.
    """
    net, routes = prepare_inputs(spec, work)
    cmd = [sumo_binary("sumo"), *sumo_args(spec, net, routes)]
    if fcd:
        cmd += ["--fcd-output", str(work / "fcd.xml"), "--fcd-output.acceleration", "true",
                "--device.fcd.begin", f"{spec.simulation.warmup_s:g}"]
    c0, t0 = children_cpu_s(), time.perf_counter()
    subprocess.run(cmd, check=True, capture_output=True)
    return time.perf_counter() - t0, children_cpu_s() - c0
