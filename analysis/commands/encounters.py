"""``merge-irl encounters``: extract merge encounters from a trajectory file (Parquet or NGSIM CSV)."""

from __future__ import annotations

# API imports sit inside the functions: `merge-irl --help` imports every command module (analysis/commands/__init__.py).
import argparse
import sys
from pathlib import Path


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "encounters", help="extract merge encounters (B merging, lag A, lead C) from a trajectory file",
        description="Find every lane 7 -> 6 merge in TRAJECTORIES and write the per-frame encounter table to "
                    "--out; the per-merge summary goes beside it as <stem>.merges.parquet.",
    )
    p.add_argument("trajectories", metavar="TRAJECTORIES", help="trajectories .parquet or NGSIM .csv/.txt")
    p.add_argument("--out", required=True, metavar="FILE", help="output Parquet file")
    p.add_argument("--max-frames-before", type=int, default=None, metavar="N",
                   help="keep at most N frames before the merge (default: since A and B are both in the section)")
    p.add_argument("--frames-after", type=int, default=0, metavar="N", help="frames kept after the merge (default 0)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from sim.encounters import EncounterWindow, extract
    from sim.errors import TrajectoryFormatError
    from sim.outputs import write_parquet
    from sim.ngsim_io import read_trajectories

    if args.max_frames_before is not None and args.max_frames_before < 0:
        raise TrajectoryFormatError(f"--max-frames-before: must be >= 0, got {args.max_frames_before}")
    if args.frames_after < 0:
        raise TrajectoryFormatError(f"--frames-after: must be >= 0, got {args.frames_after}")
    table = read_trajectories(args.trajectories)
    enc = extract(table, window=EncounterWindow(args.max_frames_before, args.frames_after))
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    merges = out.with_name(out.stem + ".merges.parquet")
    write_parquet(enc.frames, out)
    write_parquet(enc.merges, merges)
    print(f"{len(enc.merges)} merges, {int((enc.merges['A_id'] != 0).sum())} with a lag car, "
          f"{len(enc.frames)} encounter frames", file=sys.stderr)
    print(out)
    print(merges)
    return 0
