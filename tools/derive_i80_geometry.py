"""Derive the compact I-80 road geometry shipped in ``scenarios/data/i80_geometry.toml``.

One-off script (kept so the numbers can be re-derived and checked):

    python -m tools.derive_i80_geometry ../shared/data/i80_geometry \
        --out scenarios/data/i80_geometry.toml

Input: NGSIM.jl's I-80 files (MIT licence; point lists in NGSIM global coordinates, feet):
``ngsimjl_centerlines80.txt`` (``centerline1``..``centerline6``, ``onramp``, ``offramp``) and
``ngsimjl_boundaries80.txt`` (lane edges). Every point is projected onto the centerline of lane
6 (the rightmost main lane), giving a station along the road and a lateral offset (left > 0):

* main lanes: the number of ``centerline<k>``; lane width: median offset between adjacent
  lane centerlines;
* section: from the upstream end of the on-ramp geometry to the off-ramp diverge (where the
  off-ramp centerline leaves lane 6), the stretch of I-80 between the Powell Street on-ramp and
  the off-ramp that NGSIM's study area covers;
* merge point (ramp gore): the end of the boundary separating the ramp from lane 6 (the ramp
  becomes the auxiliary lane, I-80 lane 7, there);
* ramp length: the on-ramp centerline from its start to the gore; ramp angle: its mean
  convergence angle towards lane 6;
* auxiliary lane end: where the ramp's outer edge meets lane 6's outer edge (within 1 ft);
  the station where half the auxiliary lane's width is left is reported too.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from merge_irl.atomic import write_text_atomic

FT_TO_M = 0.3048


def _read_blocks(path: Path, marker: str, named: bool) -> dict[str, np.ndarray]:
    lines = path.read_text().splitlines()
    out: dict[str, np.ndarray] = {}
    i = 0
    while i < len(lines):
        s = lines[i].strip()
        if s == marker or (not named and s.startswith(marker + " ")):
            if named:
                name, n, start = lines[i + 1].strip(), int(lines[i + 2]), i + 3
            else:
                name, n, start = s, int(lines[i + 1]), i + 2
            out[name] = np.array([[float(v) for v in ln.split()] for ln in lines[start:start + n]])
            i = start + n
        else:
            i += 1
    return out


class Reference:
    """Stations / signed lateral offsets (ft, left > 0) relative to a polyline."""

    def __init__(self, pts: np.ndarray) -> None:
        self.a = pts[:-1]
        self.seg = np.diff(pts, axis=0)
        self.len = np.hypot(*self.seg.T)
        self.s0 = np.concatenate([[0.0], np.cumsum(self.len)])

    def project(self, p: np.ndarray) -> tuple[float, float]:
        t = np.clip(((p - self.a) * self.seg).sum(1) / self.len**2, 0.0, 1.0)
        q = self.a + t[:, None] * self.seg
        d = np.hypot(*(p - q).T)
        j = int(np.argmin(d))
        cross = self.seg[j, 0] * (p[1] - self.a[j, 1]) - self.seg[j, 1] * (p[0] - self.a[j, 0])
        return float(self.s0[j] + t[j] * self.len[j]), float(math.copysign(d[j], cross))

    def project_all(self, pts: np.ndarray) -> np.ndarray:
        """float64[N, 2] -> float64[N, 2] (station, offset); points beyond the ends dropped."""
        st = np.array([self.project(p) for p in pts])
        inside = (st[:, 0] > 1e-6) & (st[:, 0] < self.s0[-1] - 1e-6)
        return st[inside]


def _crossing(st: np.ndarray, level: float) -> float:
    """First station where the offset rises to ``level`` (linear interpolation)."""
    s, o = st[:, 0], st[:, 1]
    i = int(np.argmax(o >= level))
    if o[i] < level:
        raise ValueError(f"offset never reaches {level}")
    if i == 0:
        return float(s[0])
    return float(s[i - 1] + (level - o[i - 1]) * (s[i] - s[i - 1]) / (o[i] - o[i - 1]))


def derive(data_dir: Path) -> dict:
    cl = _read_blocks(data_dir / "ngsimjl_centerlines80.txt", "CENTERLINE", named=True)
    bd = _read_blocks(data_dir / "ngsimjl_boundaries80.txt", "BOUNDARY", named=False)
    mains = sorted(k for k in cl if k.startswith("centerline"))
    n_main = len(mains)
    ref = Reference(cl[f"centerline{n_main}"])
    offsets = [np.median(ref.project_all(cl[f"centerline{k}"])[:, 1]) for k in range(1, n_main + 1)]
    lane_w = float(np.median(-np.diff(offsets)))
    ramp = ref.project_all(cl["onramp"])
    off = ref.project_all(cl["offramp"])
    s_start = float(ramp[0, 0])
    s_diverge = float(off[0, 0])
    # boundary between ramp and lane 6: the one starting near the ramp and ending at lane 6's edge
    edge6 = -lane_w / 2
    cand = {k: ref.project_all(v) for k, v in bd.items()}
    gore_b = min((v for v in cand.values() if len(v) and abs(v[0, 0] - s_start) < 50 and v[0, 1] > -2.9 * lane_w),
                 key=lambda v: v[0, 1] - edge6 if v[0, 1] < edge6 else np.inf)
    s_gore = float(gore_b[-1, 0])
    outer = min((v for v in cand.values() if len(v) and abs(v[0, 0] - s_start) < 50), key=lambda v: v[0, 1])
    s_aux_end = _crossing(outer, edge6 - 1.0)
    s_aux_half = _crossing(outer, edge6 - lane_w / 2)
    ramp_len = float(np.hypot(*np.diff(cl["onramp"], axis=0).T).sum())
    conv = (ramp[-1, 1] - ramp[0, 1]) / (ramp[-1, 0] - ramp[0, 0])
    return {
        "main_lanes": n_main,
        "lane_width_ft": lane_w,
        "section_start_station_ft": s_start,
        "section_length_ft": s_diverge - s_start,
        "merge_position_ft": s_gore - s_start,
        "ramp_length_ft": min(ramp_len, s_gore - s_start),
        "ramp_angle_deg": math.degrees(math.atan(conv)),
        "aux_length_ft": s_aux_end - s_gore,
        "aux_half_width_length_ft": s_aux_half - s_gore,
        "offramp_diverge_ft": s_diverge - s_start,
    }


def to_toml(g: dict, source: str) -> str:
    m = {k: g[k] * FT_TO_M for k in ("section_length_ft", "merge_position_ft", "ramp_length_ft",
                                     "aux_length_ft", "lane_width_ft")}
    lines = [
        "# I-80 (Emeryville, NGSIM study area) road geometry, derived by",
        "# tools/derive_i80_geometry.py from NGSIM.jl's I-80 lane geometry (MIT).",
        f"# Source: {source}. Stations along lane 6's centerline, origin at the on-ramp's upstream end.",
        "",
        "[derived_ft]",
    ]
    lines += [f"{k} = {v:.1f}" if isinstance(v, float) else f"{k} = {v}" for k, v in g.items()]
    lines += [
        "",
        "# The same in the scenario spec's [road] terms (metres).",
        "[road]",
        f"main_lanes = {g['main_lanes']}",
        f"main_length_m = {m['section_length_ft']:.1f}",
        f"merge_position_m = {m['merge_position_ft']:.1f}",
        f"ramp_length_m = {m['ramp_length_ft']:.1f}",
        f"aux_length_m = {m['aux_length_ft']:.1f}",
        f"lane_width_m = {m['lane_width_ft']:.2f}",
        f"ramp_angle_deg = {g['ramp_angle_deg']:.1f}",
        "",
    ]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("data_dir", type=Path, help="folder with ngsimjl_centerlines80.txt and ngsimjl_boundaries80.txt")
    ap.add_argument("--out", type=Path, default=Path(__file__).resolve().parents[1] / "scenarios" / "data" / "i80_geometry.toml")
    args = ap.parse_args(argv)
    text = to_toml(derive(args.data_dir), "sisl/NGSIM.jl data/ (centerlines80, boundaries80)")
    write_text_atomic(args.out, text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
