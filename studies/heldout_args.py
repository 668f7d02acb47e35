"""The command-line options the held-out calibration studies share: the pairs folder and the
splits by follower (``analysis.calibration.split_by_follower``)."""

from __future__ import annotations

import argparse
import os
from pathlib import Path

#: The authors' I-80 pair folder under ``$MERGE_IRL_SHARED`` (default ``../shared``).
DEFAULT_PAIRS = Path(os.environ.get("MERGE_IRL_SHARED", "../shared")) / "data" / "ngsim_i80_car_following"


def add_split_arguments(ap: argparse.ArgumentParser) -> None:
    """``--pairs DIR``, ``--holdout FRACTION`` (0.3) and ``--seeds S [S ...]`` (0 1 2)."""
    ap.add_argument("--pairs", type=Path, default=DEFAULT_PAIRS, metavar="DIR",
                    help=f"folder of pair CSVs (default {DEFAULT_PAIRS})")
    ap.add_argument("--holdout", type=float, default=0.3, metavar="FRACTION",
                    help="share of the followers held out of each fit (default 0.3)")
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2], metavar="S",
                    help="seeds of the splits by follower, one table row each (default 0 1 2)")
