"""``merge-irl encounters``: extract merge encounters from a trajectory file (Parquet or NGSIM CSV)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from merge_irl.atomic import write_text_atomic
from sim.errors import TrajectoryFormatError, out_of_memory
from sim.merges.encounters import EncounterWindow, extract
from sim.ngsim.io import read_ngsim, read_trajectories
from sim.ngsim.smooth import SmoothingConfig
from sim.runtime.outputs import write_parquet
from sim.runtime.sites import I80, SITES, load_site

#: RMS jerk (ft/s^3) above which unsmoothed accelerations are taken as raw measurement noise.
RAW_JERK_FT_S3 = 30.0


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "encounters",
        description="Find every ramp -> merge-lane merge in TRAJECTORIES and write the per-frame encounter "
                    "table to --out, by the merge-frame rule (A = B's lag car at B's merge frame; a simulated "
                    "run's own encounters.parquet is cut by generate's --encounter-rule); the per-merge summary "
                    "goes beside it as <stem>.merges.parquet and, for NGSIM files, the loader's report as "
                    "<stem>.load-report.txt.",
    )
    p.add_argument("trajectories", metavar="TRAJECTORIES", help="trajectories .parquet or NGSIM .csv/.txt")
    p.add_argument("--out", required=True, metavar="FILE", help="output Parquet file")
    p.add_argument("--max-frames-before", type=int, default=None, metavar="N",
                   help="keep at most N frames before the merge (default: since A and B are both in the section)")
    p.add_argument("--frames-after", type=int, default=0, metavar="N", help="frames kept after the merge (default 0)")
    p.add_argument("--location", default=None, metavar="SITE",
                   help="NGSIM files with a Location column: keep this site's rows (e.g. i-80)")
    p.add_argument("--recording", type=int, default=None, metavar="N",
                   help="NGSIM files holding several recordings (Global_Time jumps): keep recording N")
    p.add_argument("--site", default=None, metavar="NAME|FILE.toml",
                   help="lane coding: i-80, us-101 (built in, sim.runtime.sites) or a TOML lane mapping (default: the "
                        "--location site if built in, else i-80)")
    p.add_argument("--smooth", action="store_true",
                   help="NGSIM files: smooth positions and recompute speeds and accelerations (Savitzky-Golay)")
    p.set_defaults(func=run)


def gap_lines(merges) -> list[str]:
    """What the recording's missing frames did to the encounters, from the merges summary
    (:data:`sim.merges.encounters.MERGE_COLUMNS`): none when nothing is missing."""
    out = []
    gapped = merges[merges["frame_gaps"] > 0]
    if len(gapped):
        out.append(f"frame gaps: {len(gapped)} encounter(s) with {int(gapped['frame_gaps'].sum())} gap(s) in their "
                   "frames; learning splits them there (no decision step spans missing frames)")
    lead = merges[merges["lead_gap_frames"] > 0] if "lead_gap_frames" in merges.columns else merges.iloc[:0]
    if len(lead):
        out.append(f"lead car gaps: {len(lead)} encounter(s) with {int(lead['lead_gap_frames'].sum())} frame(s) in which "
                   "C was missing between rows of it; left out (not read as 'no lead car'), learning splits there")
    late = merges[~merges["merge_observed"]]
    if len(late):
        out.append(f"merges not observed: {len(late)} B first seen in the merge lane after missing frames (up to "
                   f"{int(late['merge_gap_frames'].max())} frames late; merge_observed is false for them)")
    return out


def run(args: argparse.Namespace) -> int:
    if args.max_frames_before is not None and args.max_frames_before < 0:
        raise TrajectoryFormatError(f"--max-frames-before: must be >= 0, got {args.max_frames_before}")
    if args.frames_after < 0:
        raise TrajectoryFormatError(f"--frames-after: must be >= 0, got {args.frames_after}")
    src = Path(args.trajectories)
    out = Path(args.out)
    report = None
    if src.suffix.lower() in (".csv", ".txt"):
        load = read_ngsim(src, location=args.location, recording=args.recording,
                          smooth=SmoothingConfig() if args.smooth else False)
        table, report = load.table, load.report
    else:
        if args.location is not None or args.recording is not None or args.smooth:
            raise TrajectoryFormatError(
                f"{src}: --location, --recording and --smooth apply to NGSIM .csv/.txt files only")
        table = read_trajectories(src)
    if args.site is not None:
        site = load_site(args.site)
    elif report is not None and report.location in SITES:
        site = SITES[report.location]
    else:
        site = I80
    try:
        enc = extract(table, window=EncounterWindow(args.max_frames_before, args.frames_after), site=site)
    except MemoryError as e:
        raise out_of_memory(e, f"{src}: finding merges in {len(table)} rows",
                            "free memory or raise the limit (ulimit -v), or keep fewer rows "
                            "(--location, --recording)") from None
    out.parent.mkdir(parents=True, exist_ok=True)
    merges = out.with_name(out.stem + ".merges.parquet")
    written = [write_parquet(enc.frames, out), write_parquet(enc.merges, merges)]
    gaps = gap_lines(enc.merges)
    for line in gaps:
        print(line, file=sys.stderr)
    if report is not None:
        text = report.summary() + f"\n  site lane coding: {site.describe()}\n" + "".join(f"  {g}\n" for g in gaps)
        print(text, end="", file=sys.stderr)
        written.append(write_text_atomic(out.with_name(out.stem + ".load-report.txt"), text))
        if report.smoothing == "none" and (report.acc_saturated_rows or report.jerk_rms_ft_s3 > RAW_JERK_FT_S3):
            print(f"warning: acc_A comes from the file's raw, unsmoothed speeds ({report.acc_saturated_rows} rows "
                  f"at the +-11.2 ft/s^2 cap, RMS jerk {report.jerk_rms_ft_s3:.1f} ft/s^3): as action labels this "
                  "noise reads as hard braking and accelerating; rerun with --smooth", file=sys.stderr)
    print(f"{len(enc.merges)} merges, {int((enc.merges['A_id'] != 0).sum())} with a lag car, "
          f"{len(enc.frames)} encounter frames", file=sys.stderr)
    for r in enc.excluded.itertuples(index=False):
        print(f"left out: B {r.B_id} at frame {r.merge_frame}: {r.reason}", file=sys.stderr)
    for w in written:
        print(w)
    return 0
