"""SUMO's inputs for a scenario: the network and route files, the command-line options, and
the path of a SUMO binary."""

from __future__ import annotations

from pathlib import Path

from scenarios.network import build_network
from scenarios.routes import write_routes
from scenarios.spec.model import ScenarioSpec


def sumo_binary(name: str = "sumo") -> str:
    """Path of a SUMO binary (``sumo``, ``netconvert``) via sumolib."""
    import sumolib

    return sumolib.checkBinary(name)


def prepare_inputs(spec: ScenarioSpec, work_dir: Path) -> tuple[Path, Path]:
    """Network (cached) and route file of ``spec``; returns (net.net.xml, routes.rou.xml)."""
    net = build_network(spec.road)
    routes = write_routes(spec, work_dir)
    return net, routes


def sumo_args(spec: ScenarioSpec, net: Path, routes: Path) -> list[str]:
    """Command-line options shared by the libsumo run and the bare-binary benchmark."""
    sim = spec.simulation
    return [
        "-n", str(net), "-r", str(routes),
        "--step-length", f"{sim.step_s:g}",
        "--begin", "0", "--end", f"{sim.duration_s:g}",
        "--seed", str(sim.seed),
        "--no-step-log", "true", "--no-warnings", "true",
        "--collision.action", "warn",
        # SUMO disables jam teleports for any value <= 0
        "--time-to-teleport", f"{sim.time_to_teleport_s:g}" if sim.time_to_teleport_s > 0 else "-1",
    ]
