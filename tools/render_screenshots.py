"""Render rerun recordings to PNG screenshots for the docs, headless.

For each ``.rrd`` this writes a blueprint file (``.rbl``) like the one the recording carries
(:func:`analysis.recording.blueprint.merge_blueprint`) but *playing* the first take-over in a loop
(rerun's blueprint cannot place the time cursor, which otherwise stays on the first frame,
before any car is controlled), then runs::

    rerun FILE.rrd FILE.rbl --window-size 1600x1000 --screenshot-to FILE.png

under a virtual X display (``xvfb-run``, Debian package ``xvfb``) when no display is set.
The viewer needs a Vulkan or GL driver; without a GPU, Mesa's software one (Debian package
``mesa-vulkan-drivers``: lavapipe) works, slowly (about 30 s per screenshot). The PNG is then
shrunk (``--width``) and reduced to a 256-colour palette to keep the docs small.

Usage::

    python tools/render_screenshots.py runs/demo/demo.rrd --out docs/screens --name demo
    python tools/render_screenshots.py runs/demo/demo.rrd --tab training --name demo-training

Exits 2 on bad input (missing file, no viewer, no display and no xvfb-run), 1 if the viewer
fails (its log is printed).
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from analysis.recording.blueprint import merge_blueprint
from analysis.recording.read import read_rrd_table, recording_info
from analysis.recording.scene import MIRROR_Y


def blueprint_inputs(rrd: Path) -> dict:
    """``merge_blueprint`` arguments recovered from a recording: the controlled cars (in order
    of take-over), the training methods, the section bounds, the first take-over and a
    playback speed."""
    table = read_rrd_table(rrd)
    ents = table.entity.astype(str)
    speed = table[ents.str.match(r"^/metrics/A_\d+/speed$")]
    firsts = speed.groupby("entity")["step"].agg(["min", "max"]).sort_values("min")
    a_ids = [int(e.split("/")[2][2:]) for e in firsts.index]
    methods = sorted({e.split("/")[2] for e in ents[ents.str.match(r"^/train/[^/]+/loglik$")]})
    first = None
    if len(firsts):
        # the first take-over: the first car's first unbroken run of logged frames (the same car
        # may be taken over again later)
        steps = np.sort(speed.loc[speed.entity == firsts.index[0], "step"].to_numpy(np.int64))
        gap = np.flatnonzero(np.diff(steps) > 1)
        first = (int(steps[0]), int(steps[gap[0]] if gap.size else steps[-1]))
    t0 = float(table["step"].min()) if "step" in table and table["step"].notna().any() else 0.0
    bounds = None
    lanes = table[ents == "/world/lanes"]
    if len(lanes) and "LineStrips2D:strips" in lanes:
        strips = lanes["LineStrips2D:strips"].iloc[0]
        pts = np.concatenate([np.asarray([list(p) for p in s], float) for s in strips]) @ MIRROR_Y[:2, :2]
        lo, hi = pts.min(axis=0) - 30.0, pts.max(axis=0) + 30.0
        bounds = (float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1]))
    # the viewer plays 30 frames per second at speed 1 and takes its screenshot about 1 s after
    # opening: fast enough to reach the first take-over in about 0.4 s
    speed = max(4.0, (first[0] - t0) / 12.0) if first is not None else 4.0
    return {"a_ids": a_ids, "training_methods": methods, "section_bounds": bounds, "first_control": first,
            "play": speed}


def viewer_command(rrd: Path, rbl: Path, png: Path, size: str) -> list[str]:
    """The screenshot command, wrapped in ``xvfb-run`` when there is no display.

    Raises:
        SystemExit: (2) no ``rerun`` executable, or no display and no ``xvfb-run``.
    """
    rerun = shutil.which("rerun") or str(Path(sys.executable).with_name("rerun"))
    if not Path(rerun).exists():
        raise SystemExit("render_screenshots: no 'rerun' executable (pip install rerun-sdk)")
    cmd = [rerun, str(rrd), str(rbl), "--window-size", size, "--screenshot-to", str(png)]
    if os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"):
        return cmd
    xvfb = shutil.which("xvfb-run")
    if xvfb is None:
        raise SystemExit("render_screenshots: no display and no xvfb-run (Debian: apt-get install xvfb mesa-vulkan-drivers)")
    w, h = size.split("x")
    return [xvfb, "-a", "-s", f"-screen 0 {w}x{h}x24", *cmd]


def shrink(png: Path, width: int) -> None:
    """Scale ``png`` to ``width`` pixels wide and store it with a 256-colour palette."""
    from PIL import Image

    im = Image.open(png).convert("RGB")
    if im.width > width:
        im = im.resize((width, round(im.height * width / im.width)), Image.Resampling.LANCZOS)
    im.quantize(256, method=Image.Quantize.MEDIANCUT).save(png, optimize=True)


def render(rrd: Path, png: Path, *, size: str = "1600x1000", width: int = 1400, tab: str = "run",
           timeout_s: float = 300.0) -> Path:
    """One screenshot of ``rrd`` into ``png``; see the module docstring."""
    args = blueprint_inputs(rrd)
    bp = merge_blueprint(**args, active_tab=1 if tab == "training" else 0)
    png.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        rbl = Path(tmp) / "view.rbl"
        bp.save(recording_info(rrd)["application_id"], str(rbl))
        out = Path(tmp) / "view.png"
        res = subprocess.run(viewer_command(rrd, rbl, out, size), capture_output=True, text=True, timeout=timeout_s, check=False,
                             env={**os.environ, "XDG_RUNTIME_DIR": os.environ.get("XDG_RUNTIME_DIR", tmp)})
        if res.returncode != 0 or not out.exists():
            sys.stderr.write(res.stdout[-3000:] + res.stderr[-3000:])
            raise RuntimeError(f"{rrd}: the viewer exited with {res.returncode} and no screenshot")
        shrink(out, width)
        shutil.move(str(out), png)
    return png


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("rrd", type=Path, nargs="+", help="recordings (.rrd)")
    ap.add_argument("--out", type=Path, default=Path("docs/screens"), help="folder of the PNGs")
    ap.add_argument("--name", help="file name (without .png) for a single recording; default: the .rrd's stem")
    ap.add_argument("--tab", choices=("run", "training"), default="run", help="the blueprint tab shown")
    ap.add_argument("--size", default="1600x1000", help="viewer window size WxH (logical points)")
    ap.add_argument("--width", type=int, default=1400, help="width of the stored PNG (pixels)")
    a = ap.parse_args(argv)
    missing = [str(p) for p in a.rrd if not p.is_file()]
    if missing:
        print(f"render_screenshots: no such recording: {', '.join(missing)}", file=sys.stderr)
        return 2
    if a.name and len(a.rrd) > 1:
        print("render_screenshots: --name needs exactly one recording", file=sys.stderr)
        return 2
    for rrd in a.rrd:
        try:
            png = render(rrd, a.out / f"{a.name or rrd.stem}.png", size=a.size, width=a.width, tab=a.tab)
        except RuntimeError as e:
            print(f"render_screenshots: {e}", file=sys.stderr)
            return 1
        print(f"{png} ({png.stat().st_size // 1024} kB)")
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except SystemExit as e:
        if isinstance(e.code, str):
            print(e.code, file=sys.stderr)
            sys.exit(2)
        raise
