"""Run real SUMO (libsumo) on leader-follower pairs: the leader replays a speed profile, the
follower drives with a SUMO car-following model.

This is the ground truth the numpy replica (:mod:`analysis.calibration.models`) is checked
against, and a generator of synthetic pairs with known parameters. Every pair gets its own
one-lane straight edge (so pairs never interact) in one network; the whole batch is one
libsumo simulation (libsumo allows one per process: call this in a fresh process when another
simulation ran before).

Leaders are controlled with ``setSpeedMode(id, 0)`` + ``setSpeed(id, v)`` each step, so their
speed follows the profile exactly; their realised positions are recorded and returned.
"""

from __future__ import annotations

import subprocess
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from analysis.calibration.models import CALIBRATION_MODELS, DT, EIDM_NOISE_OFF, CFParams
from scenarios.errors import ScenarioError


@dataclass(frozen=True)
class ReplayCase:
    """One pair to simulate (SI units).

    Attributes:
        v_leader: float64[T] leader speed profile (m/s), one value per 0.1 s step.
        x_leader0, x_follower0: initial front positions (m) on the edge.
        v_follower0: follower's initial speed (m/s).
        leader_length: m.
    """

    v_leader: np.ndarray
    x_leader0: float
    x_follower0: float
    v_follower0: float
    leader_length: float = 4.5


@dataclass(frozen=True)
class ReplayResult:
    """float64[P, T] arrays recorded from SUMO after every step (step 0 = inserted state)."""

    x_leader: np.ndarray
    v_leader: np.ndarray
    x_follower: np.ndarray
    v_follower: np.ndarray


def _build_net(workdir: Path, n: int, length: float) -> Path:
    import sumolib

    nodes = ["<nodes>"]
    edges = ["<edges>"]
    for i in range(n):
        y = 20.0 * i
        nodes.append(f'  <node id="a{i}" x="0" y="{y}"/><node id="b{i}" x="{length:.1f}" y="{y}"/>')
        edges.append(f'  <edge id="e{i}" from="a{i}" to="b{i}" numLanes="1" speed="70"/>')
    (workdir / "n.nod.xml").write_text("\n".join(nodes + ["</nodes>"]))
    (workdir / "e.edg.xml").write_text("\n".join(edges + ["</edges>"]))
    net = workdir / "net.net.xml"
    proc = subprocess.run(
        [sumolib.checkBinary("netconvert"), "-n", str(workdir / "n.nod.xml"),
         "-e", str(workdir / "e.edg.xml"), "-o", str(net), "--no-turnarounds"],
        capture_output=True, text=True,
    )
    if proc.returncode != 0:
        raise ScenarioError(f"netconvert failed: {proc.stderr.strip()[:500]}")
    return net


