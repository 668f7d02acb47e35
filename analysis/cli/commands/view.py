"""``merge-irl view RUN_DIR|FILE.rrd``: open rerun recordings in the viewer, or say how to."""

from __future__ import annotations

# API imports sit inside the functions: `merge-irl --help` imports every command module (analysis/cli/commands/__init__.py).
import argparse


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "view", help="open a run's rerun recordings (.rrd) in the rerun viewer",
        description="Open the .rrd files of a run folder (searched recursively) or one .rrd file in the "
                    "rerun viewer when one is available; otherwise print how to open them. Every file is read "
                    "first: one that is not a readable .rrd is refused (exit 2) and no viewer starts.")
    p.add_argument("target", help="a run folder or an .rrd file")
    p.add_argument("--print-only", action="store_true", help="only print the files and the command")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from analysis.recording.view import check_recordings, find_recordings, open_viewer, viewer_command

    files = find_recordings(args.target)
    check_recordings(files)  # a corrupt or foreign file: one line, exit 2, no viewer started
    for f in files:
        print(f)
    cmd = viewer_command(files)
    if args.print_only or cmd is None:
        print("open with:  " + " ".join(cmd or ["rerun", *map(str, files)]))
        if cmd is None:
            print("(no rerun viewer found here, or no display: install the viewer with "
                  "`pip install rerun-sdk` on a machine with a display, then run the command above)")
        return 0
    open_viewer(cmd)
    print("started: " + " ".join(cmd))
    return 0
