"""SUMO route file of a scenario: the driver population (vTypes) and the demand (flows).

Every vehicle class (car, truck) is a list of vTypes with probabilities; all of them go into
one ``vTypeDistribution`` named ``traffic`` with probability ``(1 - truck_share) * p`` for a car
type and ``truck_share * p`` for a truck type (p normalised within the class). One flow per
main lane (``departLane`` fixed) and one on the ramp; ``poisson`` arrivals use SUMO's
``period="exp(rate)"``, ``uniform`` arrivals ``vehsPerHour``. Randomness comes from SUMO's
``--seed``.
"""

from __future__ import annotations

from pathlib import Path
from xml.sax.saxutils import quoteattr

from scenarios.spec.model import ScenarioSpec, VTypeSpec

#: vClass written for each of the spec's vehicle classes.
SUMO_VCLASS = {"car": "passenger", "truck": "truck"}


def _fmt(v: object) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return f"{v:.6g}"
    return str(v)


def vtype_xml(vt: VTypeSpec, cls: str) -> str:
    """One ``<vType>`` element."""
    attrs: list[tuple[str, object]] = [
        ("id", vt.id), ("vClass", SUMO_VCLASS[cls]), ("carFollowModel", vt.car_follow_model),
        ("laneChangeModel", vt.lane_change_model), ("length", vt.length_m), ("width", vt.width_m),
        ("minGap", vt.min_gap_m), ("maxSpeed", vt.max_speed_mps), ("accel", vt.accel),
        ("decel", vt.decel), ("emergencyDecel", max(vt.emergency_decel, vt.decel)),
        ("sigma", vt.sigma), ("tau", vt.tau), ("speedFactor", vt.speed_factor),
        ("speedDev", vt.speed_dev),
    ]
    attrs += list(vt.cf_params) + list(vt.lc_params)
    body = " ".join(f"{k}={quoteattr(_fmt(v))}" for k, v in attrs)
    return f"    <vType {body}/>"


def type_class_map(spec: ScenarioSpec) -> dict[str, str]:
    """vType id -> "car" | "truck"."""
    return {vt.id: cls for cls in ("car", "truck") for vt in getattr(spec.drivers, cls)}


def routes_xml(spec: ScenarioSpec) -> str:
    """The full route file text."""
    d = spec.demand
    lines = ["<routes>", '  <vTypeDistribution id="traffic">']
    for cls, share in (("car", 1.0 - d.truck_share), ("truck", d.truck_share)):
        types = getattr(spec.drivers, cls)
        total = sum(vt.probability for vt in types)
        for vt in types:
            p = share * vt.probability / total
            if p > 0:
                lines.append(vtype_xml(vt, cls).replace("/>", f' probability="{p:.9g}"/>'))
    lines.append("  </vTypeDistribution>")
    tail = " bottleneck bottleneck_out" if spec.road.bottleneck_length_m > 0 else ""
    lines.append(f'  <route id="main" edges="main_in aux main_out{tail}"/>')
    lines.append(f'  <route id="ramp" edges="ramp aux main_out{tail}"/>')
    end = spec.simulation.duration_s
    n = spec.road.main_lanes

    def flow(fid: str, route: str, lane: int, veh_h: float) -> str:
        if d.arrivals == "poisson":
            rate = f'period="exp({veh_h / 3600.0:.9g})"'
        else:
            rate = f'vehsPerHour="{veh_h:.9g}"'
        return (f'  <flow id="{fid}" type="traffic" route="{route}" begin="0" end="{end:g}" {rate} '
                f'departLane="{lane}" departSpeed="{d.depart_speed}" departPos="base"/>')

    for i, veh_h in enumerate(d.main_veh_h):  # leftmost first: I-80 lane 7 - n + i
        if veh_h > 0:
            i80_lane = 7 - n + i
            lines.append(flow(f"L{i80_lane}", "main", n - 1 - i, veh_h))
    if d.ramp_veh_h > 0:
        lines.append(flow("R7", "ramp", 0, d.ramp_veh_h))
    lines.append("</routes>\n")
    return "\n".join(lines)


def write_routes(spec: ScenarioSpec, folder: Path) -> Path:
    """Write ``routes.rou.xml`` into ``folder`` and return its path."""
    path = Path(folder) / "routes.rou.xml"
    path.write_text(routes_xml(spec), encoding="utf-8")
    return path