def run_sumo_pairs(
    cases: Sequence[ReplayCase], params: Sequence[CFParams] | CFParams, *, model: str = "idm",
    action_step_s: float = DT,
) -> ReplayResult:
    """Simulate every case in one libsumo run; ``params`` per case or one for all.

    ``model`` is a key of :data:`~analysis.calibration.models.CALIBRATION_MODELS` (Krauss with
    sigma 0, EIDM with its noise off). libsumo runs one simulation at a time per process; runs
    may follow each other in the same process. ``action_step_s``: the followers' vType
    ``actionStepLength`` (s, a multiple of the 0.1 s step; decisions every that long).

    Raises:
        ScenarioError: ``model`` has no SUMO car-following model, or SUMO did not insert a pair's follower.
    """
    import libsumo as traci

    if model not in CALIBRATION_MODELS:
        raise ScenarioError(f"model must be one of {sorted(CALIBRATION_MODELS)}, got {model!r}")
    n = len(cases)
    plist = [params] * n if isinstance(params, CFParams) else list(params)
    T = max(len(c.v_leader) for c in cases)
    length = max(c.x_leader0 + float(np.sum(c.v_leader)) * DT for c in cases) + 2000.0
    with tempfile.TemporaryDirectory(prefix="merge-irl-replay-") as tmp:
        wd = Path(tmp)
        net = _build_net(wd, n, length)
        rou = ["<routes>"]
        for i, (c, p) in enumerate(zip(cases, plist)):
            extra = ' sigma="0"' if model == "krauss" else f' delta="{float(p.delta)!r}"'
            extra += f' actionStepLength="{float(action_step_s)!r}"' if action_step_s != DT else ""
            if model == "eidm":  # deterministic: noise off (models.EIDM_NOISE_OFF)
                extra += "".join(f' {k}="{v!r}"' for k, v in EIDM_NOISE_OFF.items())
            rou.append(
                f'  <vType id="L{i}" length="{float(c.leader_length)!r}" maxSpeed="70" accel="20" decel="{float(p.decel)!r}" '
                f'emergencyDecel="{float(max(p.emergencyDecel, p.decel))!r}" speedFactor="1" speedDev="0" minGap="0"/>'
            )
            rou.append(
                f'  <vType id="F{i}" carFollowModel="{CALIBRATION_MODELS[model]}" accel="{float(p.accel)!r}" '
                f'decel="{float(p.decel)!r}" tau="{float(p.tau)!r}" minGap="{float(p.minGap)!r}" maxSpeed="{float(p.maxSpeed)!r}" '
                f'emergencyDecel="{float(p.emergencyDecel)!r}" speedFactor="1" speedDev="0"{extra}/>'
            )
        for i, c in enumerate(cases):
            rou.append(f'  <route id="r{i}" edges="e{i}"/>')
            rou.append(
                f'  <vehicle id="l{i}" type="L{i}" route="r{i}" depart="0" departPos="{float(c.x_leader0)!r}" '
                f'departSpeed="{float(c.v_leader[0])!r}" insertionChecks="none"/>'
            )
            rou.append(
                f'  <vehicle id="f{i}" type="F{i}" route="r{i}" depart="0" departPos="{float(c.x_follower0)!r}" '
                f'departSpeed="{min(float(c.v_follower0), float(plist[i].maxSpeed))!r}" insertionChecks="none"/>'
            )
        (wd / "r.rou.xml").write_text("\n".join(rou + ["</routes>"]))
        traci.start([
            "sumo", "-n", str(net), "-r", str(wd / "r.rou.xml"), "--step-length", str(DT),
            "--no-step-log", "--no-warnings", "--collision.action", "none",
            "--default.action-step-length", str(DT),
        ])
        try:
            out = np.full((4, n, T), np.nan)
            traci.simulationStep()
            for k in range(T):
                if k > 0:
                    for i, c in enumerate(cases):
                        if k < len(c.v_leader):
                            traci.vehicle.setSpeed(f"l{i}", float(c.v_leader[k]))
                    traci.simulationStep()
                present = set(traci.vehicle.getIDList())
                for i, c in enumerate(cases):
                    if k == 0 and (f"l{i}" not in present or f"f{i}" not in present):
                        raise ScenarioError(f"SUMO did not insert pair {i}")
                    if k >= len(c.v_leader) or f"l{i}" not in present:
                        continue
                    if k == 0:
                        if c.v_follower0 > plist[i].maxSpeed:  # SUMO inserts at most at maxSpeed
                            traci.vehicle.setPreviousSpeed(f"f{i}", float(c.v_follower0))
                        traci.vehicle.setSpeedMode(f"l{i}", 0)
                        traci.vehicle.setLaneChangeMode(f"l{i}", 0)
                        traci.vehicle.setLaneChangeMode(f"f{i}", 0)
                    out[0, i, k] = traci.vehicle.getLanePosition(f"l{i}")
                    out[1, i, k] = traci.vehicle.getSpeed(f"l{i}")
                    out[2, i, k] = traci.vehicle.getLanePosition(f"f{i}")
                    out[3, i, k] = traci.vehicle.getSpeed(f"f{i}")
        finally:
            traci.close()
    return ReplayResult(x_leader=out[0], v_leader=out[1], x_follower=out[2], v_follower=out[3])
