"""Build the SUMO network of a scenario with netconvert, cached by a hash of the road spec.

Geometry (SUMO metres): the main road runs along +x at the left road edge y = 0, lanes
spreading to the right (negative y), SUMO lane index 0 = rightmost. Edges:

* ``main_in``  x in [0, merge_position]: the main lanes;
* ``aux``      x in [merge_position, merge_position + aux_length]: main lanes + the auxiliary
  lane as SUMO lane 0 (I-80 lane 7), which has no successor: its vehicles must merge;
* ``main_out`` to ``main_length``: the main lanes;
* ``ramp``     one lane joining from the right at ``merge_position`` into the auxiliary lane;
* ``bottleneck``, ``bottleneck_out`` (only when ``bottleneck_length_m`` > 0) past
  ``main_length``: the downstream bottleneck whose queue reaches back into the section
  (vehicles on it have Local_Y beyond the study area): ``bottleneck_length_m`` of the main
  lanes at ``bottleneck_speed_mps``, then :data:`BOTTLENECK_EXIT_M` of ``bottleneck_lanes``
  lanes at the same speed: a lane drop, the rightmost lanes end there (``bottleneck_drop`` =
  "right") or the leftmost (``"left"``; ``bottleneck_out`` is then shifted right so that the
  lanes going on keep their lateral position).

Networks are cached in ``$MERGE_IRL_CACHE/networks/<hash>/net.net.xml`` (default cache
``~/.cache/merge-irl``). The hash covers the road spec and this module's format version, so a
rerun reuses the file; a build happens in a temporary folder renamed into place atomically.
Each entry holds the SHA-256 of its network file (``net.sha256``): an entry whose file is
missing, truncated or altered (a damaged disk, a hand edit) is detected and rebuilt.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import secrets
import shutil
import subprocess
from dataclasses import asdict
from pathlib import Path

from scenarios.errors import ScenarioError
from scenarios.spec.model import RoadSpec

NETWORK_FORMAT_VERSION = 1
#: Length (m) of the bottleneck's last edge, past the lane drop.
BOTTLENECK_EXIT_M = 200.0
NET_FILE = "net.net.xml"
CHECKSUM_FILE = "net.sha256"


class NetworkBuildError(ScenarioError, RuntimeError):
    """netconvert failed or is missing."""


def cache_root() -> Path:
    """``$MERGE_IRL_CACHE`` or ``~/.cache/merge-irl``."""
    env = os.environ.get("MERGE_IRL_CACHE")
    return Path(env).expanduser() if env else Path.home() / ".cache" / "merge-irl"


def network_key(road: RoadSpec) -> str:
    """Hex hash of everything the network depends on."""
    d = asdict(road)
    if not road.bottleneck_length_m > 0:  # roads without a bottleneck keep their cached networks
        for k in ("bottleneck_length_m", "bottleneck_speed_mps", "bottleneck_lanes", "bottleneck_drop"):
            d.pop(k)
    elif road.bottleneck_drop == "right":  # the layout before the field existed: same key
        d.pop("bottleneck_drop")
    payload = json.dumps({"v": NETWORK_FORMAT_VERSION, "road": d}, sort_keys=True)
    return hashlib.sha256(payload.encode()).hexdigest()[:16]


def _xml_files(road: RoadSpec) -> dict[str, str]:
    n, w = road.main_lanes, road.lane_width_m
    xm, xa, L = road.merge_position_m, road.merge_position_m + road.aux_length_m, road.main_length_m
    a = math.radians(road.ramp_angle_deg)
    y_join = -n * w  # right edge of the main lanes: the ramp's left edge where it joins
    rx0, ry0 = xm - road.ramp_length_m * math.cos(a), y_join - road.ramp_length_m * math.sin(a)
    nodes = f"""<nodes>
  <node id="start" x="0.00" y="0.00" type="priority"/>
  <node id="merge" x="{xm:.3f}" y="0.00" type="priority"/>
  <node id="auxend" x="{xa:.3f}" y="0.00" type="priority"/>
  <node id="end" x="{L:.3f}" y="0.00" type="priority"/>
  <node id="ramp_start" x="{rx0:.3f}" y="{ry0:.3f}" type="priority"/>
</nodes>
"""
    nb = road.bottleneck_lanes or n
    left = road.bottleneck_drop == "left"
    if road.bottleneck_length_m > 0:
        xb = L + road.bottleneck_length_m
        y_out = -(n - nb) * w if left else 0.0  # left edge of bottleneck_out's lanes
        nodes = nodes.replace("</nodes>", f'  <node id="bottleneck_mid" x="{xb:.3f}" y="0.00" type="priority"/>\n'
                                          f'  <node id="bottleneck_end" x="{xb + BOTTLENECK_EXIT_M:.3f}" y="{y_out:.3f}" '
                                          'type="priority"/>\n</nodes>')
    v, vr = road.speed_limit_mps, road.ramp_speed_limit_mps
    edges = f"""<edges>
  <edge id="main_in" from="start" to="merge" numLanes="{n}" speed="{v:.3f}" width="{w:.3f}" priority="3" spreadType="right"/>
  <edge id="aux" from="merge" to="auxend" numLanes="{n + 1}" speed="{v:.3f}" width="{w:.3f}" priority="3" spreadType="right"/>
  <edge id="main_out" from="auxend" to="end" numLanes="{n}" speed="{v:.3f}" width="{w:.3f}" priority="3" spreadType="right"/>
  <edge id="ramp" from="ramp_start" to="merge" numLanes="1" speed="{vr:.3f}" width="{w:.3f}" priority="1" spreadType="right"
        shape="{rx0:.3f},{ry0:.3f} {xm:.3f},{y_join:.3f}"/>
