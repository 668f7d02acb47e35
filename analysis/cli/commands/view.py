"""``merge-irl view RUN_DIR|FILE.rrd``: open rerun recordings in the viewer, or say how to."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from analysis.errors import AnalysisError
from analysis.recording.view import (
    check_recordings,
    find_recordings,
    no_viewer_advice,
    open_viewer,
    readable_recordings,
    viewer_command,
)


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "view",
        description="Open the .rrd files of a run folder (searched recursively) or one .rrd file in the "
                    "rerun viewer when one is available; otherwise print how to open them. Every file is read "
                    "first: in a folder, one that is not a readable .rrd is named on stderr and left out, and the "
                    "others open; a single file that is not readable, or a folder with none readable, is refused "
                    "(exit 2) and no viewer starts.")
    p.add_argument("target", help="a run folder or an .rrd file")
    p.add_argument("--print-only", action="store_true", help="only print the files and the command")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    files = find_recordings(args.target)
    if len(files) == 1 or not Path(args.target).is_dir():
        check_recordings(files)  # the one file asked for is corrupt or foreign: one line, exit 2, no viewer
    else:
        files, bad = readable_recordings(files)
        for line in bad:  # one bad recording does not block the run's others
            print(f"merge-irl view: warning: left out {line}", file=sys.stderr)
        if not files:
            raise AnalysisError(f"{args.target}: none of its {len(bad)} .rrd recordings is readable")
    for f in files:
        print(f)
    cmd = viewer_command(files)
    if args.print_only or cmd is None:
        print("open with:  " + " ".join(cmd or ["rerun", *map(str, files)]))
        if cmd is None:
            print(no_viewer_advice())
        return 0
    open_viewer(cmd)
    print("started: " + " ".join(cmd))
    return 0