</edges>
"""
    if road.bottleneck_length_m > 0:
        vb = road.bottleneck_speed_mps
        xb = L + road.bottleneck_length_m
        out_shape = f' shape="{xb:.3f},{y_out:.3f} {xb + BOTTLENECK_EXIT_M:.3f},{y_out:.3f}"' if left else ""
        edges = edges.replace("</edges>", "".join(
            f'  <edge id="{eid}" from="{a}" to="{b}" numLanes="{k}" speed="{vb:.3f}" width="{w:.3f}" priority="3" '
            f'spreadType="right"{shape}/>\n'
            for eid, a, b, k, shape in (("bottleneck", "end", "bottleneck_mid", n, ""),
                                        ("bottleneck_out", "bottleneck_mid", "bottleneck_end", nb, out_shape)))
            + "</edges>")
    cons = ["<connections>"]
    for i in range(n):
        cons.append(f'  <connection from="main_in" to="aux" fromLane="{i}" toLane="{i + 1}"/>')
        cons.append(f'  <connection from="aux" to="main_out" fromLane="{i + 1}" toLane="{i}"/>')
    cons.append('  <connection from="ramp" to="aux" fromLane="0" toLane="0"/>')
    if road.bottleneck_length_m > 0:  # nb lanes go on; the n - nb rightmost (or leftmost) lanes end
        for i in range(n):
            cons.append(f'  <connection from="main_out" to="bottleneck" fromLane="{i}" toLane="{i}"/>')
        for i in range(nb):
            src = i if left else i + n - nb  # SUMO lane index 0 = rightmost
            cons.append(f'  <connection from="bottleneck" to="bottleneck_out" fromLane="{src}" toLane="{i}"/>')
    cons.append("</connections>\n")
    return {"nodes.nod.xml": nodes, "edges.edg.xml": edges, "connections.con.xml": "\n".join(cons)}


def netconvert_binary() -> str:
    """Path of netconvert (via sumolib, which knows the eclipse-sumo wheel's layout)."""
    import sumolib

    return sumolib.checkBinary("netconvert")


def build_network(road: RoadSpec, *, cache_dir: Path | None = None) -> Path:
    """Path of the ``.net.xml`` for ``road``; runs netconvert only if it is not cached yet.

    Raises:
        NetworkBuildError: netconvert fails (its error output is in the message).
    """
    root = (cache_dir or cache_root()) / "networks"
    final = root / network_key(road)
    net = final / NET_FILE
    if _intact(final):
        return net
    if final.exists():  # damaged: moved aside (one rename) and removed, then built again
        aside = root / f".{final.name}-{secrets.token_hex(6)}-damaged"
        try:
            os.rename(final, aside)
        except FileNotFoundError:  # another process moved it first
            pass
        shutil.rmtree(aside, ignore_errors=True)
    root.mkdir(parents=True, exist_ok=True)
    tmp = root / f".{final.name}-{secrets.token_hex(6)}"
    tmp.mkdir()  # mode 0777 minus umask, readable like the files (mkdtemp would give 0700)
    try:
        for name, text in _xml_files(road).items():
            (tmp / name).write_text(text, encoding="utf-8")
        cmd = [
            netconvert_binary(),
            "--node-files", "nodes.nod.xml",
            "--edge-files", "edges.edg.xml",
            "--connection-files", "connections.con.xml",
            "--output-file", NET_FILE,
            "--offset.disable-normalization", "true",
            "--no-turnarounds", "true",
            "--no-warnings", "true",
        ]
        proc = subprocess.run(cmd, cwd=tmp, capture_output=True, text=True)
        if proc.returncode != 0 or not (tmp / NET_FILE).is_file():
            raise NetworkBuildError(f"netconvert failed for road {road}: {proc.stderr.strip()[-2000:]}")
        (tmp / "road.json").write_text(json.dumps(asdict(road), indent=1), encoding="utf-8")
        (tmp / CHECKSUM_FILE).write_text(_sha256(tmp / NET_FILE) + "\n", encoding="utf-8")
        try:
            os.rename(tmp, final)
        except OSError:
            if not _intact(final):  # someone else's build did not win either
                raise
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
    return net


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _intact(entry: Path) -> bool:
    """Whether the cache ``entry`` holds its network file with the checksum recorded at build."""
    try:
        return (entry / CHECKSUM_FILE).read_text(encoding="utf-8").strip() == _sha256(entry / NET_FILE)
    except (OSError, UnicodeDecodeError):
        return False


__all__ = ["build_network", "cache_root", "network_key", "NetworkBuildError"]
